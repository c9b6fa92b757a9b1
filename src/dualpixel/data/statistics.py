"""Statistics of DP datasets: disparity, blur size, noise and gradient content, for
matching synthetic data to a camera.

Everything is measured at the resolution the images are stored at (the resolution a network sees),
per ``patch x patch`` block of the grey (channel-mean) image:

- **disparity** (px): the horizontal shift ``d`` of the right view against the left,
  ``R(x) ~ L(x - d)``, found by minimising the SSD of the horizontal gradients over integer shifts
  and refined by a parabola through the three best. Positive means the right view lies to the right
  (with our convention, a point behind the focal plane, CoC r > 0). Only textured blocks count.
- **blur** (px): the std of the Gaussian that best maps the target onto the combined input (least
  squares over the block), from a grid of 0 .. ``max_sigma`` px in 0.25 px steps. Needs a target;
  only blocks whose target has texture count (a flat block has no measurable blur).
- **noise**: the std of the input's noise per image, in [0, 1] units: Immerkaer's (1996) 3x3
  Laplacian-difference filter (which cancels locally linear image content and has gain 6 on white
  noise) with a median-absolute-deviation estimate of its std, robust to edges.
- **gradient**: the fraction of input pixels whose gradient magnitude (central differences of the
  grey image, per pixel) exceeds 0.05, per image.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from dualpixel.data.layout import discover_any, read_frame
from dualpixel.errors import InputFileError, ParameterError
from dualpixel.filters import channel_mean
from dualpixel.optics.tone import combined_image

__all__ = [
    "DatasetStatistics",
    "FrameStatistics",
    "block_disparity_map",
    "block_sums",
    "dataset_statistics",
    "defocus_shift_counts",
    "frame_statistics",
]

PERCENTILES = (25, 50, 75, 90)
BLUR_STEP = 0.25
GRADIENT_THRESHOLD = 0.05


@dataclass
class FrameStatistics:
    """Per-block and per-image measurements of one frame (see the module docstring)."""

    disparity: np.ndarray  # (n,) signed px, textured blocks
    blur: np.ndarray  # (m,) px, textured target blocks; empty without a target
    noise: float
    gradient_fraction: float


@dataclass
class DatasetStatistics:
    """Measurements pooled over a dataset's frames, with percentile summaries."""

    name: str
    frames: int
    size: tuple[int, int]  # (H, W) of the first frame
    disparity: np.ndarray
    blur: np.ndarray
    noise: np.ndarray
    gradient_fraction: np.ndarray
    max_blur: float = 8.0
    extra: dict = field(default_factory=dict)

    def summary(self) -> dict:
        """Percentiles (p25, p50, p75, p90) of every statistic, JSON-ready."""

        def pct(values: np.ndarray) -> dict[str, float] | None:
            if values.size == 0:
                return None
            return {f"p{p}": round(float(np.percentile(values, p)), 4) for p in PERCENTILES}

        return {
            "name": self.name, "frames": self.frames, "size": f"{self.size[1]}x{self.size[0]}",
            "abs_disparity_px": pct(np.abs(self.disparity)),
            "disparity_px": pct(self.disparity),
            "blur_sigma_px": pct(self.blur),
            "blur_at_max_fraction": (round(float(np.mean(self.blur >= self.max_blur)), 4)
                                     if self.blur.size else None),
            "noise_std": pct(self.noise),
            "gradient_fraction": pct(self.gradient_fraction),
            **self.extra,
        }


def block_sums(values: np.ndarray, patch: int, dtype=None) -> np.ndarray:
    """Sums over non-overlapping ``patch`` blocks of ``(H, W, ...)`` values, ``(H // patch,
    W // patch, ...)`` (the remainder at the borders is dropped); ``dtype``: the accumulator."""
    rows, cols = values.shape[0] // patch, values.shape[1] // patch
    trimmed = values[: rows * patch, : cols * patch]
    return trimmed.reshape(rows, patch, cols, patch, *values.shape[2:]).sum(axis=(1, 3),
                                                                          dtype=dtype)


def _textured(grey: np.ndarray, patch: int, threshold: float) -> np.ndarray:
    """Blocks whose mean absolute horizontal gradient exceeds ``threshold`` (bool per block)."""
    gradient = np.abs(np.diff(grey, axis=1, append=grey[:, -1:]))
    return block_sums(gradient, patch) / patch**2 > threshold


def block_disparity_map(
    left: np.ndarray, right: np.ndarray, *, patch: int = 64, max_shift: int = 12,
    min_texture: float = 0.004,
) -> tuple[np.ndarray, np.ndarray, int]:
    """Signed horizontal shift of ``right`` against ``left`` per block, px ``(rows, cols)``,
    whether each block is textured enough to trust it, and the image column where the block
    grid starts (``max_shift``: the search needs that margin); rows start at 0."""
    grey_left = channel_mean(left)
    gl, gr = np.diff(grey_left, axis=1), np.diff(channel_mean(right), axis=1)
    width = gl.shape[1]
    if width <= 2 * max_shift + 1:
        raise ParameterError(f"images must be wider than {2 * max_shift + 1} px, got {width + 1}")
    core = slice(max_shift, width - max_shift)
    right_core, diff = gr[:, core], np.empty_like(gr[:, core])
    costs = []
    for shift in range(-max_shift, max_shift + 1):
        # R(x) = L(x - d): compare R at x with L at x - d
        np.subtract(right_core, gl[:, max_shift - shift : width - max_shift - shift], out=diff)
        costs.append(block_sums(np.multiply(diff, diff, out=diff), patch))
    cost = np.stack(costs)  # (S, rows, cols)
    best = cost.argmin(axis=0)
    inner = np.clip(best, 1, cost.shape[0] - 2)
    c0 = np.take_along_axis(cost, (inner - 1)[None], 0)[0]
    c1 = np.take_along_axis(cost, inner[None], 0)[0]
    c2 = np.take_along_axis(cost, (inner + 1)[None], 0)[0]
    curvature = c0 - 2 * c1 + c2
    offset = np.where(curvature > 0, 0.5 * (c0 - c2) / np.maximum(curvature, 1e-12), 0.0)
    shift = inner - max_shift + np.clip(offset, -0.5, 0.5)
    textured = _textured(grey_left[:, core], patch, min_texture)
    return shift.astype(np.float32), textured, max_shift


def block_disparity(
    left: np.ndarray, right: np.ndarray, *, patch: int = 64, max_shift: int = 12,
    min_texture: float = 0.004,
) -> np.ndarray:
    """Signed horizontal shift of ``right`` against ``left`` per textured block, px ``(n,)``."""
    shift, textured, _ = block_disparity_map(left, right, patch=patch, max_shift=max_shift,
                                             min_texture=min_texture)
    return shift[textured]


#: A block counts as defocused when its views shift by more than this (px).
DEFOCUSED_SHIFT = 0.75
#: At least this many defocused blocks before the direction of their shift is read.
MIN_DEFOCUSED_BLOCKS = 12


def defocus_shift_counts(left: np.ndarray, right: np.ndarray) -> tuple[int, int] | None:
    """How many defocused blocks of a DP pair shift as content behind the focus plane does
    (``right`` shifted right of ``left``) and how many as content in front of it, or ``None``
    when the pair is too small or has too few defocused blocks to tell (64-px blocks from
    1280 px wide, 32-px below)."""
    patch = 64 if left.shape[1] >= 1280 else 32
    if left.shape[0] < 2 * patch or left.shape[1] < 4 * patch:
        return None
    shifts = block_disparity(left, right, patch=patch, max_shift=min(12, patch // 4))
    defocused = shifts[np.abs(shifts) > DEFOCUSED_SHIFT]
    if defocused.size < MIN_DEFOCUSED_BLOCKS:
        return None
    behind = int((defocused > 0).sum())
    return behind, int(defocused.size) - behind


def block_blur(
    combined: np.ndarray, target: np.ndarray, *, patch: int = 64, max_sigma: float = 8.0,
    min_texture: float = 0.01,
) -> np.ndarray:
    """Std (px) of the Gaussian that best maps ``target`` to ``combined``, per textured block."""
    grey_in, grey_target = channel_mean(combined), channel_mean(target)
    sigmas = np.arange(0.0, max_sigma + BLUR_STEP / 2, BLUR_STEP)
    costs = []
    for sigma in sigmas:
        blurred = grey_target if sigma == 0 else cv2.GaussianBlur(
            grey_target, (0, 0), float(sigma), borderType=cv2.BORDER_REFLECT
        )
        costs.append(block_sums((blurred - grey_in) ** 2, patch))
    best = np.stack(costs).argmin(axis=0)
    textured = _textured(grey_target, patch, min_texture)
    return sigmas[best][textured].astype(np.float32)


def noise_level(image: np.ndarray) -> float:
    """Noise std of an ``(H, W, 3)`` image in [0, 1] (Immerkaer filter + MAD, channel mean)."""
    kernel = np.array([[1, -2, 1], [-2, 4, -2], [1, -2, 1]], np.float32)
    filtered = cv2.filter2D(np.ascontiguousarray(image, np.float32), -1, kernel)[1:-1, 1:-1]
    mad = np.median(np.abs(filtered.reshape(-1, filtered.shape[-1])), axis=0)
    return float(np.mean(mad / (0.6745 * 6.0)))


def gradient_fraction(image: np.ndarray, threshold: float = GRADIENT_THRESHOLD) -> float:
    """Fraction of pixels whose grey gradient magnitude (central differences) exceeds
    ``threshold``."""
    gy, gx = np.gradient(channel_mean(image))
    return float(np.mean(np.hypot(gx, gy) > threshold))


def frame_statistics(
    left: np.ndarray, right: np.ndarray, target: np.ndarray | None = None,
    combined: np.ndarray | None = None, *, patch: int = 64, max_sigma: float = 8.0,
) -> FrameStatistics:
    """Measure one frame; images are float ``(H, W, 3)`` in [0, 1] of one size.

    ``combined`` defaults to the views' mean in linear light
    (:func:`~dualpixel.optics.tone.combined_image`; DPDD brightness convention).
    """
    shapes = {a.shape for a in (left, right, target, combined) if a is not None}
    if len(shapes) != 1:
        raise ParameterError(f"left, right, target and combined must share one size, got {shapes}")
    if min(left.shape[:2]) < patch:
        raise ParameterError(f"images of {left.shape[1]}x{left.shape[0]} are smaller than the "
                             f"{patch}-px blocks")
    if combined is None:
        combined = combined_image(left, right)
    blur = (block_blur(combined, target, patch=patch, max_sigma=max_sigma)
            if target is not None else np.zeros(0, np.float32))
    return FrameStatistics(
        disparity=block_disparity(left, right, patch=patch),
        blur=blur,
        noise=noise_level(combined),
        gradient_fraction=gradient_fraction(combined),
    )


def dataset_statistics(
    root: str | Path, *, split: str | None = None, limit: int | None = None, patch: int = 64,
    max_sigma: float = 8.0, name: str | None = None, progress: bool = False,
) -> DatasetStatistics:
    """Pool :func:`frame_statistics` over the frames of a dataset (at most ``limit`` frames, taken
    evenly across sequences)."""
    from dualpixel.progress import progress_bar

    if limit is not None and limit < 1:
        raise ParameterError(f"limit must be >= 1, got {limit}")
    sequences = discover_any(root, split)
    frames = [f for s in sequences for f in s.frames]
    if limit is not None and limit < len(frames):
        frames = [frames[int(i)] for i in np.linspace(0, len(frames) - 1, limit).round()]
    pooled: dict[str, list] = {"disparity": [], "blur": [], "noise": [], "gradient": []}
    size = (sequences[0].height, sequences[0].width)
    for paths in progress_bar(frames, desc=f"statistics of {Path(root).name}", enabled=progress):
        images = read_frame(paths)
        combined = None
        if paths.combined is not None:
            from dualpixel.io.images import read_rgb

            combined = read_rgb(paths.combined)
            if combined.shape != images["left"].shape:
                raise InputFileError(paths.combined, "size differs from the views")
        stats = frame_statistics(images["left"], images["right"], images.get("target"), combined,
                                 patch=patch, max_sigma=max_sigma)
        pooled["disparity"].append(stats.disparity)
        pooled["blur"].append(stats.blur)
        pooled["noise"].append(stats.noise)
        pooled["gradient"].append(stats.gradient_fraction)
    return DatasetStatistics(
        name=name or Path(root).name, frames=len(frames), size=size,
        disparity=np.concatenate(pooled["disparity"]), blur=np.concatenate(pooled["blur"]),
        noise=np.asarray(pooled["noise"], np.float32),
        gradient_fraction=np.asarray(pooled["gradient"], np.float32), max_blur=max_sigma,
    )


def write_summary(stats: list[DatasetStatistics], path: str | Path) -> Path:
    """Write the summaries of ``stats`` as one JSON file, atomically."""
    from dualpixel.io.atomic import atomic_path

    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps([s.summary() for s in stats], indent=2))
    return Path(path)
