"""A camera's own DP photographs without targets, as training data for the formation loss:
each pair's blur per block (:class:`BlurMap`, measured by :mod:`dualpixel.adaptation.blur_maps`;
stored with the camera as one JSON file) and crops of the views with their per-pixel maps
(:class:`ViewsDataset`).

Each item (keyed ``(index, seed)`` as :class:`~dualpixel.data.dataset.DPPatchDataset`'s, so a
run is reproducible whatever the loader) is a crop of pair ``index``'s views with its per-pixel
blur maps (:meth:`BlurMap.pixel_maps`): ``left``, ``right`` ``(1, 3, h, w)``, ``radial``
``(1, 1, h, w)``, ``radius``, ``side``, ``blurred``, ``in_focus`` ``(1, h, w)``. Flips as for
training pairs: a horizontal flip mirrors the image and swaps the views, which keeps each
block's side (the left and right PSFs are mirror images).
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from torch.utils.data import Dataset

from dualpixel.data.dataset import random_flips
from dualpixel.data.radial import radial_distance
from dualpixel.errors import InputFileError
from dualpixel.io.images import image_size, read_rgb
from dualpixel.optics.camera import DPCamera

__all__ = ["IN_FOCUS_RADIUS", "BlurMap", "ViewsDataset", "read_blur_maps", "write_blur_maps"]

#: Blocks whose radius is at most this (px) count as in focus: the output must keep the views.
IN_FOCUS_RADIUS = 1.0
MAPS_FORMAT = "dualpixel-blur-maps-1"
#: Crops are drawn again (up to this many times) while fewer than ``MIN_LABELLED`` of their
#: pixels lie in blurred or in-focus blocks.
TRIES = 10
MIN_LABELLED = 0.1


@dataclass(frozen=True)
class BlurMap:
    """One pair's blocks: ``radius`` ``(rows, cols)`` px (at the pair's width), ``side``
    (+1 / -1: behind / in front of the focal plane as the camera's ratio sign has it),
    ``informative`` (bool: the views tell the blur), ``in_focus`` (bool: textured, the views
    agree and the radius is at most :data:`IN_FOCUS_RADIUS`); block ``(i, j)`` covers rows
    ``margin + i * patch`` onwards and columns ``margin + j * patch`` onwards of the views,
    ``patch`` px square."""

    left: str
    right: str
    radius: np.ndarray
    side: np.ndarray
    informative: np.ndarray
    in_focus: np.ndarray
    patch: int
    margin: int

    def pixel_maps(self, height: int, width: int,
                   window: tuple[int, int, int, int] | None = None) -> tuple[np.ndarray, ...]:
        """``(radius, side, blurred, in_focus)`` float32 per pixel of the ``height x width``
        views, or of their ``window`` ``(top, left, rows, cols)`` alone: the block's values, 0
        outside every block; ``blurred`` marks informative blocks beyond
        :data:`IN_FOCUS_RADIUS`, ``in_focus`` the in-focus ones."""
        top, left, rows, cols = window or (0, 0, height, width)
        values = np.stack([self.radius, self.side,
                           self.informative & (self.radius > IN_FOCUS_RADIUS),
                           self.in_focus]).astype(np.float32)

        def blocks(start: int, count: int, blocks: int) -> tuple[np.ndarray, np.ndarray]:
            index = (np.arange(start, start + count) - self.margin) // self.patch
            inside = (index >= 0) & (index < blocks)
            return np.clip(index, 0, blocks - 1), inside

        by, in_y = blocks(top, rows, self.radius.shape[0])
        bx, in_x = blocks(left, cols, self.radius.shape[1])
        maps = values[:, by][:, :, bx] * (in_y[:, None] & in_x[None, :])
        return tuple(maps)


def write_blur_maps(maps: Sequence[BlurMap], camera: DPCamera, path: str | Path) -> Path:
    """``maps`` and the camera they were measured at, as one JSON file (atomic)."""
    from dualpixel.io.atomic import atomic_path

    record = {"format": MAPS_FORMAT, "camera": camera.to_dict(), "pairs": [
        {"left": m.left, "right": m.right, "patch": m.patch, "margin": m.margin,
         "radius": np.round(m.radius, 3).tolist(), "side": m.side.astype(int).tolist(),
         "informative": m.informative.astype(int).tolist(),
         "in_focus": m.in_focus.astype(int).tolist()} for m in maps]}
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(record) + "\n")
    return Path(path)


def read_blur_maps(path: str | Path) -> tuple[list[BlurMap], DPCamera]:
    """What :func:`write_blur_maps` wrote; errors name the file."""
    from dualpixel.io.documents import read_mapping

    record = read_mapping(path, "blur maps")
    if record.get("format") != MAPS_FORMAT:
        raise InputFileError(path, f"not a blur-maps file (expected \"format\": "
                                   f"\"{MAPS_FORMAT}\")")
    camera = DPCamera.from_dict(record.get("camera"), path)
    maps = []
    try:
        for entry in record["pairs"]:
            radius = np.asarray(entry["radius"], np.float64)
            side = np.asarray(entry["side"], np.int8)
            informative = np.asarray(entry["informative"], bool)
            in_focus = np.asarray(entry["in_focus"], bool)
            if radius.ndim != 2 or any(g.shape != radius.shape
                                       for g in (side, informative, in_focus)):
                raise ValueError("radius, side, informative and in_focus must be grids of one "
                                 "shape")
            maps.append(BlurMap(str(entry["left"]), str(entry["right"]), radius, side,
                                informative, in_focus, int(entry["patch"]),
                                int(entry["margin"])))
    except (KeyError, TypeError, ValueError) as error:
        raise InputFileError(path, f"bad blur-maps entry: {error}") from None
    if not maps:
        raise InputFileError(path, "holds no pairs")
    return maps, camera


class ViewsDataset(Dataset):
    """``patch_size`` crops of the pairs of ``maps`` (their files read per item)."""

    def __init__(self, maps: Sequence[BlurMap], patch_size: int, *, flips: bool = True) -> None:
        self.maps, self.patch_size, self.flips = list(maps), patch_size, flips
        self.sizes = []
        for blur in self.maps:
            size = image_size(blur.left)
            if image_size(blur.right) != size:
                raise InputFileError(blur.right, f"differs in size from {blur.left}")
            if min(size) < patch_size:
                raise InputFileError(blur.left, f"is {size[1]}x{size[0]}, smaller than the "
                                                f"{patch_size}-px crops")
            self.sizes.append(size)

    def __len__(self) -> int:
        return len(self.maps)

    def __getitem__(self, key: tuple[int, int]) -> dict[str, torch.Tensor]:
        index, seed = key
        rng = np.random.default_rng(seed)
        blur, (height, width) = self.maps[index], self.sizes[index]
        size = self.patch_size
        for _ in range(TRIES):
            top, left = int(rng.integers(height - size + 1)), int(rng.integers(width - size + 1))
            maps = blur.pixel_maps(height, width, (top, left, size, size))
            if ((maps[2] + maps[3]) > 0).mean() >= MIN_LABELLED:
                break
        window = (slice(top, top + size), slice(left, left + size))
        views = [read_rgb(path)[window] for path in (blur.left, blur.right)]
        item = {name: torch.from_numpy(np.ascontiguousarray(view)).permute(2, 0, 1)[None]
                for name, view in zip(("left", "right"), views)}
        radial = radial_distance(size, size, full_size=(height, width), top=top, left=left)
        item["radial"] = torch.from_numpy(radial)[None, None]
        for name, values in zip(("radius", "side", "blurred", "in_focus"), maps):
            item[name] = torch.from_numpy(np.ascontiguousarray(values))[None]
        if self.flips:
            item = random_flips(item, rng)
        return {k: v.contiguous() for k, v in item.items()}
