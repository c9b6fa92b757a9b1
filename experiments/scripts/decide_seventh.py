"""The seventh decision's verdict (issue #54): the rule in the comment of
recipes/rdpd-light-cameras.yaml, item by item, on what
experiments/scripts/decide_seventh.sh measured. Reference: rdpd-light.v12 as it ships (tied).

    python experiments/scripts/decide_seventh.py --candidate CAND --out runs/family6/decision
"""

from __future__ import annotations

import argparse
import csv
import json
from pathlib import Path

SETS = ["canon-840-test", "canon-hd-test", "canon-stored-test", "dslr-test", "phone-test",
        "phone-raw-test", "phone-close-test"]
LINEAR = [s for s in SETS if s != "canon-stored-test"]
PSNR_SLACK = 0.05  # item 1: dB below v12 allowed on canon-stored
ERROR_SLACK = 0.05  # item 2: no camera's true local error above v12's by more than 5 %
FRAME_BRIGHTNESS = 0.01  # item 3: largest change of a photograph's brightness
#: item 3: what the sharp target shows on the held-out synthetic frames (written in the rule)
BOUNDS = {"phone": {"local_brightness": 0.0160, "overshoot": 1.73},
          "DSLR": {"local_brightness": 0.0143, "overshoot": 3.10}}
DEV_FLOOR_HD = 1.5  # item 4: dB at 1620x980
SCENE_SLACK = 0.3  # item 4: dB a dev scene may lose against v12


def gain(folder: Path) -> float:
    summary = json.loads((folder / "summary.json").read_text())["summary"]
    name = next(k for k in summary if k != "input")
    return summary[name]["combined"]["psnr"] - summary["input"]["combined"]["psnr"]


def scene_gains(folder: Path) -> dict[str, float]:
    """Per scene, the model's PSNR gain over the input (the published DPDNet rows left out)."""
    rows = list(csv.DictReader(open(folder / "per_image.csv")))
    model = {r["name"]: float(r["psnr"]) for r in rows
             if r["method"] not in ("input", "dpdnet")}
    given = {r["name"]: float(r["psnr"]) for r in rows if r["method"] == "input"}
    return {name: model[name] - given[name] for name in model}


def real_pair_failures(rows: list[dict[str, str]]) -> list[str]:
    """Item 3 on one method's ``check-model`` rows (printed): no frame's brightness changed by
    more than :data:`FRAME_BRIGHTNESS`, per camera the mean local shift and overshoot within
    :data:`BOUNDS`; the failures."""
    cameras = {k: v["camera"] for k, v in json.loads(
        Path("../shared/data/dp-real-nogt/pairs.json").read_text()).items()}
    failures, groups = [], {}
    for row in rows:
        folder, name = row["pair"].split("/", 1)
        groups.setdefault(cameras[name] if folder == "dp-real-nogt" else folder, []).append(row)
        change = float(row["brightness_change"])
        if abs(change) > FRAME_BRIGHTNESS:
            failures.append(f"{row['pair']} brightness {100 * change:+.2f} %")
    print(f"   largest |brightness change| "
          f"{max(abs(float(r['brightness_change'])) for r in rows):.4f}")
    for camera, members in sorted(groups.items()):
        kind = "phone" if "Pixel" in camera else "DSLR"
        for key, bound in BOUNDS[kind].items():
            mean = sum(float(r[key]) for r in members) / len(members)
            ok = mean <= bound
            print(f"   {camera[:40]:40} n={len(members):2} {key:16} {mean:.4f} (bound {bound})"
                  f"{'' if ok else '  <- fails'}")
            if not ok:
                failures.append(f"{camera} mean {key} {mean:.4f} > {bound}")
    return failures


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--candidate", required=True)
    parser.add_argument("--out", required=True, type=Path)
    parser.add_argument("--data", default="runs/family6/data")
    args = parser.parse_args()
    out, failures = args.out, []

    print("1. PSNR gain over the input, held-out synthetic frames (as run, tied)")
    for name in SETS:
        mine, v12 = gain(out / "synth" / name / "candidate"), gain(out / "synth" / name / "v12")
        ok = mine > v12 if name in LINEAR else mine >= v12 - PSNR_SLACK
        print(f"   {name:18} {mine:+.2f} (v12 {v12:+.2f}){'' if ok else '  <- fails'}")
        if not ok:
            failures.append(f"1: {name} {mine:+.2f} against v12 {v12:+.2f}")

    print("2. true local brightness error against the target")
    calibration = json.loads((out / "calibration.json").read_text())
    keys = {Path(k).name: v for k, v in calibration.items()}
    cand = next(m for m in keys[SETS[0]] if m.startswith(args.candidate))
    v12 = next(m for m in keys[SETS[0]] if m.startswith("rdpd-light"))
    mine_all = [keys[s][cand]["error"] for s in SETS]
    v12_all = [keys[s][v12]["error"] for s in SETS]
    for name, a, b in zip(SETS, mine_all, v12_all):
        ok = a <= b * (1 + ERROR_SLACK)
        print(f"   {name:18} {a:.4f} (v12 {b:.4f}){'' if ok else '  <- fails'}")
        if not ok:
            failures.append(f"2: {name} {a:.4f} against v12 {b:.4f} + 5 %")
    mean_mine, mean_v12 = sum(mine_all) / len(SETS), sum(v12_all) / len(SETS)
    print(f"   mean over the seven {mean_mine:.4f} (v12 {mean_v12:.4f})")
    if mean_mine > mean_v12:
        failures.append(f"2: mean {mean_mine:.4f} against v12 {mean_v12:.4f}")
    phone_sets, dslr_sets = SETS[4:], SETS[:4]
    for kind, sets in (("phone", phone_sets), ("DSLR", dslr_sets)):
        shown = {m: sum(keys[s]["target"][m] for s in sets) / len(sets)
                 for m in ("shift", "overshoot")}
        print(f"   (the target on the {kind} sets this run: local shift {shown['shift']:.4f}, "
              f"overshoot {shown['overshoot']:.2f}; the rule's bounds "
              f"{BOUNDS[kind]['local_brightness']}, {BOUNDS[kind]['overshoot']})")

    print("3. real pairs (dualpixel check-model)")
    rows = [r for r in csv.DictReader(open(out / "target-free" / "target_free.csv"))]
    mine_rows = [r for r in rows if r["method"] == args.candidate + "+tied"]
    if not mine_rows:
        raise SystemExit(f"no rows of {args.candidate}+tied in the target-free table")
    failures += [f"3: {failure}" for failure in real_pair_failures(mine_rows)]

    print("4. dev Canon scenes (a floor)")
    for res in ("canon-dp-real", "canon-dp-real-hd"):
        mine = scene_gains(out / "dev" / res / "candidate")
        v12 = scene_gains(out / "dev" / res / "v12")
        a, b = sum(mine.values()) / len(mine), sum(v12.values()) / len(v12)
        worst = min(mine[k] - v12[k] for k in mine)
        print(f"   {res:18} mean {a:+.2f} (v12 {b:+.2f}), worst scene against v12 {worst:+.2f}")
        if a < b:
            failures.append(f"4: {res} mean {a:+.2f} below v12 {b:+.2f}")
        if res.endswith("-hd") and a < DEV_FLOOR_HD:
            failures.append(f"4: {res} mean {a:+.2f} below +{DEV_FLOOR_HD}")
        if worst < -SCENE_SLACK:
            failures.append(f"4: {res} a scene {worst:+.2f} against v12")

    print("\nverdict:", "the candidate ships" if not failures else "nothing ships")
    for failure in failures:
        print("   ", failure)


if __name__ == "__main__":
    main()
