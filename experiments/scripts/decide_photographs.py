"""The photographic run's verdict (issue #77, item 7): the rule in the header of
recipes/rdpd-light-photographs.yaml, item by item, on what experiments/scripts/
decide_photographs.sh measured and the run's own evaluation. Reference: rdpd-light.v15 as it
ships (tied): its registry row, its results CSV, and its scores on the photographic held-out
sets measured by the script.

    python experiments/scripts/decide_photographs.py --run runs/rdpd-light-photographs-cpu

``--v15-rows``: append v15's per-image scores on the photographic held-out sets (evaluations
``photo-*``) to docs/results/rdpd-light.v15.csv, so the model card's held-out table sets the two
models side by side on the same frames (once, after the verdict).
"""

from __future__ import annotations

import argparse
import csv
import json
from pathlib import Path

from decide_seventh import gain, real_pair_failures, scene_gains

CAMERAS = ["canon-840", "canon-hd", "canon-stored", "dslr", "phone", "phone-raw", "phone-close"]
PROCEDURAL_SLACK = 0.1  # rule 1: dB a procedural held-out set may fall below v15
ROOT = Path(__file__).resolve().parents[2]


def v15_rows(out: Path) -> list[dict[str, str]]:
    """v15's per-image rows (docs/results columns) on the photographic held-out sets."""
    rows = []
    for camera in CAMERAS:
        table = out / "v15" / f"photo-{camera}" / "per_image.csv"
        by_image: dict[str, dict[str, str]] = {}
        for row in csv.DictReader(open(table)):
            image = by_image.setdefault(row["name"], {"evaluation": f"photo-{camera}",
                                                      "image": row["name"]})
            prefix = "input_" if row["method"] == "input" else ""
            image[prefix + "psnr"] = f"{float(row['psnr']):.4f}"
            image[prefix + "ssim"] = f"{float(row['ssim']):.4f}"
        rows.extend(by_image.values())
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--run", type=Path, default=ROOT / "runs" / "rdpd-light-photographs-cpu")
    parser.add_argument("--tag", default="rdpd-light.v16")
    parser.add_argument("--v15-rows", action="store_true")
    args = parser.parse_args()
    run, out, failures = args.run, args.run / "decision", []
    registry = json.loads((ROOT / "src/dualpixel/weights/registry.json").read_text())
    v15 = registry["weights"]["rdpd-light.v15"]

    print("1. photographic held-out sets: PSNR gain over the input (tied), candidate > v15")
    for camera in CAMERAS:
        mine, ref = gain(run / "eval" / f"photo-{camera}"), gain(out / "v15" / f"photo-{camera}")
        ok = mine > ref
        print(f"   {camera:14} {mine:+.2f} (v15 {ref:+.2f}){'' if ok else '  <- fails'}")
        if not ok:
            failures.append(f"1: photographic {camera} {mine:+.2f} against v15 {ref:+.2f}")
    print(f"   procedural held-out sets: PSNR, no more than {PROCEDURAL_SLACK} dB below v15")
    for camera in CAMERAS:
        summary = json.loads((run / "eval" / camera / "summary.json").read_text())["summary"]
        mine = summary["model"]["combined"]["psnr"]
        ref = v15["metrics"][camera]["psnr"]
        ok = mine >= ref - PROCEDURAL_SLACK
        print(f"   {camera:14} {mine:.2f} (v15 {ref:.2f}, {mine - ref:+.2f})"
              f"{'' if ok else '  <- fails'}")
        if not ok:
            failures.append(f"1: procedural {camera} {mine:.2f} against v15 {ref:.2f}")

    print("2. real pairs (dualpixel check-model, tied): the seventh rule's bounds")
    rows = list(csv.DictReader(open(out / "target-free" / "target_free.csv")))
    mine_rows = [r for r in rows if r["method"].endswith("+tied")]
    if not mine_rows:
        raise SystemExit("no tied rows in the target-free table")
    failures += [f"2: {failure}" for failure in real_pair_failures(mine_rows)]

    print("3. dev Canon scenes: every scene above its input, means at least v15's")
    reference = list(csv.DictReader(open(ROOT / "docs/results/rdpd-light.v15.csv")))
    for res in ("canon-dp-real", "canon-dp-real-hd"):
        mine = scene_gains(run / "eval" / res)
        ref = [float(r["psnr"]) - float(r["input_psnr"]) for r in reference
               if r["evaluation"] == res]
        a, b = sum(mine.values()) / len(mine), sum(ref) / len(ref)
        worst = min(mine.values())
        print(f"   {res:18} mean {a:+.2f} (v15 {b:+.2f}), worst scene {worst:+.2f}")
        if a < b:
            failures.append(f"3: {res} mean {a:+.2f} below v15 {b:+.2f}")
        if worst <= 0:
            failures.append(f"3: {res} a scene at {worst:+.2f}")

    print("\nverdict:", "the candidate ships" if not failures else "nothing ships")
    for failure in failures:
        print("   ", failure)
    if args.v15_rows and not failures:
        path = ROOT / "docs/results/rdpd-light.v15.csv"
        with open(path, newline="") as handle:
            existing = list(csv.DictReader(handle))
        if any(r["evaluation"].startswith("photo-") for r in existing):
            print(f"{path} already holds v15's photographic rows")
            return
        with open(path, "a", newline="") as handle:
            writer = csv.DictWriter(handle, fieldnames=list(existing[0]))
            writer.writerows({k: r.get(k, "") for k in existing[0]} for r in v15_rows(out))
        print(f"v15's photographic rows appended to {path}")


if __name__ == "__main__":
    main()
