"""Is the real blur round? Per tile of dev-layout scenes, the shape of the blur that takes the
target to the combined view (issue #77, item 3).

Per ``--tile``-px tile (stride half a tile, Hann window) of the combined view ``(L + R) / 2`` and
the target, both in linear light and averaged over the channels, the amplitude spectra ``|C|`` and
``|T|``. A candidate blur is the camera's combined kernel (the mean of its two view kernels, the
whole aperture) at CoC radius ``r``, stretched by ``sqrt(a)`` along the direction ``theta`` and
by ``1 / sqrt(a)`` across it (area kept): ``a > 1`` at 0 degrees is wider across than up. Each
candidate is scored by the least-squares residual of ``|C| ~ g |T| |K|`` with the gain ``g`` free,
over the frequencies ``0 < |f| <= 0.4`` cycles / px: a shift of the target (its sub-pixel
offset) and its exposure do not count. Per textured tile: the round fit's radius, the best
aspect at 0 and at 45 degrees, and the share of the round fit's residual the best shape removes.

    python experiments/scripts/formation_blur_shape.py ../shared/data/canon-dp-real-hd \\
        --camera canon-hd-linear --max-radius 20
"""

from __future__ import annotations

import argparse
import itertools
from pathlib import Path

import cv2
import numpy as np

from dualpixel.io.images import read_rgb
from dualpixel.optics.camera import load_camera
from dualpixel.optics.psf import dp_psf
from dualpixel.optics.tone import srgb_to_linear_array

ASPECTS = (0.6, 0.7, 0.8, 0.9, 1.0, 1.11, 1.25, 1.43, 1.67)
ANGLES = (0.0, 45.0)
BINS = ((2.0, 4.5), (4.5, 9.0), (9.0, 20.1))


def stretched(kernel: np.ndarray, size: int, aspect: float, angle: float) -> np.ndarray:
    """``kernel`` centred on a ``size`` square, stretched by ``sqrt(aspect)`` along ``angle``
    (degrees from the x axis) and squeezed by as much across it; sums to 1."""
    canvas = np.zeros((size, size), np.float32)
    k = kernel.shape[0]
    start = size // 2 - k // 2
    canvas[start : start + k, start : start + k] = kernel
    theta = np.deg2rad(angle)
    rotation = np.array([[np.cos(theta), -np.sin(theta)], [np.sin(theta), np.cos(theta)]])
    scale = np.diag([np.sqrt(aspect), 1 / np.sqrt(aspect)])
    matrix = rotation @ scale @ rotation.T
    centre = np.array([size // 2, size // 2], float)
    affine = np.hstack([matrix, (centre - matrix @ centre)[:, None]]).astype(np.float32)
    out = cv2.warpAffine(canvas, affine, (size, size), flags=cv2.INTER_LINEAR)
    return out / out.sum()


def candidate_spectra(radii: np.ndarray, camera: str, size: int) -> tuple[np.ndarray, list]:
    """``(N, size, size // 2 + 1)`` amplitude spectra of every candidate, and their
    ``(radius, aspect, angle)``."""
    psf = load_camera(camera).psf
    spectra, labels = [], []
    for radius in radii:
        if radius < 0.5:
            base = np.ones((1, 1), np.float32)
        else:
            base = dp_psf(float(radius), psf).combined.numpy()
        for aspect, angle in itertools.product(ASPECTS, ANGLES):
            if aspect == 1.0 and angle:
                continue
            kernel = np.fft.ifftshift(stretched(base, size, aspect, angle))
            spectra.append(np.abs(np.fft.rfft2(kernel)))
            labels.append((float(radius), aspect, angle))
    return np.asarray(spectra, np.float32), labels


def tile_spectra(image: np.ndarray, tile: int) -> tuple[np.ndarray, list[tuple[int, int]]]:
    """Amplitude spectra ``(n, tile, tile // 2 + 1)`` of the Hann-windowed tiles of a grey
    image (mean removed), stride ``tile // 2``, and each tile's top-left corner."""
    window = np.outer(np.hanning(tile), np.hanning(tile)).astype(np.float32)
    corners = [(y, x) for y in range(0, image.shape[0] - tile + 1, tile // 2)
               for x in range(0, image.shape[1] - tile + 1, tile // 2)]
    tiles = np.stack([image[y : y + tile, x : x + tile] for y, x in corners])
    tiles = (tiles - tiles.mean(axis=(1, 2), keepdims=True)) * window
    return np.abs(np.fft.rfft2(tiles)), corners


def scene_rows(scene: Path, spectra: np.ndarray, labels: list, tile: int,
               min_detail: float) -> list[tuple[float, ...]]:
    """Per textured tile: x across the frame (-1 to 1), round radius, best aspect at 0 and at
    45 degrees, and the share of the round residual the best shape removes."""
    left, right, target = (srgb_to_linear_array(read_rgb(scene / f"{n}.png"))
                           for n in ("view0", "view1", "target"))
    combined = ((left + right) / 2).mean(axis=-1)
    sharp = target.mean(axis=-1)
    blurred, corners = tile_spectra(combined, tile)
    clean, _ = tile_spectra(sharp, tile)
    fy = np.fft.fftfreq(tile)[:, None]
    fx = np.fft.rfftfreq(tile)[None, :]
    band = ((fx**2 + fy**2) > 0) & (np.hypot(fx, fy) <= 0.4)
    radius = np.array([label[0] for label in labels])
    aspect = np.array([label[1] for label in labels])
    angle = np.array([label[2] for label in labels])
    round_ = aspect == 1.0
    kernels = spectra[:, band]
    rows = []
    for (_, x), c, t in zip(corners, blurred, clean):
        detail = np.sqrt((t[band] ** 2).sum()) / tile
        if detail < min_detail:
            continue
        a, b = c[band], t[band][None, :] * kernels
        residual = (a @ a) - (b @ a) ** 2 / np.maximum((b * b).sum(axis=1), 1e-20)
        best_round = np.argmin(np.where(round_, residual, np.inf))
        if radius[best_round] < BINS[0][0]:
            continue
        by_angle = []
        for theta in ANGLES:
            pick = round_ | (angle == theta)
            by_angle.append(aspect[np.argmin(np.where(pick, residual, np.inf))])
        gain = 1 - residual.min() / residual[best_round]
        rows.append(((x + tile / 2) / combined.shape[1] * 2 - 1, radius[best_round],
                     *by_angle, gain))
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("roots", nargs="+", type=Path,
                        help="folders of dev-layout scenes (scene_NN/view0, view1, target)")
    parser.add_argument("--camera", default="canon-hd-linear")
    parser.add_argument("--max-radius", type=float, default=20.0)
    parser.add_argument("--tile", type=int, default=128)
    parser.add_argument("--min-detail", type=float, default=0.004,
                        help="least RMS amplitude of the target tile's spectrum in the band")
    args = parser.parse_args()
    radii = np.concatenate([[0.0], np.arange(0.75, 5.01, 0.25),
                            np.arange(5.5, args.max_radius + 0.01, 0.5)])
    spectra, labels = candidate_spectra(radii, args.camera, args.tile)
    print("| scenes | radius of the round fit | |x| | tiles | aspect at 0 deg, median (IQR) "
          "| aspect at 45 deg, median (IQR) | residual removed, median |")
    print("|---|---|---|---|---|---|---|")
    for root in args.roots:
        rows = np.asarray([row for scene in sorted(root.glob("scene_*"))
                           for row in scene_rows(scene, spectra, labels, args.tile,
                                                 args.min_detail)])
        for (low, high), (near, far) in itertools.product(BINS, ((0.0, 0.6), (0.6, 1.01))):
            pick = ((rows[:, 1] >= low) & (rows[:, 1] < high) & (np.abs(rows[:, 0]) >= near)
                    & (np.abs(rows[:, 0]) < far))
            if not pick.any():
                continue
            cells = []
            for column in (2, 3):
                q = np.percentile(rows[pick, column], [25, 50, 75])
                cells.append(f"{q[1]:.2f} ({q[0]:.2f}-{q[2]:.2f})")
            print(f"| {root.name} | {low:g}-{high:g} px | {near:g}-{min(far, 1):g} | "
                  f"{pick.sum()} | {cells[0]} | {cells[1]} | "
                  f"{np.median(rows[pick, 4]):.3f} |", flush=True)


if __name__ == "__main__":
    main()
