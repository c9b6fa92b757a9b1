"""Issue #77 item 3: where our formation fails to explain real DP views, by blur size.

For every PSF shape given, the target-calibrated fit of :mod:`dualpixel.calibration.camera`
(views explained by the sharp target blurred by the shape's left and right kernels, with
crosstalk, gain and offset per block; linear light) on the dev Canon scenes, and the share of the
views' variance the fit leaves, summed over usable blocks, per CoC radius bin, per channel and by
distance from the frame's centre. Lower is better; the bins show whether the shape fails where
the blur is large.

    python experiments/scripts/formation_by_radius.py ../shared/data/canon-dp-real [--bank pixel4]
"""

from __future__ import annotations

import argparse
import itertools
import json
import time

import cv2
import numpy as np

from dualpixel.calibration.camera import MIN_TEXTURE, fit_blocks, read_calibration_frames
from dualpixel.optics.psf import PSFParams
from dualpixel.optics.psf_bank import PSF_BANKS
from dualpixel.optics.tone import srgb_to_linear_array

BINS = (2.0, 3.0, 4.5, 6.0, 8.0, 12.0)
FIELD = (0.0, 0.35, 0.7, 1.01)  # distance from the centre, a fraction of the half-diagonal
LARGE = 4.5  # px: the field columns count blocks blurred at least this much
SHAPES = {
    "canon (file)": PSFParams(n=3, alpha=0.45, beta=0.2, kappa=0.21),
    "paper mode": PSFParams(n=3, alpha=0.4, beta=0.2, kappa=0.14),
    "flat half-disc": PSFParams(n=15, alpha=1.0, beta=1.0, kappa=0.05),
    "flat, soft": PSFParams(n=7, alpha=0.55, beta=0.9, kappa=0.14),
    "deep ring": PSFParams(n=15, alpha=0.35, beta=0.1, kappa=0.05),
    "wide smooth": PSFParams(n=2, alpha=0.55, beta=0.6, kappa=0.45),
}


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("roots", nargs="+")
    parser.add_argument("--bank", default=None, help="also every shape of this bank")
    parser.add_argument("--patch", type=int, default=48)
    parser.add_argument("--step", type=float, default=0.25, help="radius grid step, px")
    parser.add_argument("--base-blur", default="0",
                        help="Gaussian stds (px) the kernels are also blurred by, comma-separated "
                             "(a blur of every radius: lens softness, the sensor's processing)")
    parser.add_argument("--only", default=None, help="only this shape of the list above")
    parser.add_argument("--json", default=None)
    args = parser.parse_args()
    frames = read_calibration_frames(args.roots)
    linear = [(name, *(srgb_to_linear_array(v) for v in (left, right, target)))
              for name, left, right, target in frames]
    shapes = dict(SHAPES) if args.only is None else {args.only: SHAPES[args.only]}
    if args.bank:
        shapes.update({f"{args.bank}:{i}": p for i, p in enumerate(PSF_BANKS[args.bank])})
    radii = np.arange(0.0, 12.01, args.step)
    rows = {}
    base_blurs = [float(b) for b in args.base_blur.split(",")]
    runs = [(f"{label} + {base:g} px" if base else label, params, base)
            for label, params in shapes.items() for base in base_blurs]
    for label, params, base in runs:
        started = time.monotonic()
        residual = np.zeros((len(BINS) - 1, 3))
        variance = np.zeros_like(residual)
        field_res, field_var = np.zeros(len(FIELD) - 1), np.zeros(len(FIELD) - 1)
        ratios = []
        field_pixels = np.zeros(len(FIELD) - 1)
        for _, left, right, target in linear:
            if base:  # blurring the target blurs every kernel alike (convolutions commute)
                target = cv2.GaussianBlur(target, (0, 0), base, borderType=cv2.BORDER_REFLECT)
            fit = fit_blocks(left, right, target, params, radii, patch=args.patch)
            green = fit.radius[..., 1]
            usable = (fit.texture.min(axis=-1) > MIN_TEXTURE) & (green >= BINS[0])
            height, width = left.shape[:2]
            centre = np.array([(width - 1) / 2, (height - 1) / 2])
            field = np.linalg.norm(fit.centres - centre, axis=-1) / np.linalg.norm(centre)
            ratios.append(np.stack([green, field, np.abs(fit.ratio[..., 1])], -1)[usable])
            for b in range(len(BINS) - 1):
                inside = usable & (green >= BINS[b]) & (green < BINS[b + 1])
                residual[b] += fit.residual[inside].sum(0)
                variance[b] += fit.variance[inside].sum(0)
            for f in range(len(FIELD) - 1):  # the blur large enough to show its shape
                inside = (usable & (green >= LARGE) & (field >= FIELD[f])
                          & (field < FIELD[f + 1]))
                field_res[f] += fit.residual[inside].sum()
                field_var[f] += fit.variance[inside].sum()
                field_pixels[f] += inside.sum() * 2 * args.patch**2 * left.shape[-1]
        ratios = np.concatenate(ratios)
        large = ratios[ratios[:, 0] >= LARGE]
        field_ratio = [float(np.median(large[(large[:, 1] >= low) & (large[:, 1] < high), 2]))
                       for low, high in itertools.pairwise(FIELD)]
        rows[label] = {"params": params.as_dict(),
                       "by_radius": [float(x) for x in residual.sum(1) / variance.sum(1)],
                       "by_channel": [float(x) for x in residual.sum(0) / variance.sum(0)],
                       "by_field": [float(x) for x in field_res / field_var],
                       "blocks_variance": [float(x) for x in variance.sum(1)],
                       "field_residual_per_pixel": [float(x) for x in field_res / field_pixels],
                       "field_variance_per_pixel": [float(x) for x in field_var / field_pixels],
                       "field_disparity_ratio": field_ratio,
                       "total": float(residual.sum() / variance.sum())}
        print(f"{label:22s} total {rows[label]['total']:.4f}  by radius "
              + " ".join(f"{x:.4f}" for x in rows[label]["by_radius"])
              + "  by channel " + " ".join(f"{x:.4f}" for x in rows[label]["by_channel"])
              + "  by field (r >= 4.5) " + " ".join(f"{x:.4f}" for x in rows[label]["by_field"])
              + "  ratio " + " ".join(f"{x:.2f}" for x in field_ratio)
              + "  per pixel: residual " + " ".join(
                  f"{x:.1e}" for x in rows[label]["field_residual_per_pixel"])
              + ", variance " + " ".join(
                  f"{x:.1e}" for x in rows[label]["field_variance_per_pixel"])
              + f"  ({time.monotonic() - started:.0f} s)", flush=True)
    if args.json:
        with open(args.json, "w") as handle:
            json.dump({"bins": BINS, "field": FIELD, "rows": rows}, handle, indent=1)


if __name__ == "__main__":
    main()
