"""Target-free checks against known answers (issue #54): on held-out synthetic DP frames, what
`dualpixel check-model`'s checks say of the sharp target (a perfect deblur) and of each model,
beside each model's true local brightness error and flat-block detail error against the target
and its PSNR.

    python experiments/scripts/checks_calibration.py DATASET [DATASET ...] \\
        --checkpoint rdpd-light --checkpoint runs/family6/ship/rdpd-light.v15.safetensors

Each DATASET is a DPDD-layout folder with targets (a recipe's held-out set); its first 12 test
frames are used. Models run with the brightness tied (as the shipped models run).
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from dualpixel.data.layout import discover_any
from dualpixel.evaluation.target_free import (
    check_deblurred,
    flat_detail_error,
    local_brightness_error,
    model_methods,
)
from dualpixel.io.images import read_rgb, read_views


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("datasets", nargs="+")
    parser.add_argument("--checkpoint", action="append", required=True)
    parser.add_argument("--frames", type=int, default=12)
    parser.add_argument("--json", help="also write {dataset: {method: {measure: mean}}} here")
    args = parser.parse_args()
    summary: dict[str, dict[str, dict[str, float]]] = {}
    methods = model_methods(args.checkpoint, device="cpu", brightness=["tied"])
    for root in args.datasets:
        rows: dict[str, dict[str, list[float]]] = {}
        for sequence in discover_any(root, "test", require_target=True)[:args.frames]:
            frame = sequence.frames[0]
            left, right, _ = read_views(frame.left, frame.right)
            target = read_rgb(frame.target)[..., :left.shape[2]]
            outputs = {"target": target, **{name: method(left, right)
                                            for name, method in methods.items()}}
            for name, output in outputs.items():
                report = check_deblurred(left, right, output)
                row = rows.setdefault(name, {"shift": [], "overshoot": [], "error": [],
                                             "invented": [], "flat_error": [], "psnr": []})
                row["shift"].append(report.local_brightness)
                row["overshoot"].append(report.overshoot)
                row["error"].append(local_brightness_error(output, target))
                row["invented"].append(report.invented_texture)
                row["flat_error"].append(flat_detail_error(left, right, output, target))
                mse = float(np.mean((output - target) ** 2))
                row["psnr"].append(-10 * np.log10(mse) if mse > 0 else np.inf)
        print(root)
        means = {name: {k: float(np.nanmean(v)) for k, v in row.items()}  # NaN: no flat block
                 for name, row in rows.items()}
        summary[str(root)] = means
        for name, row in means.items():
            print(f"  {name:40.40} local shift {row['shift']:.4f}  overshoot "
                  f"{row['overshoot']:.3f}  true local error {row['error']:.4f}  invented "
                  f"{row['invented']:.3f}  flat detail error {row['flat_error']:.3f}  PSNR "
                  f"{row['psnr']:.2f}", flush=True)
    if args.json:
        with open(args.json, "w") as file:
            json.dump(summary, file, indent=1)


if __name__ == "__main__":
    main()
