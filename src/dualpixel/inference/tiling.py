"""Tiled full-resolution inference with bounded memory (paper Sec. 5: "full-resolution inputs").

The image is reflect-padded to a multiple of 16 exactly as the whole-image path pads it, and cut
into the fewest tiles of one size (at most ``tile``, a multiple of 16, at positions that are
multiples of 16, so every tile's pooling grid matches the whole image's) that overlap their
neighbours by at least ``overlap`` pixels: a 1680x1120 image at ``tile=512`` is 4x3 tiles of
480x416, 1.27x the image's pixels, where fixed 512-px tiles would be 1.7x. Tiles go through the
network in batches (``max_batch`` tiles at once, each ensemble member counting as one), and are
blended once with weights that are ~0 over the outer quarter of the overlap and ramp linearly to 1
across its middle half (1 at the image border), so the pixels kept from a tile lie away from its
zero-padded edges. For a recurrent network each batch of tiles keeps its own ConvLSTM state across
frames.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import torch

from dualpixel.errors import ParameterError
from dualpixel.models.unet import SIZE_MULTIPLE, DeblurNet, pad_to_multiple

if TYPE_CHECKING:
    from dualpixel.inference.onnx_runtime import OnnxRuntimeNet

__all__ = ["MAX_BATCH", "TileGrid", "deblur_tiled"]

#: Tiles (times ensemble members) per network pass: memory stays at a few tiles' worth.
MAX_BATCH = 4


@dataclass(frozen=True)
class TileGrid:
    """Where the tiles of one axis lie: at most ``size`` long, overlapping by ``overlap`` or
    more, at multiples of 16."""

    size: int
    overlap: int

    def __post_init__(self) -> None:
        if self.size % SIZE_MULTIPLE or self.size <= 0:
            raise ParameterError(f"tile size must be a positive multiple of 16, got {self.size}")
        if not 0 <= self.overlap < self.size:
            raise ParameterError(f"overlap must be in [0, tile size), got {self.overlap}")

    def layout(self, length: int) -> tuple[int, list[int]]:
        """``(span, starts)`` covering an axis of ``length`` (a multiple of 16): the fewest tiles
        of one span (<= size, a multiple of 16) with every neighbour overlap >= ``overlap``."""
        if length <= self.size:
            return length, [0]
        step = SIZE_MULTIPLE
        count = 2
        while True:
            span = min(self.size,
                       math.ceil((length + (count - 1) * self.overlap) / (count * step)) * step)
            starts = [int(i * (length - span) / (count - 1)) // step * step
                      for i in range(count - 1)] + [length - span]
            if all(b - a <= span - self.overlap for a, b in itertools.pairwise(starts)):
                return span, starts
            count += 1

    def starts(self, length: int) -> list[int]:
        """The tile origins of :meth:`layout`."""
        return self.layout(length)[1]

    def weights(self, start: int, length: int, span: int) -> np.ndarray:
        """Blend weights of a tile ``[start, start+span)`` of an axis of ``length``."""
        ramp = np.ones(span)
        if self.overlap > 0:
            # 0 over the outer quarter of the overlap (where zero padding at the tile edge is
            # felt), then a linear rise to 1 over its middle half.
            quarter = self.overlap / 4
            rise = np.clip((np.arange(span) + 0.5 - quarter) / (2 * quarter), 1e-6, 1.0)
            if start > 0:
                ramp = np.minimum(ramp, rise)
            if start + span < length:
                ramp = np.minimum(ramp, rise[::-1])
        return ramp


def deblur_tiled(
    model: DeblurNet | OnnxRuntimeNet,
    x: torch.Tensor,
    *,
    tile: int,
    overlap: int,
    states: dict | None = None,
    max_batch: int = MAX_BATCH,
    channels_last: bool = False,
) -> tuple[torch.Tensor, dict]:
    """Run ``model.step`` on ``x`` ``(M, C, H, W)`` (M ensemble members) tile by tile, batched;
    returns ``(M, 3, H, W)`` float32 on the CPU and the recurrent states of the tile batches
    (pass them back for the next frame)."""
    grid = TileGrid(tile, overlap)
    padded, height, width = pad_to_multiple(x)
    members, _, full_h, full_w = padded.shape
    span_h, tops = grid.layout(full_h)
    span_w, lefts = grid.layout(full_w)
    origins = [(top, left) for top in tops for left in lefts]
    per_pass = max(1, max_batch // members)
    output = torch.zeros(members, 3, full_h, full_w)
    total = torch.zeros(1, 1, full_h, full_w)
    states = {} if states is None else states
    for index, first in enumerate(range(0, len(origins), per_pass)):
        chunk = origins[first : first + per_pass]
        batch = torch.cat([padded[..., top : top + span_h, left : left + span_w]
                           for top, left in chunk])
        if channels_last:
            batch = batch.contiguous(memory_format=torch.channels_last)
        out, states[index] = model.step(batch, states.get(index))
        out = out.float().cpu().reshape(len(chunk), members, 3, span_h, span_w)
        for tile_out, (top, left) in zip(out, chunk):
            weight = torch.from_numpy(np.outer(
                grid.weights(top, full_h, span_h), grid.weights(left, full_w, span_w)
            ).astype(np.float32))
            output[..., top : top + span_h, left : left + span_w] += tile_out * weight
            total[..., top : top + span_h, left : left + span_w] += weight
    return (output / total)[..., :height, :width], states
