"""Cameras outside the family (issue #54): the table of what out_of_family.sh measured, read as
docs/log/2026-11-28-twelfth-session.md fixed before the run.

    python experiments/scripts/out_of_family.py runs/out-of-family \
        [--csv docs/results/outside-family.csv]   # the model card's table reads it
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path
from statistics import mean

from decide_seventh import gain, scene_gains

SETS = ["paper", "disk", "gaussian", "punnappurath", "phone-noisy", "large-blur"]
MODELS = ["rdpd-light.v15", "rdpd-light.v12", "rdpd-wide.v2"]
TIE = 0.05  # dB: v15 "loses" a set only below v12 by more than this


def write_results(out: Path, path: Path, models: list[str], append: bool = False) -> None:
    """Per set, model and image: the input's and the model's PSNR (the model card's source);
    ``append``: added to ``path``'s rows (a model shipped later), replacing none."""
    rows = []
    for s in SETS:
        for m in models:
            found = list(csv.DictReader(open(out / "eval" / s / m / "per_image.csv")))
            given = {r["name"]: r["psnr"] for r in found if r["method"] == "input"}
            rows += [{"evaluation": s, "image": r["name"], "method": r["method"],
                      "input_psnr": f"{float(given[r['name']]):.4f}",
                      "psnr": f"{float(r['psnr']):.4f}"} for r in found if r["method"] != "input"]
    if append:
        existing = list(csv.DictReader(open(path, newline="", encoding="utf-8")))
        known = {r["method"] for r in existing}
        if known & {r["method"] for r in rows}:
            raise SystemExit(f"{path} already holds rows of {sorted(known)}")
        rows = existing + rows
    with open(path, "w", newline="", encoding="utf-8") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]), lineterminator="\n")
        writer.writeheader()
        writer.writerows(rows)


def main(out: Path) -> None:
    gains = {m: {s: gain(out / "eval" / s / m) for s in SETS} for m in MODELS}
    losing = {m: {s: sum(g < 0 for g in scene_gains(out / "eval" / s / m).values())
                  for s in SETS} for m in MODELS}
    print("| set | " + " | ".join(MODELS) + " | v15 - v12 |")
    print("|---|" + "---|" * (len(MODELS) + 1))
    for s in SETS:
        cells = [f"{gains[m][s]:+.2f} ({losing[m][s]} lose)" for m in MODELS]
        diff = gains["rdpd-light.v15"][s] - gains["rdpd-light.v12"][s]
        print(f"| {s} | " + " | ".join(cells) + f" | {diff:+.2f} |")
    means = {m: mean(gains[m].values()) for m in MODELS}
    print("| mean | " + " | ".join(f"{means[m]:+.2f}" for m in MODELS) + " | "
          f"{means['rdpd-light.v15'] - means['rdpd-light.v12']:+.2f} |")
    agrees = means["rdpd-light.v12"] > means["rdpd-wide.v2"]
    print(f"\nranks v12 above v2 as the unseen photographs did: {'yes' if agrees else 'no'}")
    behind = [s for s in SETS if gains["rdpd-light.v15"][s] < gains["rdpd-light.v12"][s] - TIE]
    print(f"sets where v15 is below v12 by more than {TIE} dB: {', '.join(behind) or 'none'}")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", nargs="?", type=Path, default=Path("runs/out-of-family"))
    parser.add_argument("--csv", type=Path, help="also write the per-image results here")
    parser.add_argument("--models", nargs="+", default=MODELS,
                        help="the models whose rows are written (the table needs the three)")
    parser.add_argument("--append", action="store_true", help="add the rows to --csv's")
    args = parser.parse_args()
    if args.models == MODELS:
        main(args.out)
    if args.csv:
        write_results(args.out, args.csv, args.models, args.append)
