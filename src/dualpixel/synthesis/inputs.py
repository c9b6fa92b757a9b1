"""Discovering input sequences of all-in-focus RGB + depth (SYNTHIA-SF or any RGB-D folder)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np

from dualpixel.errors import InputFileError
from dualpixel.io.dpdd import list_files
from dualpixel.io.images import (
    DEPTH_SUFFIXES,
    IMAGE_SUFFIXES,
    read_depth,
    read_rgb,
    read_synthia_depth,
)

__all__ = ["InputFrame", "InputSequence", "discover_sequences", "load_depth", "load_frame"]

InputFormat = Literal["synthia", "rgbd"]

#: The authors' split of SYNTHIA-SF: SEQ3 is the test sequence, the others train.
SYNTHIA_TEST_SEQUENCES = ("SEQ3",)


@dataclass(frozen=True)
class InputFrame:
    name: str  # output file stem
    rgb: Path
    depth: Path


@dataclass(frozen=True)
class InputSequence:
    name: str
    split: str
    frames: tuple[InputFrame, ...]


def _pair(name: str, split: str, rgb_dir: Path, depth_dir: Path) -> InputSequence:
    for folder in (rgb_dir, depth_dir):
        if not folder.is_dir():
            raise InputFileError(folder, "folder not found")
    rgb = list_files(rgb_dir, IMAGE_SUFFIXES)
    depth = list_files(depth_dir, DEPTH_SUFFIXES)
    if not rgb:
        raise InputFileError(rgb_dir, "holds no images")
    missing = sorted(set(rgb) - set(depth))
    extra = sorted(set(depth) - set(rgb))
    if missing:
        raise InputFileError(
            rgb[missing[0]], f"has no depth map in {depth_dir} ({len(missing)} frames lack one)"
        )
    if extra:
        raise InputFileError(
            depth[extra[0]], f"has no RGB frame in {rgb_dir} ({len(extra)} depth maps lack one)"
        )
    frames = tuple(InputFrame(stem, rgb[stem], depth[stem]) for stem in sorted(rgb))
    return InputSequence(name, split, frames)


def discover_sequences(
    root: str | Path, fmt: InputFormat, *, split: str = "train"
) -> list[InputSequence]:
    """Find the input sequences under ``root``.

    * ``synthia``: ``SEQn/RGBLeft/*.png`` with ``SEQn/DepthLeft/*.png``; SEQ3 is ``test``.
    * ``rgbd``: ``rgb/`` and ``depth/`` with matching names, either directly in ``root`` (one
      sequence) or in each subfolder of it (one sequence per subfolder); all get ``split``.
    """
    root = Path(root)
    if not root.is_dir():
        raise InputFileError(root, "input folder not found")
    if fmt == "synthia":
        folders = sorted(p for p in root.iterdir() if (p / "RGBLeft").is_dir())
        if not folders:
            raise InputFileError(
                root, "holds no SYNTHIA-SF sequence (SEQn/RGBLeft, SEQn/DepthLeft)"
            )
        return [
            _pair(p.name, "test" if p.name in SYNTHIA_TEST_SEQUENCES else "train",
                  p / "RGBLeft", p / "DepthLeft")
            for p in folders
        ]
    if fmt == "rgbd":
        from dualpixel.synthesis.scenes import check_scenes_complete

        check_scenes_complete(root)
        if (root / "rgb").is_dir():
            return [_pair(root.name, split, root / "rgb", root / "depth")]
        folders = sorted(p for p in root.iterdir() if (p / "rgb").is_dir())
        if not folders:
            raise InputFileError(root, "holds no RGB-D sequence (rgb/ and depth/ folders)")
        return [_pair(p.name, split, p / "rgb", p / "depth") for p in folders]
    raise InputFileError(root, f"unknown input format {fmt!r} (use 'synthia' or 'rgbd')")


def load_frame(
    frame: InputFrame, fmt: InputFormat, *, max_depth: float = 250.0, depth_scale: float = 0.001
) -> tuple[np.ndarray, np.ndarray]:
    """Read one frame's RGB ``(H, W, 3)`` and depth ``(H, W)`` and check they match."""
    rgb = read_rgb(frame.rgb)
    depth = load_depth(frame, fmt, max_depth=max_depth, depth_scale=depth_scale)
    if depth.shape != rgb.shape[:2]:
        raise InputFileError(
            frame.depth,
            f"depth is {depth.shape[1]}x{depth.shape[0]} but {frame.rgb.name} is "
            f"{rgb.shape[1]}x{rgb.shape[0]}",
        )
    return rgb, depth


def load_depth(
    frame: InputFrame, fmt: InputFormat, *, max_depth: float = 250.0, depth_scale: float = 0.001
) -> np.ndarray:
    """Read one frame's depth ``(H, W)``, clipped at ``max_depth`` (its RGB is not read)."""
    if fmt == "synthia":
        depth = read_synthia_depth(frame.depth, max_depth=max_depth)
    else:
        depth = np.minimum(read_depth(frame.depth, png_scale=depth_scale), max_depth)
    if fmt == "synthia" and (depth <= 0).any():
        raise InputFileError(frame.depth, "depth has zero values (must be > 0)")
    return depth
