"""Padding an input to the size a U-Net needs, and cropping back."""

from __future__ import annotations

import torch
import torch.nn.functional as F

__all__ = ["SIZE_MULTIPLE", "pad_to_multiple"]

#: Spatial size the network needs: four 2x2 poolings.
SIZE_MULTIPLE = 16


def pad_to_multiple(
    x: torch.Tensor, multiple: int = SIZE_MULTIPLE
) -> tuple[torch.Tensor, int, int]:
    """Reflect-pad ``(..., H, W)`` at the bottom and right to multiples of ``multiple``.

    While exporting (ONNX), the padding is always in the graph (by zero rows where none is
    needed), so that a graph traced at a multiple of 16 still runs at any other size of at least
    16 x 16."""
    height, width = x.shape[-2:]
    pad_h, pad_w = -height % multiple, -width % multiple
    if torch.compiler.is_exporting():
        return F.pad(x, (0, pad_w, 0, pad_h), mode="reflect"), height, width
    if pad_h or pad_w:
        mode = "reflect" if pad_h < height and pad_w < width else "replicate"
        x = F.pad(x, (0, pad_w, 0, pad_h), mode=mode)
    return x, height, width
