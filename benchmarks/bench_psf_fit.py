"""The full supplement-S2 fit on the 48 real Pixel 4 DP PSF pairs (../shared), timed in one run.

Fits our model (15 x 10 x 10 x 5 shapes x CoC radii x sub-pixel centres) and Punnappurath et al.'s
to all 96 kernels, prints seconds, the mean 2-D correlation of both models and the ratio of the
time per kernel to the time of the whole grid's candidate generation (most of the work is shared
by all kernels).

    .venv/bin/python benchmarks/bench_psf_fit.py [--report runs/pixel4-fit]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from dualpixel.calibration.psf_fit import PAPER_SEARCH_GRID, fit_psf_models
from dualpixel.calibration.report import write_fit_report

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data" / "pixel4-measured-psf"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--report", type=Path, default=None, help="also write the fit report")
    args = parser.parse_args()
    left, right = np.load(SHARED / "left.npy"), np.load(SHARED / "right.npy")
    started = time.perf_counter()
    one = fit_psf_models(left[:1], right[:1], grid=PAPER_SEARCH_GRID, progress=False)
    single = time.perf_counter() - started
    started = time.perf_counter()
    fits = fit_psf_models(left, right, grid=PAPER_SEARCH_GRID)
    full = time.perf_counter() - started
    ours = np.mean([f.correlation for f in fits])
    theirs = np.mean([f.punnappurath_correlation for f in fits])
    best = np.mean([f.punnappurath_best_correlation for f in fits])
    print(f"1 pair: {single:.1f} s; 48 pairs: {full:.1f} s; ratio 48 pairs / 1 pair: "
          f"{full / single:.2f} (the candidate grid is shared by all kernels)")
    print(f"mean 2-D correlation over {len(fits)} kernels: ours {ours:.4f}, Punnappurath "
          f"{theirs:.4f} (best case {best:.4f}); ours higher on "
          f"{sum(f.correlation > f.punnappurath_correlation for f in fits)} of {len(fits)}")
    assert len(one) == 2
    if args.report:
        write_fit_report(fits, {"left": left, "right": right}, args.report,
                         meta={"seconds": round(full, 1), "grid": "paper"})
        print(f"report in {args.report}")


if __name__ == "__main__":
    main()
