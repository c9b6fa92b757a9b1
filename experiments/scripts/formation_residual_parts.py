"""Issue #77 item 3: which part of a real view that our formation does not explain costs the
model its gain, on one mildly blurred real block.

Our views are rendered from the dev scene's sharp target with the Canon camera's kernels at the
radius that fits the real views best; the residual (real view minus ours) is then added back in
parts: by scale (a Gaussian low-pass split), common to both views or opposite in them, and a
band-limited random field of the same size for comparison. The default model deblurs each; its
PSNR on the crop against the real target:

    python experiments/scripts/formation_residual_parts.py ../shared/data/canon-dp-real/scene_02 \
        --crop 100 200 420 520
"""

from __future__ import annotations

import argparse
import os

import cv2
import numpy as np
import torch

import dualpixel
from dualpixel.calibration.camera import view_kernels
from dualpixel.evaluation.metrics import psnr
from dualpixel.io.images import read_rgb
from dualpixel.optics.camera import load_camera
from dualpixel.optics.tone import linear_to_srgb_array, srgb_to_linear_array


def low_pass(image: np.ndarray, sigma: float) -> np.ndarray:
    return cv2.GaussianBlur(image.astype(np.float32), (0, 0), sigma)


def band_noise(shape: tuple[int, ...], low: float, high: float, rms: float,
               rng: np.random.Generator) -> np.ndarray:
    """A grey random field between Gaussian scales ``low`` and ``high`` px, ``rms`` in [0, 1]."""
    noise = rng.normal(size=shape[:2]).astype(np.float32)
    field = low_pass(noise, low) - low_pass(noise, high)
    return np.repeat((field / field.std() * rms)[..., None], 3, axis=-1)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("scene", help="a dev scene folder: view0, view1, target")
    parser.add_argument("--crop", type=int, nargs=4, default=(100, 200, 420, 520),
                        metavar=("TOP", "BOTTOM", "LEFT", "RIGHT"))
    parser.add_argument("--model", default="rdpd-light")
    parser.add_argument("--camera", default="canon-840-linear")
    parser.add_argument("--fit-margin", type=int, default=40,
                        help="px around the crop the radius is fitted on (0: the crop alone)")
    parser.add_argument("--figure", help="write target | outputs on the real views, ours at "
                        "the fitted radius, ours 0.75 px smaller | published DPDNet here")
    args = parser.parse_args()
    torch.set_num_threads(2)
    left, right, target = (read_rgb(os.path.join(args.scene, f"{n}.png"))
                           for n in ("view0", "view1", "target"))
    top, bottom, x0, x1 = args.crop
    crop = (slice(top, bottom), slice(x0, x1))
    pad = args.fit_margin
    margin = (slice(max(top - pad, 0), bottom + pad), slice(max(x0 - pad, 0), x1 + pad))
    params = load_camera(args.camera).psf
    light = srgb_to_linear_array(target)

    def render(radius: float) -> tuple[np.ndarray, np.ndarray]:
        return tuple(linear_to_srgb_array(cv2.filter2D(light, -1, kernel))
                     for kernel in view_kernels(radius, params))

    def error(radius: float) -> float:
        ours = render(radius)
        return sum(float(((o[margin] - v[margin]) ** 2).mean())
                   for o, v in zip(ours, (left, right)))

    radius = min(np.arange(1.0, 8.01, 0.25), key=error)
    ours_left, ours_right = render(radius)

    def deblurred(view_left: np.ndarray, view_right: np.ndarray) -> np.ndarray:
        return dualpixel.deblur(np.clip(view_left, 0, 1), np.clip(view_right, 0, 1),
                                model=args.model, device="cpu")

    def score(view_left: np.ndarray, view_right: np.ndarray) -> float:
        return psnr(deblurred(view_left, view_right)[crop], target[crop])

    if args.figure:
        panels = [target, deblurred(left, right), deblurred(ours_left, ours_right),
                  deblurred(*render(radius - 0.75)),
                  read_rgb(os.path.join(args.scene, "dpdnet.png"))]
        strip = np.concatenate([np.clip(p[crop], 0, 1) for p in panels], axis=1)
        strip = cv2.resize(strip, None, fx=2, fy=2, interpolation=cv2.INTER_NEAREST)
        cv2.imwrite(args.figure, (strip[..., ::-1] * 255).round().astype(np.uint8))

    res_left, res_right = left - ours_left, right - ours_right
    common, opposite = (res_left + res_right) / 2, (res_left - res_right) / 2
    print(f"best-fitting radius {radius:.2f} px; residual rms common "
          f"{common[crop].std() * 255:.2f}, opposite {opposite[crop].std() * 255:.2f} levels")
    print(f"real views {score(left, right):.2f} dB; ours {score(ours_left, ours_right):.2f}")
    for sigma in (0.7, 1.5, 3.0):
        coarse = score(ours_left + low_pass(res_left, sigma),
                       ours_right + low_pass(res_right, sigma))
        fine = score(ours_left + res_left - low_pass(res_left, sigma),
                     ours_right + res_right - low_pass(res_right, sigma))
        print(f"ours + residual coarser than {sigma} px {coarse:.2f}; finer {fine:.2f}")
    print(f"ours + common residual {score(ours_left + common, ours_right + common):.2f}; "
          f"+ opposite {score(ours_left + opposite, ours_right - opposite):.2f}")
    rng = np.random.default_rng(1)
    rms = float(common[crop].std())
    for low, high in ((1.0, 2.0), (2.0, 4.0)):
        shared = band_noise(target.shape, low, high, rms, rng)
        apart = [band_noise(target.shape, low, high, rms, rng) for _ in range(2)]
        print(f"ours + random {low}-{high} px field of that rms: common "
              f"{score(ours_left + shared, ours_right + shared):.2f}; independent "
              f"{score(ours_left + apart[0], ours_right + apart[1]):.2f}")


if __name__ == "__main__":
    main()
