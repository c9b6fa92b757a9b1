"""Training examples: random patches of DP sequences, cropped alike in every view and frame.

Each item is a dict of float32 tensors ``left``, ``right``, ``target`` ``(T, 3, h, w)`` and
``radial`` ``(T, 1, h, w)`` (the radial distance of the patch's pixels in the full image, Sec. 4).
Randomness comes from the seed the sampler passes with the index (``dataset[(index, seed)]``), so a
run is reproducible whatever the number of loader workers.

Augmentation keeps the DP geometry valid: a horizontal flip mirrors the defocus disparity, so the
left and right views swap; a vertical flip keeps them.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np
import torch
from torch.utils.data import Dataset

from dualpixel.data.frame_store import FrameStore, compact_frame, expand
from dualpixel.data.layout import DPFramePaths, DPSequence, read_frame
from dualpixel.data.radial import radial_distance
from dualpixel.errors import ParameterError
from dualpixel.filters import gradient_magnitude, sharpness

__all__ = ["ConcatPatches", "DPPatchDataset", "PatchConfig", "Placement", "RenderedOn",
           "flip_horizontal", "gradient_magnitude", "items_of", "random_flips", "sharpness"]


@dataclass(frozen=True)
class PatchConfig:
    """How patches are drawn: size (``None`` = whole frames), frames per item, augmentation."""

    patch_size: int | None = 512
    frames: int = 1
    flips: bool = True
    min_sharpness: float = 0.0  # reject target patches flatter than this (mean Sobel magnitude)
    max_tries: int = 10


def flip_horizontal(item: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
    """Mirror an item left-right: every image flips and the left and right views swap."""
    flipped = {key: value.flip(-1) for key, value in item.items()}
    flipped["left"], flipped["right"] = flipped["right"], flipped["left"]
    return flipped


def random_flips(item: dict[str, torch.Tensor], rng: np.random.Generator
                 ) -> dict[str, torch.Tensor]:
    """``item`` mirrored left-right (:func:`flip_horizontal`) and upside down, each with
    probability 1/2 drawn from ``rng`` in that order."""
    if rng.random() < 0.5:
        item = flip_horizontal(item)
    if rng.random() < 0.5:
        item = {k: v.flip(-2) for k, v in item.items()}
    return item


class DPPatchDataset(Dataset):
    """Random ``patch_size`` crops of ``frames`` consecutive frames from DP sequences.

    Args:
        sequences: from :func:`dualpixel.data.layout.discover_dp_dataset` (with targets).
        config: patch settings.
        cache: keep decoded frames in memory, per process (small datasets, CPU training).
        store: a folder of decoded frames shared by every process through memory maps
            (:class:`~dualpixel.data.frame_store.FrameStore`; loader workers, GPU training).
        transform: ``transform(sequence, images)`` turns each cropped frame's images
            ``{key: (h, w, 3)}`` into what the model is trained on (e.g. raw values encoded as
            ``dualpixel deblur`` encodes them); picklable for loader processes.
    """

    def __init__(self, sequences: list[DPSequence], config: PatchConfig, *, cache: bool = False,
                 store: str | Path | None = None,
                 transform: Callable[[DPSequence, dict[str, np.ndarray]],
                                     dict[str, np.ndarray]] | None = None):
        if not sequences:
            raise ParameterError("no sequences to draw patches from")
        self.config = config
        self.sequences = [s for s in sequences if len(s.frames) >= config.frames]
        if not self.sequences:
            longest = max(len(s.frames) for s in sequences)
            raise ParameterError(f"sequence_frames is {config.frames} but no sequence has that "
                                 f"many frames (the longest, {longest}); lower sequence_frames or "
                                 "train on frames (synthetic_as_frames: true)")
        if config.patch_size is not None:
            small = [s for s in self.sequences if min(s.height, s.width) < config.patch_size]
            if small:
                raise ParameterError(
                    f"patch_size {config.patch_size} exceeds sequence {small[0].name} "
                    f"({small[0].width}x{small[0].height}); lower patch_size"
                )
        self._cache: dict[DPFramePaths, dict[str, np.ndarray]] | None = {} if cache else None
        self._store = FrameStore(store) if store is not None else None
        self.transform = transform

    def __len__(self) -> int:
        return len(self.sequences)

    def _load(self, frame: DPFramePaths) -> dict[str, np.ndarray]:
        """The frame's images; stored and cached ones are kept as 8-bit integers where that is
        lossless (4x less memory than float32), and patches are converted back on cropping."""
        if self._store is not None:
            return self._store.load(frame)
        if self._cache is not None and frame in self._cache:
            return self._cache[frame]
        images = read_frame(frame)
        if self._cache is not None:
            self._cache[frame] = compact_frame(images)
        return images

    def _frames(self, index: int, start: int, rng: np.random.Generator
                ) -> list[dict[str, np.ndarray]]:
        """Frames ``start ..`` of sequence ``index`` (``config.frames`` of them), read."""
        return [self._load(f) for f in self.sequences[index].frames[start:
                                                                    start + self.config.frames]]

    def _cut(self, frame, top: int, left: int, height: int, width: int
             ) -> dict[str, np.ndarray]:
        """A frame's images (as :meth:`_frames` gives them) cut to the crop: float32."""
        return {key: expand(frame[key][top : top + height, left : left + width])
                for key in frame}

    def placed(self, key: int | tuple[int, int]) -> Placement:
        """Where item ``key`` comes from: its frames (as :meth:`_frames` gives them) and its
        crop, chosen on the first frame's target; the generator left as the item goes on."""
        index, seed = key if isinstance(key, tuple) else (key, index_seed(key))
        rng = np.random.default_rng(seed)
        sequence = self.sequences[index]
        start = int(rng.integers(len(sequence.frames) - self.config.frames + 1))
        frames = self._frames(index, start, rng)
        size = self.config.patch_size
        height, width = sequence.height, sequence.width
        top = left = 0
        if size is not None:
            for _ in range(self.config.max_tries):
                top = int(rng.integers(height - size + 1))
                left = int(rng.integers(width - size + 1))
                crop = frames[0]["target"][top : top + size, left : left + size]
                if self.config.min_sharpness <= 0 or sharpness(crop) >= self.config.min_sharpness:
                    break
        h, w = (size, size) if size is not None else (height, width)
        return Placement(sequence, frames, (top, left, h, w), rng)

    def __getitem__(self, key: int | tuple[int, int]) -> dict[str, torch.Tensor]:
        sequence, frames, window, rng = self.placed(key)
        top, left, h, w = window
        crops = [self._cut(frame, *window) for frame in frames]
        if self.transform is not None:
            crops = [self.transform(sequence, crop) for crop in crops]
        item = {
            key: torch.from_numpy(np.stack([crop[key] for crop in crops]))
            .permute(0, 3, 1, 2).contiguous()
            for key in crops[0]
        }
        radial = radial_distance(h, w, full_size=(sequence.height, sequence.width), top=top,
                                 left=left)
        item["radial"] = torch.from_numpy(radial)[None, None].expand(len(frames), 1, h, w).clone()
        if self.config.flips:
            item = random_flips(item, rng)
        return item


class Placement(NamedTuple):
    """An item's sequence, frames, crop ``(top, left, height, width)`` px and generator."""

    sequence: DPSequence
    frames: list
    window: tuple[int, int, int, int]
    rng: np.random.Generator


class ConcatPatches(Dataset):
    """Several patch datasets as one, indexed in order (``(index, seed)`` keys, as
    :class:`DPPatchDataset` takes them): the same indices as one dataset of all their sequences."""

    def __init__(self, parts: list[Dataset]):
        if not parts:
            raise ParameterError("no datasets to draw patches from")
        self.parts = parts
        self.starts = np.cumsum([0] + [len(part) for part in parts])

    def __len__(self) -> int:
        return int(self.starts[-1])

    def _part(self, index: int) -> int:
        return int(np.searchsorted(self.starts, index, side="right")) - 1

    def __getitem__(self, key: int | tuple[int, int]) -> dict[str, torch.Tensor]:
        index, seed = key if isinstance(key, tuple) else (key, index_seed(key))
        part = self._part(index)
        return self.parts[part][(index - int(self.starts[part]), seed)]

    def render_items(self, keys: list[tuple[int, int]], device) -> list[dict[str, torch.Tensor]]:
        """The items of ``keys`` in order: each part's through its ``render_items`` where it has
        one (frames rendered on ``device``), else read."""
        items: list[dict[str, torch.Tensor] | None] = [None] * len(keys)
        for part, dataset in enumerate(self.parts):
            mine = [k for k, (index, _) in enumerate(keys) if self._part(index) == part]
            local = [(keys[k][0] - int(self.starts[part]), keys[k][1]) for k in mine]
            for k, item in zip(mine, items_of(dataset, local, device)):
                items[k] = item
        return items


def items_of(dataset: Dataset, keys: list[tuple[int, int]], device
             ) -> list[dict[str, torch.Tensor]]:
    """``dataset[key]`` for every key, rendered together on ``device`` where the dataset renders
    (``render_items``: on-the-fly sources), else read one by one."""
    if not keys:
        return []
    render = getattr(dataset, "render_items", None)
    return render(keys, device) if render is not None else [dataset[key] for key in keys]


class RenderedOn(Dataset):
    """``dataset``'s items, each batch of keys rendered together on ``device``
    (:func:`items_of`), for loader processes that render on an accelerator: a
    :class:`~torch.utils.data.DataLoader` with a batch sampler hands each process whole batches
    (``__getitems__``), so every process launches its own batches' work and the host's cores
    share what one training process would do alone. The items come back on the CPU."""

    def __init__(self, dataset: Dataset, device: torch.device | str):
        self.dataset, self.device = dataset, torch.device(device)

    def __len__(self) -> int:
        return len(self.dataset)

    def __getitem__(self, key):
        return self.dataset[key]

    def __getitems__(self, keys: list[tuple[int, int]]) -> list[dict[str, torch.Tensor]]:
        return items_of(self.dataset, keys, self.device)


def index_seed(index: int) -> int:
    """A fixed seed for an index used without one (evaluation, debugging)."""
    return int(np.random.SeedSequence(index).generate_state(1)[0])
