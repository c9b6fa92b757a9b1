"""Tiled full-resolution inference with bounded memory (paper Sec. 5: "full-resolution inputs").

The image is reflect-padded to a multiple of 16 exactly as the whole-image path pads it, and cut
into tiles whose positions are multiples of 16, so every tile's pooling grid matches the whole
image's. Tiles overlap by ``overlap`` pixels and are blended with weights that are ~0 over the outer
quarter of the overlap and ramp linearly to 1 across its middle half (and stay 1 at the image
border), so the pixels kept from a tile lie away from its zero-padded edges. The radial channel is
computed once for the full image and cropped per tile. For a recurrent network each tile keeps its
own ConvLSTM state across frames.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from dualpixel.errors import ParameterError
from dualpixel.models.unet import SIZE_MULTIPLE, DeblurNet, pad_to_multiple

__all__ = ["TileGrid", "deblur_tiled"]


@dataclass(frozen=True)
class TileGrid:
    """Tile origins along one axis of a padded length, each ``size`` long, stepping by 16s."""

    size: int
    overlap: int

    def __post_init__(self) -> None:
        if self.size % SIZE_MULTIPLE or self.size <= 0:
            raise ParameterError(f"tile size must be a positive multiple of 16, got {self.size}")
        if not 0 <= self.overlap < self.size:
            raise ParameterError(f"overlap must be in [0, tile size), got {self.overlap}")

    def starts(self, length: int) -> list[int]:
        if length <= self.size:
            return [0]
        stride = max(SIZE_MULTIPLE, (self.size - self.overlap) // SIZE_MULTIPLE * SIZE_MULTIPLE)
        starts = [*range(0, length - self.size, stride), length - self.size]
        return sorted(set(starts))

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
    model: DeblurNet,
    x: torch.Tensor,
    *,
    tile: int,
    overlap: int,
    states: dict | None = None,
) -> tuple[torch.Tensor, dict]:
    """Run ``model.step`` on ``x`` ``(1, C, H, W)`` tile by tile; returns ``(1, 3, H, W)`` on the
    CPU and the per-tile recurrent states (pass them back for the next frame)."""
    grid = TileGrid(tile, overlap)
    padded, height, width = pad_to_multiple(x)
    full_h, full_w = padded.shape[-2:]
    output = torch.zeros(1, 3, full_h, full_w)
    total = torch.zeros(1, 1, full_h, full_w)
    states = {} if states is None else states
    for top in grid.starts(full_h):
        for left in grid.starts(full_w):
            span_h, span_w = min(tile, full_h), min(tile, full_w)
            window = padded[..., top : top + span_h, left : left + span_w]
            out, states[(top, left)] = model.step(window, states.get((top, left)))
            weight = torch.from_numpy(np.outer(
                grid.weights(top, full_h, span_h), grid.weights(left, full_w, span_w)
            ).astype(np.float32))
            output[..., top : top + span_h, left : left + span_w] += out.float().cpu() * weight
            total[..., top : top + span_h, left : left + span_w] += weight
    return (output / total)[..., :height, :width], states
