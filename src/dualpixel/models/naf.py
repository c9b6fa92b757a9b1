"""NAFNet-style levels for the deblurring U-Net (ours; Chen, Chu, Zhang & Sun, "Simple Baselines
for Image Restoration", ECCV 2022).

The light RDPD's levels are two 3x3 convolutions with ReLU; a NAF level is a stack of
:class:`NAFBlock` (layer norm, 1x1 expansion, 3x3 depthwise convolution, a simple gate, 1x1
projection, then a gated 1x1 feed-forward, each half residual with a learnt scale that starts at
zero, so a fresh block is the identity). For the same arithmetic a level gets several blocks,
hence far more depth and receptive field: what strong blur on real texture asks of the network
(issue #77, item 4). The U-Net around them is :class:`~dualpixel.models.unet.DeblurNet`'s
(skips concatenated, the residual output and the refiner), with NAFNet's sampling: a 2x2 stride-2
convolution down and a 1x1 convolution with a pixel shuffle up.

Left out on purpose: NAFNet's simplified channel attention. It scales each channel by its mean
over the whole image, so a 1680x1120 frame and its tiles (or the 256-px training crops) would
see other means and give other outputs; every operation here is local, and tiled inference
equals the whole frame's as it does for RDPD.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn

__all__ = ["LayerNorm2d", "NAFBlock", "ShuffleUp", "naf_blocks", "naf_down"]


class LayerNorm2d(nn.Module):
    """Layer normalisation over the channels of each pixel of ``(B, C, H, W)``, with a learnt
    per-channel scale and offset: ``torch.nn.functional.layer_norm`` on the channels-last view
    (no copy for a channels-last tensor; one transposing copy otherwise, still faster than
    normalising along dim 1 by hand)."""

    def __init__(self, channels: int, eps: float = 1e-6) -> None:
        super().__init__()
        self.weight = nn.Parameter(torch.ones(channels))
        self.bias = nn.Parameter(torch.zeros(channels))
        self.eps = eps

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        weight, bias = self.weight.to(x.dtype), self.bias.to(x.dtype)
        normed = F.layer_norm(x.permute(0, 2, 3, 1), (x.shape[1],), weight, bias, self.eps)
        return normed.permute(0, 3, 1, 2).to(x.dtype)  # autocast may compute it in float32


def simple_gate(x: torch.Tensor) -> torch.Tensor:
    """NAFNet's nonlinearity: the first half of the channels times the second,
    ``(B, 2C, H, W)`` -> ``(B, C, H, W)``."""
    first, second = x.chunk(2, dim=1)
    return first * second


class NAFBlock(nn.Module):
    """One NAF block on ``(B, C, H, W)`` (shape kept)::

        y = x + beta  * W2(gate(DW(W1(LN(x)))))     # spatial half: 3x3 depthwise
        z = y + gamma * W4(gate(W3(LN(y))))         # channel half: a gated feed-forward

    ``W1``, ``W3`` expand to ``2C`` (the gate halves them back), ``DW`` is a 3x3 depthwise
    convolution; ``beta`` and ``gamma`` are per channel and start at zero (a fresh block is the
    identity)."""

    def __init__(self, channels: int) -> None:
        super().__init__()
        if channels < 1:
            raise ValueError(f"a NAF block needs at least one channel, got {channels}")
        wide = 2 * channels
        self.norm1 = LayerNorm2d(channels)
        self.expand = nn.Conv2d(channels, wide, 1)
        self.depthwise = nn.Conv2d(wide, wide, 3, padding=1, groups=wide)
        self.project = nn.Conv2d(channels, channels, 1)
        self.norm2 = LayerNorm2d(channels)
        self.feed = nn.Conv2d(channels, wide, 1)
        self.feed_out = nn.Conv2d(channels, channels, 1)
        self.beta = nn.Parameter(torch.zeros(1, channels, 1, 1))
        self.gamma = nn.Parameter(torch.zeros(1, channels, 1, 1))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        y = self.project(simple_gate(self.depthwise(self.expand(self.norm1(x)))))
        x = torch.addcmul(x, y, self.beta.to(y.dtype))  # autocast: stay in y's dtype
        y = self.feed_out(simple_gate(self.feed(self.norm2(x))))
        return torch.addcmul(x, y, self.gamma.to(y.dtype))


def naf_blocks(channels: int, count: int, *, cin: int | None = None,
               kernel: int = 1) -> nn.Sequential:
    """``count`` NAF blocks of ``channels``, after a ``kernel`` x ``kernel`` convolution from
    ``cin`` channels when given (3x3 from the image, 1x1 from a skip and upsampled features)."""
    if count < 0:
        raise ValueError(f"a level needs zero or more blocks, got {count}")
    entry = [] if cin is None else [nn.Conv2d(cin, channels, kernel, padding=kernel // 2)]
    return nn.Sequential(*entry, *(NAFBlock(channels) for _ in range(count)))


def naf_down(cin: int, cout: int) -> nn.Conv2d:
    """Half the size: a 2x2 convolution of stride 2,
    ``(B, cin, H, W)`` -> ``(B, cout, H/2, W/2)``."""
    return nn.Conv2d(cin, cout, 2, stride=2)


class ShuffleUp(nn.Module):
    """Twice the size: a 1x1 convolution to ``4 cout`` channels and a pixel shuffle,
    ``(B, cin, H, W)`` -> ``(B, cout, 2H, 2W)``."""

    def __init__(self, cin: int, cout: int) -> None:
        super().__init__()
        self.conv = nn.Conv2d(cin, 4 * cout, 1, bias=False)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return F.pixel_shuffle(self.conv(x), 2)
