"""A camera's DP blur from its two views alone, pooled over frames (issue #74 item 1).

Renders validation photographs with a known camera (``canon-840-linear``; depth ``ramp``: 1-7 m
across the frame, or ``steps``: seven fronto-parallel planes), fits the whitened cross-convolution
of :mod:`dualpixel.calibration.target_free` to the views alone and compares the pooled ratios and
each informative block's radius with the truth.

    python experiments/scripts/target_free_whitened.py [noise|clean] [ramp|steps] [N_PHOTOS]

``LAMBDA`` sets the whitening's regularisation, ``PATCH`` the block size.
"""

from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path

import cv2
import numpy as np

import dualpixel
from dualpixel.calibration.target_free import pool_constants, view_energies
from dualpixel.data.statistics import block_sums
from dualpixel.io.images import read_rgb
from dualpixel.optics.psf import PSFParams
from dualpixel.optics.tone import srgb_to_linear_array

ROOT = Path(__file__).resolve().parents[2]
PHOTOS = ROOT.parent / "shared" / "data" / "photographs" / "validation"
PATCH = int(os.environ.get("PATCH", 48))
RADII = np.arange(0.5, 12.01, 0.25)
RATIOS = np.arange(0.2, 1.51, 0.025)


def render(photo: Path, layout: str, noise: bool, seed: int) -> tuple[np.ndarray, ...]:
    image = cv2.resize(read_rgb(photo), (840, 560), interpolation=cv2.INTER_AREA)
    ys, xs = np.mgrid[0:560, 0:840]
    if layout == "steps":
        depth = 1.0 + (xs // 120)
    else:
        depth = 1.0 + 6.0 * (xs / 840) ** 1.5 + 0.5 * np.sin(ys / 60)
    frame = dualpixel.synthesize(image, depth.astype(np.float32), camera="canon-840-linear",
                                 seed=seed, distortion=False, noise=noise)
    left, right = (srgb_to_linear_array(np.asarray(frame[k], np.float32)).astype(np.float32)
                   for k in ("left", "right"))
    return left, right, np.asarray(frame["defocus"], np.float64)


def main(mode: str, layout: str, count: int) -> None:
    camera = json.loads((ROOT / "src/dualpixel/cameras/canon-840-linear.json").read_text())
    params = PSFParams(**camera["psf"])
    regularisation = float(os.environ.get("LAMBDA", 1e-2))
    start = time.perf_counter()
    energies, truths = [], []
    for seed, photo in enumerate(sorted(PHOTOS.iterdir())[:count]):
        left, right, defocus = render(photo, layout, mode == "noise", seed)
        energy = view_energies(left, right, params, RADII, RATIOS, patch=PATCH,
                               regularisation=regularisation)
        m = int(energy.centres[0, 0, 0] - PATCH / 2)
        rows, cols = energy.centres.shape[:2]
        truths.append(block_sums(defocus[m: m + rows * PATCH, m: m + cols * PATCH], PATCH)
                      / PATCH**2)
        energies.append(energy)
    fit = pool_constants(energies)
    usable = [(np.abs(t) >= 1.0) & i for t, i in zip(truths, fit.informative)]
    error = np.concatenate([(r - np.abs(t))[u] for r, t, u in zip(fit.radius, truths, usable)])
    signs = np.concatenate([((s > 0) == (t > 0))[u] for s, t, u in zip(fit.side, truths, usable)])
    print(f"{count} photos, {layout}, {mode}, lambda {regularisation:g}: "
          f"{time.perf_counter() - start:.0f} s; ratios {np.round(fit.ratio, 3)} (camera "
          f"{camera['disparity_ratio']}); {error.size} informative blocks with |r| >= 1; radius "
          f"error median {np.median(error):+.2f} px, |error| p50 "
          f"{np.percentile(np.abs(error), 50):.2f} p90 {np.percentile(np.abs(error), 90):.2f}; "
          f"side agreement {signs.mean():.2f}")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "noise",
         sys.argv[2] if len(sys.argv) > 2 else "ramp",
         int(sys.argv[3]) if len(sys.argv) > 3 else 6)
