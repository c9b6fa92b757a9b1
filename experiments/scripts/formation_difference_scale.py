"""Issue #77 item 3: what the views' across-field disparity departure costs the default, bounded
at test time.

The real views' difference lies further apart than ours in the middle of the frame and closer at
its sides (``formation_radius_map.py --disparity``: real / ours ``P0 - P2 x^2``, x from -1 to 1
across the width). Before deblurring, each dev scene's views are brought to our formation's
convention by scaling their half-difference: ``L' = S + D / r(x)``, ``R' = S - D / r(x)`` with
``S = (L + R) / 2``, ``D = (L - R) / 2`` and ``r(x) = P0 - P2 x^2`` (for small disparities the
difference scales with it). PSNR of the default's output, whole frame, sides (|x| >= 0.6) and
middle, with and without the scaling: how much a formation that matched the real disparity
across the field could be worth, at most, to this network.

    python experiments/scripts/formation_difference_scale.py ../shared/data/canon-dp-real-hd \
        --profile 1.234 0.544
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import dualpixel
from dualpixel.evaluation.metrics import psnr
from dualpixel.io.images import read_rgb

SIDES = 0.6  # |x| from which a column counts as the frame's side


def scores(image: np.ndarray, target: np.ndarray, side: np.ndarray) -> tuple[float, ...]:
    """PSNR (dB) of ``image`` against ``target``: whole, the side columns, the middle ones."""
    return (psnr(image, target), psnr(image[:, side], target[:, side]),
            psnr(image[:, ~side], target[:, ~side]))


def across(width: int) -> np.ndarray:
    """``(width,)`` each column's place across the frame, -1 (left edge) to 1 (right edge)."""
    return (np.arange(width) + 0.5) / width * 2 - 1


def halves(left: np.ndarray, right: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A pair's mean ``(L + R) / 2`` and half-difference ``(L - R) / 2``: the views are
    ``mean +- half``."""
    return (left + right) / 2, (left - right) / 2


def difference_scaled(left: np.ndarray, right: np.ndarray, profile: tuple[float, float]
                      ) -> tuple[np.ndarray, np.ndarray]:
    """``(H, W, C)`` views with their half-difference divided by ``r(x) = P0 - P2 x^2`` (x from
    -1 to 1 across the width), their mean kept, clipped to [0, 1]."""
    x = across(left.shape[1])
    scale = (1.0 / (profile[0] - profile[1] * x**2))[None, :, None]
    mean, half = halves(left, right)
    return np.clip(mean + scale * half, 0, 1), np.clip(mean - scale * half, 0, 1)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("root", type=Path, help="dev scenes: view0, view1, target")
    parser.add_argument("--profile", type=float, nargs=2, default=(1.234, 0.544),
                        metavar=("P0", "P2"), help="real / our disparity, P0 - P2 x^2")
    parser.add_argument("--model", default="rdpd-light")
    args = parser.parse_args()
    found: dict[str, list[tuple[float, ...]]] = {"input": [], "views": [], "scaled": []}
    for scene in sorted(args.root.glob("scene_*")):
        left, right, target = (read_rgb(scene / f"{name}.png")
                               for name in ("view0", "view1", "target"))
        scaled = difference_scaled(left, right, tuple(args.profile))
        side = np.abs(across(left.shape[1])) >= SIDES
        found["input"].append(scores((left + right) / 2, target, side))
        for name, views in (("views", (left, right)), ("scaled", scaled)):
            output = dualpixel.deblur(*views, model=args.model, device="cpu")
            found[name].append(scores(output, target, side))
    print(f"{args.root.name}, {len(found['input'])} scenes, r(x) = {args.profile[0]:g} - "
          f"{args.profile[1]:g} x^2: mean PSNR, dB\n| | whole | sides | middle |\n"
          "|---|---|---|---|")
    for name, label in (("input", "input"), ("views", "the views as they are"),
                        ("scaled", "their difference scaled by 1 / r(x)")):
        print(f"| {label} | " + " | ".join(f"{v:.3f}" for v in np.mean(found[name], axis=0))
              + " |")


if __name__ == "__main__":
    main()
