"""Issue #77 item 3: how sharp the real views are where they are in focus, against the target.

Per textured tile of each dev scene where the two views agree (their difference's energy at
most ``--agree`` of the combined view's fine detail: in focus), the slope of the combined view's
fine detail (the green channel minus its Gaussian blur of 1.5 px) on the target's: 1 where the
view is as sharp as the target. Our formation renders an in-focus view as the target itself; the
same slope is given for the target, and for it blurred by Gaussians of a few widths, coded as the
dev frames were (with the target, in one H.264 animation at CRF 23, or as GIF frames), so the
real views' slope reads as a base blur of the in-focus optics.

    python experiments/scripts/formation_in_focus.py ../shared/data/canon-dp-real-hd --tile 64
    python experiments/scripts/formation_in_focus.py ../shared/data/canon-dp-real --coding gif
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np
from margin_under_coding import coded  # beside this script

from dualpixel.io.images import read_rgb

SIGMAS = (0.0, 0.35, 0.5, 0.7, 1.0)


def fine(image: np.ndarray) -> np.ndarray:
    """Fine detail: ``image`` minus its Gaussian blur of 1.5 px."""
    return image - cv2.GaussianBlur(image, (0, 0), 1.5)


def slopes(scene: Path, tile: int, agree: float, coding: str) -> dict[str, list[float]]:
    """Per in-focus textured tile: the real views' slope and ours at each of :data:`SIGMAS`."""
    left, right, target = (read_rgb(scene / f"{name}.png") for name in ("view0", "view1", "target"))
    ours = {}
    for sigma in SIGMAS:
        view = cv2.GaussianBlur(target, (0, 0), sigma) if sigma else target
        # the dev frames' coding: one H.264 animation at CRF 23 holding each view 10 frames
        view, _, truth = coded((view, view, target), coding, 23, hold=10, loops=3)
        ours[sigma] = (fine(view[..., 1]), fine(truth[..., 1]))
    real, truth = fine((left[..., 1] + right[..., 1]) / 2), fine(target[..., 1])
    difference = left[..., 1] - right[..., 1]
    found: dict[str, list[float]] = {"real": [], **{f"ours, {s:g} px": [] for s in SIGMAS}}
    height, width = truth.shape
    for y in range(0, height - tile + 1, tile):
        for x in range(0, width - tile + 1, tile):
            box = (slice(y, y + tile), slice(x, x + tile))
            energy = (truth[box] ** 2).mean()
            if np.sqrt(energy) < 0.01 or (difference[box] ** 2).mean() > agree * (
                    real[box] ** 2).mean():
                continue  # flat, or the views disagree (defocused)
            found["real"].append(float((real[box] * truth[box]).mean() / energy))
            for sigma, (view, reference) in ours.items():
                found[f"ours, {sigma:g} px"].append(float(
                    (view[box] * reference[box]).mean() / (reference[box] ** 2).mean()))
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("root", type=Path, help="dev scenes: view0, view1, target")
    parser.add_argument("--tile", type=int, default=32)
    parser.add_argument("--agree", type=float, default=0.2)
    parser.add_argument("--coding", choices=("h264", "gif"), default="h264")
    args = parser.parse_args()
    found: dict[str, list[float]] = {}
    for scene in sorted(args.root.glob("scene_*")):
        for key, values in slopes(scene, args.tile, args.agree, args.coding).items():
            found.setdefault(key, []).extend(values)
    print(f"{args.root.name}: {len(found['real'])} in-focus textured tiles; median slope of the "
          "view's fine detail on the target's:")
    print(" | ".join(f"{key} {np.median(values):.2f}" for key, values in found.items()))


if __name__ == "__main__":
    main()
