"""How close frame fusion's views come to the noise-free views (issue #75): variants of
:mod:`dualpixel.inference.frame_fusion` (warp interpolation, match level, smoothing) on
sequences made like the video recipe's training ones (train photographs, a seed of their own,
so neither its training nor its held-out sequences), per camera: PSNR of each frame's fused
views against the same draw's views without noise, frames 2-6, and of the views as made.

    .venv/bin/python experiments/scripts/fusion_probe.py runs/fusion-probe
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import numpy as np

from dualpixel.data.layout import discover_dp_dataset, read_frame
from dualpixel.inference import frame_fusion
from dualpixel.synthesis.dataset import synthesize_dataset
from dualpixel.synthesis.scenes import write_scene_folder
from dualpixel.training.recipe import load_recipe, scene_config, synth_config

#: name -> FrameFusion's settings (its defaults: the last)
BEFORE = {"match_spreads": 0, "max_match_level": 0.01, "smoothing_px": 2.0,
          "flow_smoothing_px": 0.0}  # one fixed level, until 2026-12-04
VARIANTS = {
    "one fixed level (before)": BEFORE,
    "flow on guides blurred 1 px": {**BEFORE, "flow_smoothing_px": 1.0},
    "flow blurred 1 px, level 3 spreads": {**BEFORE, "flow_smoothing_px": 1.0,
                                           "match_spreads": 3.0, "max_match_level": 1.0},
    "the same, smoothing 1 px, level at most 0.03 (now)": {},
}


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    return float(10 * np.log10(1.0 / np.mean((a.clip(0, 1) - b) ** 2)))


def fused_psnrs(noisy: Path, clean: Path, variant: dict, frames: int) -> list[float]:
    """Per frame 2..N of every sequence, the fused views' PSNR (left and right together);
    ``frames`` 1: the views as made."""
    scores = []
    for made, truth in zip(discover_dp_dataset(noisy, "train"),
                           discover_dp_dataset(clean, "train"), strict=True):
        fusion = frame_fusion.FrameFusion(frames, **variant)
        for k, (paths, true_paths) in enumerate(zip(made.frames, truth.frames, strict=True)):
            image, reference = read_frame(paths), read_frame(true_paths)
            left, right = fusion(image["left"], image["right"])
            if k:
                both = np.concatenate([left, right])
                scores.append(psnr(both, np.concatenate([reference["left"],
                                                         reference["right"]])))
    return scores


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("output", type=Path)
    parser.add_argument("--recipe", type=Path, default=Path("recipes/rdpd-light-video.yaml"))
    parser.add_argument("--cameras", default="canon-840,dslr,phone")
    parser.add_argument("--sequences", type=int, default=4)
    parser.add_argument("--seed", type=int, default=54000)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    recipe = load_recipe(args.recipe)
    steps = {step.name: step for step in recipe.data}
    config, _, _, photos = scene_config(steps["scenes-train"])
    scenes = args.output / "data" / "scenes-train"
    write_scene_folder(scenes, args.sequences, config, seed=args.seed, workers=args.workers,
                       progress=False, photos=photos)
    frames = config.frames
    rows = {}
    for camera in args.cameras.split(","):
        settings, _, fmt = synth_config(recipe, steps[f"{camera}-train"], args.output)
        folders = {}
        for arm, arm_settings in (("as made", settings),
                                  ("no noise", dataclasses.replace(settings, noise=False))):
            folders[arm] = args.output / "data" / camera / arm
            synthesize_dataset(scenes, fmt, folders[arm], arm_settings, workers=args.workers,
                               progress=False)
        rows.setdefault("as made", {})[camera] = np.mean(
            fused_psnrs(folders["as made"], folders["no noise"], {}, 1))
        for name, variant in VARIANTS.items():
            rows.setdefault(name, {})[camera] = np.mean(
                fused_psnrs(folders["as made"], folders["no noise"], variant, frames))
        print(camera, {name: round(row[camera], 3) for name, row in rows.items()}, flush=True)
    cameras = args.cameras.split(",")
    print("\n| views, frames 2-6 | " + " | ".join(cameras) + " |")
    print("|---|" + "---|" * len(cameras))
    for name, row in rows.items():
        print(f"| {name} | " + " | ".join(f"{row[c]:.2f}" for c in cameras) + " |")


if __name__ == "__main__":
    main()
