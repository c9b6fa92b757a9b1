"""Issue #77 item 3: how sharp the real views are where they are in focus, against the target.

Per textured tile of each dev scene where the two views agree (their difference's energy at
most ``--agree`` of the combined view's fine detail: in focus), three measures of the combined
view's fine detail (the green channel minus its Gaussian blur of 1.5 px) against the target's:

- ``slope``: its regression slope on the target's, 1 where the view is the target; lowered both
  by a softer view and by a target off by a sub-pixel shift;
- ``aligned``: the same slope once the target is moved by the tile's shift (phase correlation
  of the two fine details), which is also reported (``shift``, px);
- ``rms``: the ratio of the two fine details' RMS, which no shift changes.

Our formation renders an in-focus view as the target itself; the same measures are given for
the target blurred by Gaussians of a few widths, coded as the dev frames were (with the target,
in one H.264 animation at CRF 23, or as GIF frames), so the real views' ``rms`` reads as a base
blur of the in-focus optics.

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

SIGMAS = (0.0, 0.35, 0.5, 0.6, 0.7, 1.0)


def fine(image: np.ndarray) -> np.ndarray:
    """Fine detail: ``image`` minus its Gaussian blur of 1.5 px."""
    return image - cv2.GaussianBlur(image, (0, 0), 1.5)


def shifted(image: np.ndarray, dy: float, dx: float) -> np.ndarray:
    """``image`` moved by ``(dy, dx)`` px (bicubic, edges reflected)."""
    move = np.float32([[1, 0, dx], [0, 1, dy]])
    return cv2.warpAffine(image, move, image.shape[::-1], flags=cv2.INTER_CUBIC,
                          borderMode=cv2.BORDER_REFLECT)


def measures(view: np.ndarray, truth: np.ndarray, sharp: np.ndarray, box: tuple[slice, slice],
             tile: int) -> dict[str, float]:
    """``slope``, ``aligned``, ``shift`` and ``rms`` (module text) of one tile ``box`` of the
    fine details ``view`` and ``truth``; ``sharp`` is the target (green) they come from."""
    energy = (truth[box] ** 2).mean()
    window = np.outer(np.hanning(tile), np.hanning(tile))
    (dx, dy), _ = cv2.phaseCorrelate(truth[box].astype(np.float64),
                                     view[box].astype(np.float64), window)
    rows, cols = box
    around = (slice(rows.start - tile, rows.stop + tile),
              slice(cols.start - tile, cols.stop + tile))
    moved = fine(shifted(sharp[around], dy, dx))[tile:-tile, tile:-tile]
    return {"slope": float((view[box] * truth[box]).mean() / energy),
            "aligned": float((view[box] * moved).mean() / (moved ** 2).mean()),
            "shift": float(np.hypot(dx, dy)),
            "rms": float(np.sqrt((view[box] ** 2).mean() / energy))}


def tiles(scene: Path, tile: int, agree: float, coding: str) -> dict[str, list[dict]]:
    """Per in-focus textured tile (not on the frame's outer tile ring): the real views'
    :func:`measures` and ours at each of :data:`SIGMAS`."""
    left, right, target = (read_rgb(scene / f"{name}.png") for name in ("view0", "view1", "target"))
    ours = {}
    for sigma in SIGMAS:
        view = cv2.GaussianBlur(target, (0, 0), sigma) if sigma else target
        # the dev frames' coding: one H.264 animation at CRF 23 holding each view 10 frames
        view, _, truth = coded((view, view, target), coding, 23, hold=10, loops=3)
        ours[f"ours, {sigma:g} px"] = (fine(view[..., 1]), fine(truth[..., 1]), truth[..., 1])
    real, truth = fine((left[..., 1] + right[..., 1]) / 2), fine(target[..., 1])
    difference = left[..., 1] - right[..., 1]
    found: dict[str, list[dict]] = {"real": [], **{key: [] for key in ours}}
    height, width = truth.shape
    for y in range(tile, height - 2 * tile + 1, tile):
        for x in range(tile, width - 2 * tile + 1, tile):
            box = (slice(y, y + tile), slice(x, x + tile))
            if np.sqrt((truth[box] ** 2).mean()) < 0.01 or (difference[box] ** 2).mean() > agree * (
                    real[box] ** 2).mean():
                continue  # flat, or the views disagree (defocused)
            found["real"].append(measures(real, truth, target[..., 1], box, tile))
            for key, (view, reference, sharp) in ours.items():
                found[key].append(measures(view, reference, sharp, box, tile))
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("root", type=Path, help="dev scenes: view0, view1, target")
    parser.add_argument("--tile", type=int, default=32)
    parser.add_argument("--agree", type=float, default=0.2)
    parser.add_argument("--coding", choices=("h264", "gif"), default="h264")
    args = parser.parse_args()
    found: dict[str, list[dict]] = {}
    for scene in sorted(args.root.glob("scene_*")):
        for key, values in tiles(scene, args.tile, args.agree, args.coding).items():
            found.setdefault(key, []).extend(values)
    print(f"{args.root.name}: {len(found['real'])} in-focus textured tiles, medians of the "
          "combined view's fine detail against the target's")
    print("| views | slope | aligned slope | target's shift, px | RMS ratio |\n"
          "|---|---|---|---|---|")
    for key, values in found.items():
        row = (np.median([v[m] for v in values]) for m in ("slope", "aligned", "shift", "rms"))
        print(f"| {key} | " + " | ".join(f"{v:.2f}" for v in row) + " |")


if __name__ == "__main__":
    main()
