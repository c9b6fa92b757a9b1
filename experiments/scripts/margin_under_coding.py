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

import dualpixel
from dualpixel.io.images import read_rgb
from dualpixel.synthesis.view_coding import h264_round_trip

CODINGS = ("none", "gif", "h264")


def _psnr(image: np.ndarray, target: np.ndarray) -> float:
    return float(10 * np.log10(1.0 / np.mean((np.clip(image, 0, 1) - target) ** 2)))


def frames(test: Path, count: int) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """The first ``count`` (left, right, target) of a written held-out set, float (H, W, 3)."""
    lefts = sorted((test / "test_l").rglob("*.png"))[:count]
    return [(read_rgb(p), read_rgb(test / "test_r" / p.relative_to(test / "test_l")),
             read_rgb(test / "test_c" / "target" / p.relative_to(test / "test_l" / "source")))
            for p in lefts]


def coded(images: tuple[np.ndarray, ...], coding: str, crf: int) -> list[np.ndarray]:
    """``images`` (float (H, W, 3) in [0, 1]) after ``coding``."""
    if coding == "none":
        return list(images)
    if coding == "gif":
        return [gif_frame(image) for image in images]
    as8 = np.stack([np.clip(np.rint(image * 255), 0, 255).astype(np.uint8) for image in images])
    return list(h264_round_trip(as8, crf) / 255.0)


def gains(models: list[str], test: Path, count: int, coding: str, crf: int) -> list[float]:
    """Mean PSNR gain over the combined input of each model, dB."""
    totals = np.zeros(len(models))
    items = frames(test, count)
    for left, right, target in items:
        left, right, target = coded((left, right, target), coding, crf)
        base = _psnr((left + right) / 2, target)
        for index, model in enumerate(models):
            output = np.asarray(dualpixel.deblur(left, right, model=model, brightness="tied",
                                                 device="cpu"))
            totals[index] += _psnr(output, target) - base
    return list(totals / len(items))


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
        for coding in CODINGS:
            first, second = gains(args.models, test, args.count, coding, args.crf)
            print(f"| {test.name} | {coding} | {first:+.3f} | {second:+.3f} | "
                  f"{second - first:+.3f} |", flush=True)


if __name__ == "__main__":
    main()
