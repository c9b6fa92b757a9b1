"""A photographic run's verdict (issue #77, item 7): the rule in its recipe's header, item by
item, on what experiments/scripts/decide_photographs.sh measured and the run's own evaluation.
Reference (``--reference``, the default it would replace): its registry row, its results CSV,
and its scores on the photographic held-out sets measured by the script.

    python experiments/scripts/decide_photographs.py --run runs/rdpd-light-photographs \
        --tag rdpd-light.v17 --reference rdpd-light.v16

``--photo-slack DB``: a photographic held-out set may fall DB below the reference instead of
having to be ahead of it; ``--dev-gain SET=DB``: the dev set's mean gain must be DB above the
reference's (negative: at most that far below; default 0), e.g. for a recipe that trades clean
frames for coded views: ``--photo-slack 0.05 --dev-gain canon-dp-real-hd=0.05 --dev-gain
canon-dp-real=-0.02``.

``--reference-rows``: append the reference's per-image scores on the photographic held-out sets
(evaluations ``photo-*``) to its docs/results CSV unless it holds them, so the model card's
held-out table sets the two models side by side on the same frames (once, after the verdict).
"""

from __future__ import annotations

import argparse
import csv
import json
from pathlib import Path

from decide_seventh import gain, real_pair_failures, scene_gains

CAMERAS = ["canon-840", "canon-hd", "canon-stored", "dslr", "phone", "phone-raw", "phone-close"]
PROCEDURAL_SLACK = 0.1  # rule 1: dB a procedural held-out set may fall below the reference
ROOT = Path(__file__).resolve().parents[2]


def reference_rows(out: Path) -> list[dict[str, str]]:
    """The reference's per-image rows (docs/results columns) on the photographic held-out sets,
    from ``out`` (the script's evaluations of it)."""
    rows = []
    for camera in CAMERAS:
        table = out / f"photo-{camera}" / "per_image.csv"
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
    parser.add_argument("--run", type=Path, default=ROOT / "runs" / "rdpd-light-photographs")
    parser.add_argument("--tag", default="rdpd-light.v17")
    parser.add_argument("--reference", default="rdpd-light.v16")
    parser.add_argument("--reference-rows", action="store_true")
    parser.add_argument("--photo-slack", type=float, default=None, metavar="DB")
    parser.add_argument("--dev-gain", action="append", default=[], metavar="SET=DB")
    args = parser.parse_args()
    try:
        dev_gain = {k: float(v) for k, v in (item.split("=") for item in args.dev_gain)}
    except ValueError:
        raise SystemExit(f"--dev-gain takes SET=DB, got {args.dev_gain}") from None
    run, out, failures = args.run, args.run / "decision", []
    name = args.reference.split(".")[-1]  # "v16"
    registry = json.loads((ROOT / "src/dualpixel/weights/registry.json").read_text())
    ref_row = registry["weights"][args.reference]
    ref_out = out / args.reference

    slack = args.photo_slack
    wanted = f"> {name}" if slack is None else f">= {name} - {slack}"
    print(f"1. photographic held-out sets: PSNR gain over the input (tied), candidate {wanted}")
    for camera in CAMERAS:
        mine, ref = gain(run / "eval" / f"photo-{camera}"), gain(ref_out / f"photo-{camera}")
        ok = mine > ref if slack is None else mine >= ref - slack
        print(f"   {camera:14} {mine:+.2f} ({name} {ref:+.2f}){'' if ok else '  <- fails'}")
        if not ok:
            failures.append(f"1: photographic {camera} {mine:+.2f} against {name} {ref:+.2f}")
    print(f"   procedural held-out sets: PSNR, no more than {PROCEDURAL_SLACK} dB below {name}")
    for camera in CAMERAS:
        summary = json.loads((run / "eval" / camera / "summary.json").read_text())["summary"]
        mine = summary["model"]["combined"]["psnr"]
        ref = ref_row["metrics"][camera]["psnr"]
        ok = mine >= ref - PROCEDURAL_SLACK
        print(f"   {camera:14} {mine:.2f} ({name} {ref:.2f}, {mine - ref:+.2f})"
              f"{'' if ok else '  <- fails'}")
        if not ok:
            failures.append(f"1: procedural {camera} {mine:.2f} against {name} {ref:.2f}")

    print("2. real pairs (dualpixel check-model, tied): the seventh rule's bounds")
    rows = list(csv.DictReader(open(out / "target-free" / "target_free.csv")))
    mine_rows = [r for r in rows if r["method"].endswith("+tied")]
    if not mine_rows:
        raise SystemExit("no tied rows in the target-free table")
    failures += [f"2: {failure}" for failure in real_pair_failures(mine_rows)]

    print(f"3. dev Canon scenes: every scene above its input, means at least {name}'s "
          f"(+ {dev_gain or 0})")
    results = ROOT / "docs" / "results" / f"{args.reference}.csv"
    reference = list(csv.DictReader(open(results)))
    for res in ("canon-dp-real", "canon-dp-real-hd"):
        mine = scene_gains(run / "eval" / res)
        ref = [float(r["psnr"]) - float(r["input_psnr"]) for r in reference
               if r["evaluation"] == res]
        a, b = sum(mine.values()) / len(mine), sum(ref) / len(ref)
        worst, margin = min(mine.values()), dev_gain.get(res, 0.0)
        print(f"   {res:18} mean {a:+.3f} ({name} {b:+.3f}, {a - b:+.3f}; needs {margin:+.3f}), "
              f"worst scene {worst:+.2f}")
        if a < b + margin:
            failures.append(f"3: {res} mean {a:+.3f} against {name} {b:+.3f} (needs "
                            f"{margin:+.3f})")
        if worst <= 0:
            failures.append(f"3: {res} a scene at {worst:+.2f}")

    print("\nverdict:", "the candidate ships" if not failures else "nothing ships")
    for failure in failures:
        print("   ", failure)
    if args.reference_rows and not failures:
        with open(results, newline="") as handle:
            existing = list(csv.DictReader(handle))
        if any(r["evaluation"].startswith("photo-") for r in existing):
            print(f"{results} already holds {name}'s photographic rows")
            return
        with open(results, "a", newline="") as handle:
            writer = csv.DictWriter(handle, fieldnames=list(existing[0]))
            writer.writerows({k: r.get(k, "") for k in existing[0]}
                             for r in reference_rows(ref_out))
        print(f"{name}'s photographic rows appended to {results}")


if __name__ == "__main__":
    main()
