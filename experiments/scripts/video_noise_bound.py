"""What earlier frames can add on the video recipe's held-out sequences (issue #75): a model
(the default) on each camera's held-out views as the recipe makes them, with the noise of an
ideal average of ``--frames`` registered frames (each view's noise strength over
sqrt(frames), the same draws), without noise, and on the views as made but with
``--fuse-frames`` (:mod:`dualpixel.inference.frame_fusion`). Same scenes, cameras, seeds and
draws as ``recipes/rdpd-light-video.yaml``'s ``*-test`` steps; the recipe's evaluation (CPU,
float32, its output settings). Writes the data and reports under OUTPUT, then prints Markdown,
and OUTPUT/fuse_frames.png: one phone frame 6 (input, the model, the model with
``--fuse-frames``, target), a crop at full size.

    .venv/bin/python experiments/scripts/video_noise_bound.py runs/video-noise-bound
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
from pathlib import Path

import numpy as np

import dualpixel
from dualpixel.data.layout import discover_dp_dataset, read_frame
from dualpixel.evaluation.run import EvaluationRequest, run_evaluation
from dualpixel.inference.pipeline import build_deblurrer
from dualpixel.io.images import write_png
from dualpixel.synthesis.dataset import synthesize_dataset
from dualpixel.synthesis.scenes import write_scene_folder
from dualpixel.training.recipe import load_recipe, scene_config, synth_config

ARMS = ("as made", "fused", "ideal average", "no noise")


def views(config, arm: str, frames: int):
    """The synthesis settings of an arm's views (the draws are the recipe's)."""
    if arm == "no noise":
        return dataclasses.replace(config, noise=False)
    if arm == "ideal average":
        return dataclasses.replace(config, noise_sigmas=tuple(
            s / math.sqrt(frames) for s in config.noise_sigmas))
    return config


def figure(folder: Path, model: str, frames: int, output: Path) -> None:
    """The last frame of the second sequence: input, ``model``, ``model`` with fusion, target
    (rows 150-350, columns 300-560), side by side."""
    sequence = discover_dp_dataset(folder, "test")[1]
    images = [read_frame(paths) for paths in sequence.frames[:frames]]
    lefts, rights = (np.stack([image[key] for image in images]) for key in ("left", "right"))
    alone, fused = (dualpixel.deblur(lefts, rights, model=model, sequence=True, precision="fp32",
                                     fuse_frames=n) for n in (1, frames))
    last = images[-1]
    panels = [(last["left"] + last["right"]) / 2, alone[-1], fused[-1], last["target"]]
    strip = np.concatenate([p[150:350, 300:560, 1] for p in panels], axis=1)  # grey views
    write_png(output, strip.clip(0, 1), bit_depth=8)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("output", type=Path)
    parser.add_argument("--recipe", type=Path, default=Path("recipes/rdpd-light-video.yaml"))
    parser.add_argument("--model", default="rdpd-light.v16")
    parser.add_argument("--frames", type=int, default=6)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--arms", default=",".join(ARMS),
                        help="comma-separated, of: " + ", ".join(ARMS))
    args = parser.parse_args()
    arms = [arm.strip() for arm in args.arms.split(",")]
    if unknown := set(arms) - set(ARMS):
        parser.error(f"--arms: unknown {', '.join(sorted(unknown))} (of {', '.join(ARMS)})")
    recipe = load_recipe(args.recipe)
    steps = {step.name: step for step in recipe.data}
    config, sequences, seed, photos = scene_config(steps["scenes-test"])
    write_scene_folder(args.output / "data" / "scenes-test", sequences, config, seed=seed,
                       workers=args.workers, progress=False, photos=photos)
    cameras = [name.removesuffix("-test") for name in steps
               if name.endswith("-test") and name != "scenes-test"]
    scores: dict[str, dict[str, dict]] = {}
    for camera in cameras:
        settings, source, fmt = synth_config(recipe, steps[f"{camera}-test"], args.output)
        for arm in arms:
            folder = args.output / "data" / camera / ("as made" if arm == "fused" else arm)
            synthesize_dataset(source, fmt, folder, views(settings, arm, args.frames),
                               workers=args.workers, progress=False)
            report = args.output / "eval" / camera / arm
            if not (report / "summary.json").is_file():
                deblurrer = build_deblurrer(
                    args.model, device="cpu", precision="fp32", **recipe.output_settings,
                    fuse_frames=args.frames if arm == "fused" else 1)
                run_evaluation(EvaluationRequest(output=report, dataset=folder, niqe=False,
                                                 figures=0), deblurrer, "model")
            scores.setdefault(camera, {})[arm] = json.loads(
                (report / "summary.json").read_text())
    if {"as made", "fused"} <= set(arms):
        figure(args.output / "data" / "phone" / "as made", args.model, args.frames,
               args.output / "fuse_frames.png")
    print(f"{args.model}, PSNR (dB) on each camera's held-out sequences:\n")
    print("| views | " + " | ".join(cameras) + " | mean |")
    print("|---|" + "---|" * (len(cameras) + 1))
    for arm in arms:
        values = [scores[c][arm]["summary"]["model"]["combined"]["psnr"] for c in cameras]
        print(f"| {arm} | " + " | ".join(f"{v:.2f}" for v in values)
              + f" | {sum(values) / len(values):.3f} |")
    print("\nBy frame position (mean of the cameras):\n")
    print("| views | " + " | ".join(f"frame {k + 1}" for k in range(args.frames)) + " |")
    print("|---|" + "---|" * args.frames)
    for arm in arms:
        rows = [scores[c][arm]["by_position"]["model"] for c in cameras]
        means = [sum(r[k]["psnr"] for r in rows) / len(rows) for k in range(len(rows[0]))]
        print(f"| {arm} | " + " | ".join(f"{v:.3f}" for v in means) + " |")
    print("\nFlicker, excess change in static regions (levels of 255, mean of the cameras):\n")
    for arm in arms:
        values = [scores[c][arm]["flicker"]["model"]["excess"] for c in cameras]
        print(f"- {arm}: {sum(values) / len(values):+.3f}")


if __name__ == "__main__":
    main()
