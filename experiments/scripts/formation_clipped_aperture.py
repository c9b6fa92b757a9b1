"""Issue #77 item 3: do kernels clipped off axis (optical vignetting) explain real views far from
the frame's centre?

Per textured block of the dev Canon scenes blurred at least ``--min-radius`` px, the fit of
:func:`dualpixel.calibration.camera.fit_blocks` (views = the target blurred by the left and right
kernels, gain, crosstalk and offset per block; linear light; best radius per block), here with
each block's own kernels: the Canon camera's shape, its light outside a disc of the same radius
moved by ``s r`` along the block's direction from the frame's centre (outwards, ``s > 0``, or
inwards) cut away, the combined kernel renormalised. Prints the share of the views' variance
left unexplained by zone for each ``s``: the shape far from the centre should fit better
clipped, the centre not.

    python experiments/scripts/formation_clipped_aperture.py ../shared/data/canon-dp-real
"""

from __future__ import annotations

import argparse
import glob
import os

import cv2
import numpy as np

from dualpixel.calibration.camera import MIN_TEXTURE, fit_blocks
from dualpixel.io.images import read_rgb
from dualpixel.optics.camera import load_camera
from dualpixel.optics.psf import dp_psf
from dualpixel.optics.tone import srgb_to_linear_array

PATCH = 48
ZONES = ((0.0, 0.35), (0.35, 0.7), (0.7, 1.01))


def clipped_kernels(radius: float, params, direction: np.ndarray, shift: float
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Left and right kernels (flipped for filter2D) of ``radius``: light outside a disc of
    ``radius`` centred ``shift * radius`` px along ``direction`` (x, y) removed; together they
    sum to 1."""
    kernels = dp_psf(float(radius), params)
    left, right = (k.numpy().astype(np.float64) for k in (kernels.left, kernels.right))
    if shift != 0.0 and radius > 0:
        size = left.shape[0]
        y, x = np.mgrid[0:size, 0:size] - size // 2
        cx, cy = shift * radius * direction
        # the disc's edge softened over a pixel, as the model integrates its disc over pixels
        inside = np.clip(radius + 0.5 - np.hypot(x - cx, y - cy), 0.0, 1.0)
        left, right = left * inside, right * inside
    total = left.sum() + right.sum()
    return tuple(np.ascontiguousarray((k / total)[::-1, ::-1], np.float32) for k in (left, right))


def block_residual(views, sharp, radii, params, direction, shift) -> tuple[float, float]:
    """Least residual over ``radii`` of the block fit (summed over channels) and the views'
    variance; ``views`` and ``sharp`` are crops with the blur margin around the block."""
    margin = (sharp.shape[0] - PATCH) // 2
    inner = (slice(margin, margin + PATCH), slice(margin, margin + PATCH))
    lo, ro = (v[inner].reshape(-1, v.shape[-1]).astype(np.float64) for v in views)
    best = None
    for radius in radii:
        kl, kr = clipped_kernels(radius, params, direction, shift)
        a = cv2.filter2D(sharp, -1, kl, borderType=cv2.BORDER_REFLECT)[inner]
        b = cv2.filter2D(sharp, -1, kr, borderType=cv2.BORDER_REFLECT)[inner]
        a, b = (x.reshape(-1, x.shape[-1]).astype(np.float64) for x in (a, b))
        residual = 0.0
        for c in range(a.shape[1]):
            design = np.stack([np.concatenate([a[:, c], b[:, c]]),
                               np.concatenate([b[:, c], a[:, c]]),
                               np.ones(2 * len(a))], axis=1)
            observed = np.concatenate([lo[:, c], ro[:, c]])
            solution, *_ = np.linalg.lstsq(design, observed, rcond=None)
            residual += float(((design @ solution - observed) ** 2).sum())
        best = residual if best is None else min(best, residual)
    both = np.concatenate([lo, ro])
    return best, float(((both - both.mean(0)) ** 2).sum())


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("root")
    parser.add_argument("--shifts", default="0,0.3,0.6,-0.3,-0.6")
    parser.add_argument("--min-radius", type=float, default=4.5)
    args = parser.parse_args()
    params = load_camera("canon-840-linear").psf
    shifts = [float(s) for s in args.shifts.split(",")]
    radii = np.arange(0.0, 12.01, 0.5)
    margin = int(np.ceil(12 * 1.6)) + 2
    totals = {s: np.zeros((2, len(ZONES))) for s in shifts}
    counts = np.zeros(len(ZONES), int)
    for scene in sorted(glob.glob(os.path.join(args.root, "scene_*"))):
        left, right, target = (srgb_to_linear_array(read_rgb(os.path.join(scene, f"{n}.png")))
                               for n in ("view0", "view1", "target"))
        fit = fit_blocks(left, right, target, params, radii, patch=PATCH)
        height, width = target.shape[:2]
        # blocks at the frame's border read its reflection, as fit_blocks' filters do
        left, right, target = (cv2.copyMakeBorder(v, margin, margin, margin, margin,
                                                  cv2.BORDER_REFLECT) for v in (left, right, target))
        centre = np.array([(width - 1) / 2, (height - 1) / 2])
        for index in np.ndindex(fit.radius.shape[:2]):
            if fit.texture[index].min() <= MIN_TEXTURE or fit.radius[index][1] < args.min_radius:
                continue
            offset = fit.centres[index] - centre
            field = np.linalg.norm(offset / centre) / np.sqrt(2)
            zone = next(z for z, (a, b) in enumerate(ZONES) if a <= field < b)
            x, y = (int(v - PATCH / 2) for v in fit.centres[index])
            window = (slice(y, y + PATCH + 2 * margin), slice(x, x + PATCH + 2 * margin))
            direction = offset / max(np.linalg.norm(offset), 1e-9)
            counts[zone] += 1
            for shift in shifts:
                residual, variance = block_residual((left[window], right[window]),
                                                    np.ascontiguousarray(target[window]), radii,
                                                    params, direction, shift)
                totals[shift][:, zone] += (residual, variance)
    print(f"blocks blurred >= {args.min_radius:g} px by zone: {counts.tolist()}")
    for shift, total in totals.items():
        print(f"  clip shift s={shift:+.1f}: unexplained share by zone "
              + " ".join(f"{total[0, z] / total[1, z]:.4f}" for z in range(len(ZONES))))


if __name__ == "__main__":
    main()
