"""Issue #77: does a model's margin on clean synthetic frames survive the coding the dev views had?

Two models on the first ``--count`` frames of written held-out sets, each frame scored as written
and after the coding of the dev Canon frames: ``gif`` (every image a GIF frame with its own
palette and dither, as the 840-px dev frames) and ``h264`` (left, right and target one H.264
animation at ``--crf``, as the 1620-px dev frames; CRF 23 matches them, ``formation.md``). The
combined input is the mean of the (coded) views; the output is scored against the (coded)
target, as the dev frames score it. Full-frame PSNR gain over the input, dB, tied brightness.

    python experiments/scripts/margin_under_coding.py rdpd-light.v18 runs/coded-at-scale/ship/\
rdpd-light.v19.safetensors --sets runs/coded-at-scale/data/canon-840-test \
        runs/coded-at-scale/data/canon-hd-test
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch
from formation_view_coding import gif_frame
from view_blockiness import as_rgb8, held_out_frames, psnr  # beside this script

import dualpixel
from dualpixel.synthesis.view_coding import h264_round_trip

CODINGS = ("none", "gif", "h264")


def coded(images: tuple[np.ndarray, ...], coding: str, crf: int, **round_trip
          ) -> list[np.ndarray]:
    """``images`` (float (H, W, 3) in [0, 1]) after ``coding``: ``none``, ``gif`` (each its own
    GIF frame) or ``h264`` (one animation at ``crf``; ``round_trip``: its ``hold`` and
    ``loops``)."""
    if coding == "none":
        return list(images)
    if coding == "gif":
        return [gif_frame(image) for image in images]
    as8 = np.stack([as_rgb8(image) for image in images])
    return list(h264_round_trip(as8, crf, **round_trip) / 255.0)


def gains(models: list[str], frames: list, coding: str, crf: int) -> list[float]:
    """Mean PSNR gain over the combined input of each model on ``frames``
    (:func:`view_blockiness.held_out_frames`), dB."""
    totals = np.zeros(len(models))
    for images in frames:
        left, right, target = coded(images, coding, crf)
        base = psnr((left + right) / 2, target)
        for index, model in enumerate(models):
            output = np.asarray(dualpixel.deblur(left, right, model=model, brightness="tied",
                                                 device="cpu"))
            totals[index] += psnr(output, target) - base
    return list(totals / len(frames))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("models", nargs=2, help="two checkpoints (tags or files)")
    parser.add_argument("--sets", nargs="+", type=Path, required=True,
                        help="written held-out sets (split test)")
    parser.add_argument("--count", type=int, default=12)
    parser.add_argument("--crf", type=int, default=23)
    args = parser.parse_args()
    torch.set_num_threads(2)
    names = [Path(model).name.removesuffix(".safetensors") for model in args.models]
    print(f"| set | coding | {names[0]} | {names[1]} | "
          "difference |\n|---|---|---|---|---|")
    for test in args.sets:
        frames = held_out_frames(test, args.count)  # read once for every coding
        for coding in CODINGS:
            first, second = gains(args.models, frames, coding, args.crf)
            print(f"| {test.name} | {coding} | {first:+.3f} | {second:+.3f} | "
                  f"{second - first:+.3f} |", flush=True)


if __name__ == "__main__":
    main()
