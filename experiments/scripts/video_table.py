"""Table 2 on our sequences (issue #75): the default, the recipe's `frames` arm and its
`sequences` arm (its shipped weights: state carried, the recipe's own evaluation, and afresh)
on every camera's held-out sequences of a finished `recipes/rdpd-light-video.yaml` run, as the
recipe's evaluation runs them (CPU, float32, brightness tied); PSNR gain per camera, PSNR by
frame position and flicker, as Markdown. ``--arms from-scratch``: the three arms of a finished
`experiments/recipes/table2-from-scratch.yaml` run instead (sRDPD, RDPD with and without its
state, DPDNet, the paper's RDPD on frames and on sequences, and both RDPDs with balanced levels;
no default, none of them started from it).

    .venv/bin/python experiments/scripts/video_table.py runs/rdpd-light-video runs/video-table
    .venv/bin/python experiments/scripts/video_table.py runs/table2-from-scratch \
        runs/table2-table --arms from-scratch
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

CAMERAS = ("canon-840", "canon-hd", "canon-stored", "dslr", "phone", "phone-raw", "phone-close")


SHIPPED = {"fine-tune": "rdpd-light-video.v1", "from-scratch": "table2-rdpd.v1"}


def arms(run: Path, kind: str = "fine-tune") -> dict[str, tuple[str | None, bool]]:
    """Row name -> (weights, afresh); None: the recipe's own evaluation of the shipped weights
    (state carried), read from the run."""
    phases = run / "phases"
    rows = {"rdpd-light.v16 (frames)": ("rdpd-light.v16", False)} if kind == "fine-tune" else {}
    rows |= {"frames arm (sRDPD)": (str(phases / "frames" / "last.safetensors"), False),
             "sequences arm (RDPD), state carried": (None, False),
             "sequences arm, each frame afresh": (
                 str(run / "ship" / f"{SHIPPED[kind]}.safetensors"), True)}
    if kind == "from-scratch":
        rows["dpdnet arm (DPDNet, width 0.25)"] = (
            str(phases / "dpdnet" / "last.safetensors"), False)
        rows["dpdnet arm without the head's ReLU"] = (
            str(phases / "dpdnet-linear-head" / "last.safetensors"), False)
        paper = str(phases / "rdpd-linear-head" / "last.safetensors")
        rows["paper's sRDPD (no residual, refiner or head ReLU)"] = (
            str(phases / "srdpd-linear-head" / "last.safetensors"), False)
        rows["paper's RDPD, state carried"] = (paper, False)
        rows["paper's RDPD, each frame afresh"] = (paper, True)
        for phase, row in (("sequences-balanced", "sequences arm, balanced levels"),
                           ("rdpd-linear-head-balanced", "paper's RDPD, balanced levels")):
            weights = str(phases / phase / "last.safetensors")
            rows[f"{row}, state carried"] = (weights, False)
            rows[f"{row}, each frame afresh"] = (weights, True)
    return rows


def _recipe_evaluation(run: Path, camera: str) -> dict:
    """The recipe's evaluation of the shipped weights on ``camera``'s sequences, with the
    scores by frame position taken from its per-image table."""
    import csv

    from dualpixel.evaluation.evaluate import ImageResult, by_position

    folder = run / "eval" / f"video-{camera}"
    summary = json.loads((folder / "summary.json").read_text())
    with open(folder / "per_image.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    frames: dict[str, list[str]] = {}
    for row in rows:
        sequence, frame = row["name"].split("/")
        frames.setdefault(sequence, [])
        if frame not in frames[sequence]:
            frames[sequence].append(frame)
    results = [ImageResult(row["name"], row["method"], "", float(row["psnr"]),
                           float(row["ssim"]), float(row["mae"]), None, None,
                           position=sorted(frames[row["name"].split("/")[0]]).index(
                               row["name"].split("/")[1])) for row in rows]
    summary["by_position"] = by_position(results)
    return summary


def evaluate_all(run: Path, output: Path, kind: str = "fine-tune") -> dict:
    from dualpixel.evaluation.run import EvaluationRequest, run_evaluation
    from dualpixel.inference.pipeline import build_deblurrer

    found = {}
    for number, (row, (weights, afresh)) in enumerate(arms(run, kind).items()):
        for camera in CAMERAS:
            folder = output / f"arm{number}" / camera
            if weights is None:
                found[row, camera] = _recipe_evaluation(run, camera)
                continue
            if not (folder / "summary.json").is_file():
                deblurrer = build_deblurrer(weights, device="cpu", precision="fp32",
                                            brightness="tied")
                run_evaluation(EvaluationRequest(
                    output=folder, dataset=run / "data" / f"{camera}-test", split="test",
                    niqe=False, figures=0, afresh=afresh), deblurrer, "model")
            found[row, camera] = json.loads((folder / "summary.json").read_text())
    return found


def tables(found: dict) -> str:
    rows = list(dict.fromkeys(row for row, _ in found))
    lines = ["PSNR gain over the input (dB), 6 sequences of 6 frames per camera:", "",
             "| model | " + " | ".join(CAMERAS) + " | mean |", "|---|" + "---|" * 8]
    for row in rows:
        gains = [found[row, c]["summary"]["model"]["combined"]["psnr"]
                 - found[row, c]["summary"]["input"]["combined"]["psnr"] for c in CAMERAS]
        lines.append(f"| {row} | " + " | ".join(f"{g:+.2f}" for g in gains)
                     + f" | {sum(gains) / len(gains):+.3f} |")
    lines += ["", "PSNR gain by frame position (dB, mean of the seven cameras):", ""]
    positions = [e["position"] for e in found[rows[0], CAMERAS[0]]["by_position"]["model"]]
    lines += ["| model | " + " | ".join(f"frame {p + 1}" for p in positions) + " |",
              "|---|" + "---|" * len(positions)]
    for row in rows:
        cells = []
        for p in positions:
            gains = [found[row, c]["by_position"]["model"][p]["psnr"]
                     - found[row, c]["by_position"]["input"][p]["psnr"] for c in CAMERAS]
            cells.append(f"{sum(gains) / len(gains):+.3f}")
        lines.append(f"| {row} | " + " | ".join(cells) + " |")
    lines += ["", "Flicker: excess frame-to-frame change in static regions (levels of 255, "
              "mean of the seven cameras; the input's own in the first row):", "",
              "| model | " + " | ".join(CAMERAS) + " | mean |", "|---|" + "---|" * 8]
    first = [found[rows[0], c]["flicker"]["input"]["excess"] for c in CAMERAS]
    lines.append("| input | " + " | ".join(f"{v:+.3f}" for v in first)
                 + f" | {sum(first) / len(first):+.3f} |")
    for row in rows:
        values = [found[row, c]["flicker"]["model"]["excess"] for c in CAMERAS]
        lines.append(f"| {row} | " + " | ".join(f"{v:+.3f}" for v in values)
                     + f" | {sum(values) / len(values):+.3f} |")
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", type=Path, help="a finished rdpd-light-video run folder")
    parser.add_argument("output", type=Path, help="where the evaluations go (resumes)")
    parser.add_argument("--arms", choices=sorted(SHIPPED), default="fine-tune",
                        help="which recipe made the run (default: recipes/rdpd-light-video.yaml)")
    args = parser.parse_args()
    text = tables(evaluate_all(args.run, args.output, args.arms))
    (args.output / "tables.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
