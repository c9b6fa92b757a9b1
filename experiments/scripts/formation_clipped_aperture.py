"""Issue #77 item 3: do kernels clipped off axis (optical vignetting) explain real views far from
the frame's centre?

Per textured block of the dev Canon scenes blurred at least ``--min-radius`` px, the fit of
:func:`dualpixel.calibration.camera.fit_blocks` (views = the target blurred by the left and right
kernels, gain, crosstalk and offset per block; linear light; best radius per block), here with
each block's own kernels: the Canon camera's shape, its light outside a disc of the same radius
moved by ``s r`` along the block's direction from the frame's centre (outwards, ``s > 0``, or
inwards) cut away, the combined kernel renormalised. Prints the share of the views' variance
left unexplained by zone for each ``s``: if the aperture were clipped off axis, the blocks far
from the centre would fit better clipped and the centre not. ``--separate`` also fits each view
alone (unequal left and right apertures), ``--registered`` the target moved by the best
sub-pixel shift: explanations that would help far from the centre more than near it.

    python experiments/scripts/formation_clipped_aperture.py ../shared/data/canon-dp-real \
        --shifts 0,0.15,0.3,0.5,-0.15,-0.3 --separate --registered
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
        # per channel, L ~ p a + q b + o and R ~ p b + q a + o: the 3x3 normal equations
        m11 = (a * a + b * b).sum(0)
        m12 = 2.0 * (a * b).sum(0)
        m13 = (a + b).sum(0)
        n = np.full_like(m11, 2.0 * len(a))
        matrix = np.stack([np.stack([m11, m12, m13], -1), np.stack([m12, m11, m13], -1),
                           np.stack([m13, m13, n], -1)], -2) + 1e-9 * np.eye(3)
        rhs = np.stack([(lo * a + ro * b).sum(0), (lo * b + ro * a).sum(0), (lo + ro).sum(0)], -1)
        solution = np.linalg.solve(matrix, rhs[..., None])[..., 0]
        residual = float(((lo * lo + ro * ro).sum(0) - (solution * rhs).sum(-1)).sum())
        best = residual if best is None else min(best, residual)
    both = np.concatenate([lo, ro])
    return best, float(((both - both.mean(0)) ** 2).sum())


def separate_residual(views, sharp, radii, params) -> tuple[float, float]:
    """As :func:`block_residual` unclipped, but each view fitted alone (its own radius, gain,
    crosstalk and offset): what unequal left and right apertures (DP vignetting) could explain."""
    margin = (sharp.shape[0] - PATCH) // 2
    inner = (slice(margin, margin + PATCH), slice(margin, margin + PATCH))
    total = 0.0
    for view, own in zip(views, (0, 1)):
        observed = view[inner].reshape(-1, view.shape[-1]).astype(np.float64)
        best = None
        for radius in radii:
            kernels = clipped_kernels(radius, params, np.zeros(2), 0.0)
            a, b = (cv2.filter2D(sharp, -1, k, borderType=cv2.BORDER_REFLECT)[inner]
                    .reshape(-1, sharp.shape[-1]).astype(np.float64)
                    for k in (kernels[own], kernels[1 - own]))
            m = np.stack([np.stack([(a * a).sum(0), (a * b).sum(0), a.sum(0)], -1),
                          np.stack([(a * b).sum(0), (b * b).sum(0), b.sum(0)], -1),
                          np.stack([a.sum(0), b.sum(0), np.full(a.shape[1], float(len(a)))], -1)],
                         -2) + 1e-9 * np.eye(3)
            rhs = np.stack([(observed * a).sum(0), (observed * b).sum(0), observed.sum(0)], -1)
            solution = np.linalg.solve(m, rhs[..., None])[..., 0]
            residual = float(((observed ** 2).sum(0) - (solution * rhs).sum(-1)).sum())
            best = residual if best is None else min(best, residual)
        total += best
    both = np.concatenate([v[inner].reshape(-1, v.shape[-1]) for v in views]).astype(np.float64)
    return total, float(((both - both.mean(0)) ** 2).sum())


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("root")
    parser.add_argument("--shifts", default="0,0.3,0.6,-0.3,-0.6")
    parser.add_argument("--min-radius", type=float, default=4.5)
    parser.add_argument("--registered", action="store_true",
                        help="also fit with the target moved by the best of +-1 px in halves")
    parser.add_argument("--base-blur", type=float, default=0.0,
                        help="a Gaussian std (px) every kernel is also blurred by")
    parser.add_argument("--separate", action="store_true",
                        help="also fit each view alone (its own radius and gains)")
    args = parser.parse_args()
    params = load_camera("canon-840-linear").psf
    shifts = [float(s) for s in args.shifts.split(",")]
    radii = np.arange(0.0, 12.01, 0.5)
    margin = int(np.ceil(12 * 1.6)) + 2
    totals = {s: np.zeros((2, len(ZONES))) for s in shifts}
    for extra in ("separate", "registered"):
        if getattr(args, extra):
            totals[extra] = np.zeros((2, len(ZONES)))
    counts = np.zeros(len(ZONES), int)
    for scene in sorted(glob.glob(os.path.join(args.root, "scene_*"))):
        left, right, target = (srgb_to_linear_array(read_rgb(os.path.join(scene, f"{n}.png")))
                               for n in ("view0", "view1", "target"))
        if args.base_blur:  # blurring the target blurs every kernel alike
            target = cv2.GaussianBlur(target, (0, 0), args.base_blur,
                                      borderType=cv2.BORDER_REFLECT)
        fit = fit_blocks(left, right, target, params, radii, patch=PATCH)
        height, width = target.shape[:2]
        # blocks at the frame's border read its reflection, as fit_blocks' filters do
        left, right, target = (
            cv2.copyMakeBorder(v, margin, margin, margin, margin, cv2.BORDER_REFLECT)
            for v in (left, right, target))
        centre = np.array([(width - 1) / 2, (height - 1) / 2])
        for index in np.ndindex(fit.radius.shape[:2]):
            if fit.texture[index].min() <= MIN_TEXTURE or fit.radius[index][1] < args.min_radius:
                continue
            offset = fit.centres[index] - centre
            field = np.linalg.norm(offset) / np.linalg.norm(centre)  # of the half-diagonal
            zone = next(z for z, (a, b) in enumerate(ZONES) if a <= field < b)
            x, y = (int(v - PATCH / 2) for v in fit.centres[index])
            window = (slice(y, y + PATCH + 2 * margin), slice(x, x + PATCH + 2 * margin))
            direction = offset / max(np.linalg.norm(offset), 1e-9)
            counts[zone] += 1
            sharp = np.ascontiguousarray(target[window])
            for shift in shifts:
                residual, variance = block_residual((left[window], right[window]), sharp, radii,
                                                    params, direction, shift)
                totals[shift][:, zone] += (residual, variance)
            if args.separate:
                totals["separate"][:, zone] += separate_residual(
                    (left[window], right[window]), sharp, radii, params)
            if args.registered:  # the target moved (bilinear) by the best sub-pixel shift
                fits = [block_residual((left[window], right[window]),
                                       cv2.warpAffine(sharp, np.float32([[1, 0, dx], [0, 1, dy]]),
                                                      sharp.shape[1::-1],
                                                      borderMode=cv2.BORDER_REFLECT),
                                       radii, params, direction, 0.0)
                        for dx in (-1, -0.5, 0, 0.5, 1) for dy in (-1, -0.5, 0, 0.5, 1)]
                totals["registered"][:, zone] += min(fits)
    print(f"blocks blurred >= {args.min_radius:g} px by zone: {counts.tolist()}")
    for shift, total in totals.items():
        label = ({"separate": "each view alone", "registered": "target registered"}.get(shift)
                 or f"clip shift s={shift:+.2f}")
        print(f"  {label}: unexplained share by zone "
              + " ".join(f"{total[0, z] / total[1, z]:.4f}" for z in range(len(ZONES))))


if __name__ == "__main__":
    main()
