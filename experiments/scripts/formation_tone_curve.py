"""Which tone curve do the real views' blur fit? (issue #77, item 3)

Per textured tile of dev-layout scenes, the combined view ``(L + R) / 2`` against the target
decoded to linear light by a candidate curve, blurred by the camera's combined kernel at each
radius and encoded back, each tile's tone matched affinely; the residual's share of the view's
variance at the tile's best radius, averaged over the tiles from 2 px (the sRGB fit's radius).
Candidates: the sRGB curve and ``linear = stored ** (a + b * stored)`` over a grid (``a`` the
shadows' exponent, ``a + b`` the highlights'). Also by the target tile's brightness, the sRGB
curve against the best one.

    python experiments/scripts/formation_tone_curve.py ../shared/data/canon-dp-real-hd
    python experiments/scripts/formation_tone_curve.py ../shared/data/canon-dp-real \\
        --camera canon-840-linear --max-radius 10 --tile 32
"""

from __future__ import annotations

import argparse
import itertools
from functools import partial
from multiprocessing import Pool
from pathlib import Path

import cv2
import numpy as np

from dualpixel.io.images import read_rgb
from dualpixel.optics.camera import load_camera
from dualpixel.optics.psf import dp_psf
from dualpixel.optics.tone import linear_to_srgb_array, srgb_to_linear_array

A_GRID = (0.8, 1.0, 1.2, 1.5, 1.9, 2.2)
B_GRID = (0.0, 0.75, 1.5, 2.25)
BRIGHTNESS = (0.0, 0.2, 0.35, 0.5, 0.7, 1.01)


def power_curve(a: float, b: float, samples: int = 4096, steps: int = 1 << 20):
    """``(decode, encode)`` of ``linear = stored ** (a + b * stored)`` on [0, 1] (monotone for
    ``a > 0``, ``b >= 0``); the encoding looks linear values up in a table of ``steps``."""
    table = np.linspace(0.0, 1.0, samples)
    inverse = np.interp(np.linspace(0.0, 1.0, steps), table ** (a + b * table),
                        table).astype(np.float32)

    def decode(x: np.ndarray) -> np.ndarray:
        x = np.clip(x, 0.0, 1.0)
        return x ** (a + b * x)

    def encode(y: np.ndarray) -> np.ndarray:
        return inverse[(np.clip(y, 0.0, 1.0) * (steps - 1) + 0.5).astype(np.int32)]

    return decode, encode


def curves(a_grid: tuple[float, ...] = A_GRID, b_grid: tuple[float, ...] = B_GRID
           ) -> dict[str, tuple]:
    """Every candidate by name: "srgb" and "a,b" over the grid."""
    out = {"srgb": (srgb_to_linear_array, linear_to_srgb_array)}
    for a, b in itertools.product(a_grid, b_grid):
        out[f"{a:g},{b:g}"] = power_curve(a, b)
    return out


def tiled(image: np.ndarray, tile: int) -> np.ndarray:
    """``(rows, cols, tile * tile, C)`` whole tiles of ``image`` ``(H, W, C)``."""
    rows, cols = image.shape[0] // tile, image.shape[1] // tile
    return (image[: rows * tile, : cols * tile].reshape(rows, tile, cols, tile, -1)
            .transpose(0, 2, 1, 3, 4).reshape(rows, cols, tile * tile, -1))


def scene_residuals(scene: Path, camera: str, radii: np.ndarray, tile: int,
                    grids: tuple[tuple[float, ...], tuple[float, ...]] = (A_GRID, B_GRID)
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per candidate curve, per tile, the least residual share over ``radii``; each tile's
    sRGB-fit radius and the target tile's mean brightness; textured tiles only."""
    psf = load_camera(camera).psf
    kernels = [None if r < 0.5 else dp_psf(float(r), psf).combined.numpy() for r in radii]
    left, right, target = (np.clip(read_rgb(scene / f"{n}.png"), 0, 1).astype(np.float32)
                           for n in ("view0", "view1", "target"))
    views = tiled((left + right) / 2, tile)
    centred = views - views.mean(axis=2, keepdims=True)
    energy = (centred**2).sum(axis=2)  # per tile and channel
    variance = energy.sum(axis=-1)
    sharp = tiled(target, tile)
    textured = sharp.std(axis=2).mean(axis=-1) > 0.03
    shares, radius = [], None
    for name, (decode, encode) in curves(*grids).items():
        linear = decode(target).astype(np.float32)
        residual = []
        for kernel in kernels:
            blurred = linear if kernel is None else cv2.filter2D(linear, -1, kernel,
                                                                 borderType=cv2.BORDER_REFLECT)
            b = tiled(encode(blurred), tile)
            b = b - b.mean(axis=2, keepdims=True)
            fit = (centred * b).sum(axis=2) ** 2 / ((b * b).sum(axis=2) + 1e-12)
            residual.append((energy - fit).sum(axis=-1))
        residual = np.asarray(residual)
        if name == "srgb":
            radius = radii[residual.argmin(axis=0)]
        shares.append(residual.min(axis=0) / np.maximum(variance, 1e-12))
    pick = textured & (radius >= 2.0)
    return (np.asarray(shares)[:, pick], radius[pick], sharp.mean(axis=(2, 3))[pick])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("root", type=Path, help="dev-layout scenes (scene_NN/view0, view1, target)")
    parser.add_argument("--camera", default="canon-hd-linear")
    parser.add_argument("--max-radius", type=float, default=20.0)
    parser.add_argument("--tile", type=int, default=64)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--a-grid", type=float, nargs="+", default=list(A_GRID))
    parser.add_argument("--b-grid", type=float, nargs="+", default=list(B_GRID))
    args = parser.parse_args()
    grids = (tuple(args.a_grid), tuple(args.b_grid))
    radii = np.concatenate([[0.0], np.arange(0.75, 5.01, 0.5),
                            np.arange(6.0, args.max_radius + 0.01, 1.0)])
    scenes = sorted(args.root.glob("scene_*"))
    with Pool(args.workers) as pool:
        parts = pool.map(partial(scene_residuals, camera=args.camera, radii=radii,
                                 tile=args.tile, grids=grids), scenes)
    shares = np.concatenate([p[0] for p in parts], axis=1)
    radius = np.concatenate([p[1] for p in parts])
    brightness = np.concatenate([p[2] for p in parts])
    names = list(curves(*grids))
    mean = shares.mean(axis=1)
    best = int(np.argmin(mean))
    print(f"{args.root.name}: {shares.shape[1]} tiles from 2 px; mean residual share, sRGB "
          f"{mean[0]:.4f}, best curve a,b = {names[best]} {mean[best]:.4f}")
    a_grid, b_grid = grids
    print("| a \\ b | " + " | ".join(f"{b:g}" for b in b_grid) + " |")
    print("|---|" + "---|" * len(b_grid))
    for i, a in enumerate(a_grid):
        cells = mean[1 + i * len(b_grid) : 1 + (i + 1) * len(b_grid)]
        print(f"| {a:g} | " + " | ".join(f"{v:.4f}" for v in cells) + " |")
    print("\n| target mean | blur | tiles | sRGB | best curve | best curve wins |")
    print("|---|---|---|---|---|---|")
    for (low, high), (near, far) in itertools.product(
            itertools.pairwise(BRIGHTNESS), ((2.0, 4.5), (4.5, args.max_radius + 1))):
        pick = ((brightness >= low) & (brightness < high) & (radius >= near)
                & (radius < far))
        if pick.sum() < 5:
            continue
        wins = (shares[best, pick] < shares[0, pick]).mean()
        print(f"| {low:g}-{min(high, 1):g} | {near:g}-{far:g} px | {pick.sum()} | "
              f"{shares[0, pick].mean():.4f} | {shares[best, pick].mean():.4f} | {wins:.0%} |")


if __name__ == "__main__":
    main()
