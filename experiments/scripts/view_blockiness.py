"""Issue #77 item 3: how strongly real DP views were block-coded, against the coding training gives.

:func:`dualpixel.inference.view_checks.blockiness` (steps on the coder's 8-px grid over those
between it; about 1 uncoded) of every left view of the real pairs in ``../shared``, and of
held-out synthetic phone views (a written set of the photographic recipe) after the H.264 coding
of ``view_coding`` (both views in one animation) at several CRFs, at their own exposure and
scaled to the real phone views' (their 99.5th percentile); then what coding that hard costs the
default: its PSNR gain over the combined input (green channel, against the clean target) on the
same frames coded at each CRF (views coded at the dark exposure are scaled back before the model).

    python experiments/scripts/view_blockiness.py runs/rdpd-light-photographs/data/phone-test
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import dualpixel
from dualpixel.inference.view_checks import blockiness
from dualpixel.io.images import read_rgb
from dualpixel.synthesis.view_coding import h264_round_trip
from dualpixel.weights import DEFAULT_CHECKPOINT

SHARED = Path("../shared/data")
REAL = {"Pixel 4, GIF frames": ("dp-real-nogt", "pixel-gif-0?/left.png"),
        "Pixel 4, MP4 frames": ("dp-real-nogt", "pixel-mp4-0?/left.png"),
        "Canon R6 II": ("dp-real-nogt", "sdirt-*/left.png"),
        "dev Canon, 840 px (GIF)": ("canon-dp-real", "scene_*/view0.png"),
        "dev Canon, 1620 px (H.264)": ("canon-dp-real-hd", "scene_*/view0.png")}
CRFS = (18, 24, 30, 36, 42, 48)


def _row(label: str, values: list[float]) -> str:
    values = [v for v in values if v is not None]
    return (f"| {label} | {len(values)} | {np.median(values):.2f} | {min(values):.2f} - "
            f"{max(values):.2f} |")


def psnr(image: np.ndarray, target: np.ndarray) -> float:
    """PSNR (dB) of ``image``, clipped to [0, 1], against ``target``."""
    return float(10 * np.log10(1.0 / np.mean((np.clip(image, 0, 1) - target) ** 2)))


def _coded(left: np.ndarray, right: np.ndarray, crf: int | None, scale: float
           ) -> tuple[np.ndarray, np.ndarray]:
    """The pair (float ``(H, W, 3)`` in [0, 1]) coded at ``crf`` (None: not coded) after its
    light was scaled by ``scale``, then scaled back."""
    if crf is None:
        return left, right
    coded = h264_round_trip(np.stack([as_rgb8(left * scale), as_rgb8(right * scale)]), crf)
    return coded[0] / 255.0 / scale, coded[1] / 255.0 / scale


def as_rgb8(image: np.ndarray) -> np.ndarray:
    """A float image in [0, 1] as 8-bit levels, rounded."""
    return np.clip(np.round(image * 255), 0, 255).astype(np.uint8)


def held_out_frames(test: Path, count: int) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """The first ``count`` (left, right, target) of a written held-out set, float
    ``(H, W, 3)``."""
    lefts = sorted((test / "test_l").rglob("*.png"))[:count]
    return [(read_rgb(p), read_rgb(test / "test_r" / p.relative_to(test / "test_l")),
             read_rgb(test / "test_c" / "target" / p.relative_to(test / "test_l" / "source")))
            for p in lefts]


def coded_psnr(frames: list, crf: int | None, scales: list[float],
               model=DEFAULT_CHECKPOINT) -> tuple[float, float]:
    """Mean PSNR (dB, green) of the combined input and of ``model``'s output (tied brightness)
    with every pair of ``frames`` (:func:`held_out_frames`) coded at ``crf`` after its light was
    scaled by its ``scales`` entry."""
    scores = []
    for (left, right, target), scale in zip(frames, scales):
        target = target[..., 1]
        left, right = (np.clip(v[..., 1], 0, 1) for v in _coded(left, right, crf, scale))
        output = np.asarray(dualpixel.deblur(left, right, model=model, brightness="tied"))
        scores.append((psnr((left + right) / 2, target), psnr(output, target)))
    inputs, outputs = np.mean(scores, axis=0)
    return float(inputs), float(outputs)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("phone_set", type=Path, help="a written phone held-out set (split test)")
    parser.add_argument("--count", type=int, default=8)
    args = parser.parse_args()
    print("| views | pairs | blockiness, median | range |\n|---|---|---|---|")
    real_peak = []
    for label, (folder, pattern) in REAL.items():
        paths = sorted((SHARED / folder).glob(pattern))
        views = [read_rgb(path) for path in paths]
        if label.startswith("Pixel"):
            real_peak += [float(np.percentile(v, 99.5)) for v in views]
        print(_row(label, [blockiness(v) for v in views]))
    exposure = float(np.median(real_peak))
    frames = held_out_frames(args.phone_set, args.count)
    scales = {"own exposure": [1.0] * len(frames),
              f"at the real views' ({exposure:.2f})": [
                  exposure / max(float(np.percentile(left, 99.5)), 1e-6)
                  for left, _, _ in frames]}
    for label, factors in scales.items():
        for crf in CRFS:
            values = [blockiness(_coded(left, right, crf, scale)[0])
                      for (left, right, _), scale in zip(frames, factors)]
            print(_row(f"ours, phone, H.264 CRF {crf}, {label}", values))
    print("\n| views | input PSNR, dB | output PSNR, dB | gain, dB |\n|---|---|---|---|")
    for k, (label, factors) in enumerate(scales.items()):
        for crf in ((None,) if k == 0 else ()) + (18, 24, 30, 36, 44):
            inputs, outputs = coded_psnr(frames, crf, factors)
            name = "clean" if crf is None else f"H.264 CRF {crf}, {label}"
            print(f"| {name} | {inputs:.2f} | {outputs:.2f} | {outputs - inputs:+.2f} |")

if __name__ == "__main__":
    main()
