"""What earlier frames can add on the video recipe's held-out sequences (issue #75): a model
(the default) on each camera's held-out views as the recipe makes them, with the noise of an
ideal average of ``--frames`` registered frames (each view's noise strength over
sqrt(frames), the same draws), without noise, and on the views as made but with
``--fuse-frames`` (:mod:`dualpixel.inference.frame_fusion`). Same scenes, cameras, seeds and
draws as ``recipes/rdpd-light-video.yaml``'s ``*-test`` steps; the recipe's evaluation (CPU,
float32, its output settings). Writes the data and reports under OUTPUT, then prints Markdown.

    .venv/bin/python experiments/scripts/video_noise_bound.py runs/video-noise-bound
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
from pathlib import Path

from dualpixel.evaluation.run import EvaluationRequest, run_evaluation
from dualpixel.inference.pipeline import build_deblurrer
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("output", type=Path)
    parser.add_argument("--recipe", type=Path, default=Path("recipes/rdpd-light-video.yaml"))
    parser.add_argument("--model", default="rdpd-light.v16")
    parser.add_argument("--frames", type=int, default=6)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
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
        for arm in ARMS:
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
    print(f"{args.model}, PSNR (dB) on each camera's held-out sequences:\n")
    print("| views | " + " | ".join(cameras) + " | mean |")
    print("|---|" + "---|" * (len(cameras) + 1))
    for arm in ARMS:
        values = [scores[c][arm]["summary"]["model"]["combined"]["psnr"] for c in cameras]
        print(f"| {arm} | " + " | ".join(f"{v:.2f}" for v in values)
              + f" | {sum(values) / len(values):.3f} |")
    print("\nBy frame position (mean of the cameras):\n")
    print("| views | " + " | ".join(f"frame {k + 1}" for k in range(args.frames)) + " |")
    print("|---|" + "---|" * args.frames)
    for arm in ARMS:
        rows = [scores[c][arm]["by_position"]["model"] for c in cameras]
        means = [sum(r[k]["psnr"] for r in rows) / len(rows) for k in range(len(rows[0]))]
        print(f"| {arm} | " + " | ".join(f"{v:.3f}" for v in means) + " |")
    print("\nFlicker, excess change in static regions (levels of 255, mean of the cameras):\n")
    for arm in ARMS:
        values = [scores[c][arm]["flicker"]["model"]["excess"] for c in cameras]
        print(f"- {arm}: {sum(values) / len(values):+.3f}")


if __name__ == "__main__":
    main()
