"""The raw-path decision's verdict (issue #54): the rule in the comment of
experiments/recipes/rdpd-light-raw-path.yaml, item by item, on what `dualpixel reproduce` (the
candidate, RUN/eval) and experiments/scripts/decide_raw_path.sh (rdpd-light.v15 as it ships,
tied, OUT/v15; the target-free checks of both, OUT/target-free) measured.

    python experiments/scripts/decide_raw_path.py --run runs/rawpath --out runs/rawpath/decision
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

from decide_seventh import gain, scene_gains  # this folder: the seventh decision's readers

SETS = ["canon-840", "canon-hd", "canon-stored", "dslr", "phone", "phone-raw", "phone-close"]
TARGET_SET, TARGET_MARGIN = "phone-raw-linear", 0.10  # item 1: dB above v15 there
PSNR_SLACK = 0.05  # item 1: dB below v15 allowed on every other set
TOLERANCE = {"local_brightness": 0.0005, "overshoot": 0.05}  # item 2: check-model's own
FRAME_BRIGHTNESS = 0.01  # item 2
SCENE_SLACK, DEV_FLOOR_HD = 0.1, 1.5  # item 3


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--run", required=True, type=Path)
    parser.add_argument("--out", required=True, type=Path)
    args = parser.parse_args()
    failures = []

    print("1. PSNR gain over the input, held-out synthetic frames (tied)")
    for name in [*SETS, TARGET_SET]:
        mine, v15 = gain(args.run / "eval" / name), gain(args.out / "v15" / name)
        ok = mine >= v15 + TARGET_MARGIN if name == TARGET_SET else mine >= v15 - PSNR_SLACK
        print(f"   {name:18} {mine:+.3f} (v15 {v15:+.3f}, {mine - v15:+.3f})"
              f"{'' if ok else '  <- fails'}")
        if not ok:
            failures.append(f"1: {name} {mine:+.3f} against v15 {v15:+.3f}")

    print("2. real pairs (dualpixel check-model, both tied)")
    rows = list(csv.DictReader(open(args.out / "target-free" / "target_free.csv")))
    methods = sorted({r["method"] for r in rows})
    reference = next(m for m in methods if m.startswith("rdpd-light.v15"))
    candidate = next(m for m in methods if m != reference)
    by_pair = {(r["pair"], r["method"]): r for r in rows}
    pairs = sorted({r["pair"] for r in rows})
    worse = {key: 0 for key in TOLERANCE}
    for pair in pairs:
        mine, base = by_pair[(pair, candidate)], by_pair[(pair, reference)]
        change = float(mine["brightness_change"])
        if abs(change) > FRAME_BRIGHTNESS:
            failures.append(f"2: {pair} brightness {100 * change:+.2f} %")
        for key, slack in TOLERANCE.items():
            if float(mine[key]) > float(base[key]) + slack:
                worse[key] += 1
                failures.append(f"2: {pair} {key} {float(mine[key]):.4g} > v15 "
                                f"{float(base[key]):.4g}")
    for key in TOLERANCE:
        mean_mine = sum(float(by_pair[(p, candidate)][key]) for p in pairs) / len(pairs)
        mean_v15 = sum(float(by_pair[(p, reference)][key]) for p in pairs) / len(pairs)
        print(f"   {key:16} mean {mean_mine:.4f} (v15 {mean_v15:.4f}); pairs above v15 "
              f"beyond {TOLERANCE[key]}: {worse[key]} of {len(pairs)}")
    largest = max(abs(float(by_pair[(p, candidate)]["brightness_change"])) for p in pairs)
    print(f"   largest |brightness change| {100 * largest:.2f} %")

    print("3. dev Canon scenes (a floor)")
    for res in ("canon-dp-real", "canon-dp-real-hd"):
        mine, v15 = scene_gains(args.run / "eval" / res), scene_gains(args.out / "v15" / res)
        a, b = sum(mine.values()) / len(mine), sum(v15.values()) / len(v15)
        worst = min(mine[k] - v15[k] for k in mine)
        print(f"   {res:18} mean {a:+.2f} (v15 {b:+.2f}), worst scene against v15 {worst:+.2f}")
        if res.endswith("-hd") and a < DEV_FLOOR_HD:
            failures.append(f"3: {res} mean {a:+.2f} below +{DEV_FLOOR_HD}")
        if worst < -SCENE_SLACK:
            failures.append(f"3: {res} a scene {worst:+.2f} against v15")

    print("\nverdict:", "the candidate ships" if not failures else "nothing ships")
    for failure in failures[:40]:
        print("   ", failure)
    if len(failures) > 40:
        print(f"    ... and {len(failures) - 40} more")


if __name__ == "__main__":
    main()
