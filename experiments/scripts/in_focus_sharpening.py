"""Does a model sharpen what is already sharp? (issue #54; docs/log/2026-11-28-twelfth-session.md)
In the blocks the target-free checks call in focus (textured, the views agree within 0.3 px),
the output's gradient sum over the input's, after the checks' 1-px smoothing: per real Pixel
pair of dp-real-nogt, and per held-out synthetic frame with the sharp target's ratio beside
(what a correct deblur does there). v12 and v15 tied, rdpd-wide.v2 as given.

    python experiments/scripts/in_focus_sharpening.py HELD_OUT_DATASET [--json OUT]
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from dualpixel.data.layout import discover_any
from dualpixel.data.statistics import block_sums
from dualpixel.evaluation.target_free import (  # the checks' own grid and smoothing
    IN_FOCUS_SHIFT,
    NOISE_SIGMA,
    _block_grid,
    _shown,
    block_size,
    model_methods,
    read_pairs,
)
from dualpixel.filters import gradient_magnitude
from dualpixel.inference.overshoot import combined_view
from dualpixel.io.images import read_rgb, read_views


def in_focus_ratios(left: np.ndarray, right: np.ndarray,
                    outputs: dict[str, np.ndarray]) -> dict[str, float] | None:
    """Per output, gradient sum over the in-focus blocks against the input's (None: none)."""
    patch = block_size(left.shape[1])
    names = list(outputs)
    shown = _shown([left, right, combined_view(left, right)] + [outputs[n] for n in names],
                   "srgb", NOISE_SIGMA)
    shifts, textured, core = _block_grid(shown[0], shown[1], patch)
    focus = textured & (np.abs(shifts) <= IN_FOCUS_SHIFT)
    if not focus.any():
        return None
    given = block_sums(gradient_magnitude(shown[2])[core], patch)[focus].sum()
    return {n: float(block_sums(gradient_magnitude(o)[core], patch)[focus].sum() / given)
            for n, o in zip(names, shown[3:])}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("held_out")
    parser.add_argument("--json")
    args = parser.parse_args()
    methods = {**model_methods(["rdpd-light.v12", "rdpd-light.v15"], device="cpu",
                               brightness=["tied"]),
               **model_methods(["rdpd-wide.v2"], device="cpu")}
    results: dict[str, dict[str, dict[str, float]]] = {"real": {}, "synthetic": {}}
    for name, left, right in read_pairs("../shared/data/dp-real-nogt"):
        if name.startswith("pixel"):
            found = in_focus_ratios(left, right, {n: m(left, right) for n, m in methods.items()})
            if found:
                results["real"][name] = found
    for sequence in discover_any(args.held_out, "test", require_target=True)[:12]:
        frame = sequence.frames[0]
        left, right, _ = read_views(frame.left, frame.right)
        target = read_rgb(frame.target)[..., :left.shape[2]]
        found = in_focus_ratios(left, right, {"target": target, **{
            n: m(left, right) for n, m in methods.items()}})
        if found:
            results["synthetic"][sequence.name] = found
    groups = {"Pixel GIF": "pixel-gif", "Pixel MP4": "pixel-mp4"}
    for label, prefix in groups.items():
        rows = [v for k, v in results["real"].items() if k.startswith(prefix)]
        print(label, len(rows), {k: round(float(np.mean([r[k] for r in rows])), 3)
                                 for k in rows[0]})
    rows = list(results["synthetic"].values())
    print("held-out", len(rows), {k: round(float(np.mean([r[k] for r in rows])), 3)
                                  for k in rows[0]})
    if args.json:
        with open(args.json, "w") as handle:
            json.dump(results, handle, indent=1)


if __name__ == "__main__":
    main()
