"""A refiner that corrects the base network's output (ours, not in the paper).

The light RDPD leaves most of its error where the blur is largest (8-16 px CoC radius on the
held-out synthetic frames), and its own coarsest level, the one with the receptive field for such
blur, went dormant in training (``MODEL_CARD.md``, "What limits the light model"). The refiner is a
small U-Net with a large receptive field at little cost: it reads the network's input and the
base network's output (stacked as the views, that output, then the radial channel where the
network reads one), works at half resolution without losing information (``pixel_unshuffle``: a
2x2 block becomes 4 channels), and adds a correction::

    out = clamp(base + shuffle(U(unshuffle([views, base, radial]))), 0, 1)

Levels: per width two 3x3 convolutions with LeakyReLU(0.1), then 2x2 max-pooling; a middle block
of the last width; per level back up, bilinear 2x upsampling, a 3x3 convolution, concatenation with
the skip and two 3x3 convolutions. Its last convolution starts at zero, so a fresh refiner is the
identity and training it on top of a trained (frozen) base network starts from that network's
result.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn

from dualpixel.models.padding import pad_to_multiple

__all__ = ["Refiner"]

#: Slope of the LeakyReLU (a leaky unit cannot die, as the base network's ReLUs did).
NEGATIVE_SLOPE = 0.1


def _double_conv(cin: int, cout: int) -> nn.Sequential:
    return nn.Sequential(
        nn.Conv2d(cin, cout, 3, padding=1), nn.LeakyReLU(NEGATIVE_SLOPE, inplace=True),
        nn.Conv2d(cout, cout, 3, padding=1), nn.LeakyReLU(NEGATIVE_SLOPE, inplace=True),
    )


class Refiner(nn.Module):
    """Correct a base network's output ``(B, 3, H, W)`` given its input ``(B, C_in, H, W)``.

    Args:
        in_channels: channels of the network input ``x``: 3 per view, then 1 if it ends with the
            radial distance channel (7: left, right, radial; 3: one view).
        widths: channels per level at 1/2, 1/4, 1/8, ... of the input size (e.g. ``(32, 64, 128)``).
    """

    def __init__(self, in_channels: int, widths: tuple[int, ...]) -> None:
        super().__init__()
        if not widths or min(widths) < 1:
            raise ValueError(f"refiner widths must be positive channel counts, got {widths}")
        self.in_channels, self.widths = in_channels, tuple(widths)
        self.encoders = nn.ModuleList()
        cin = 4 * (in_channels + 3)
        for width in widths:
            self.encoders.append(_double_conv(cin, width))
            cin = width
        self.middle = _double_conv(cin, cin)
        self.upconvs = nn.ModuleList()
        self.decoders = nn.ModuleList()
        for width in reversed(widths):
            self.upconvs.append(nn.Conv2d(cin, width, 3, padding=1))
            self.decoders.append(_double_conv(2 * width, width))
            cin = width
        self.head = nn.Conv2d(cin, 12, 3, padding=1)  # 3 channels x 2x2 positions
        nn.init.zeros_(self.head.weight)
        nn.init.zeros_(self.head.bias)

    @property
    def size_multiple(self) -> int:
        """Input sides must be multiples of this (the unshuffle and one pooling per level)."""
        return 2 ** (len(self.widths) + 1)

    def forward(self, x: torch.Tensor, base: torch.Tensor) -> torch.Tensor:
        """The corrected image ``(B, 3, H, W)`` in [0, 1] from the input ``x`` ``(B, C_in, H, W)``
        and the base network's output ``base`` ``(B, 3, H, W)``; any H, W (reflect-padded)."""
        if x.ndim != 4 or x.shape[1] != self.in_channels or base.shape != (
                x.shape[0], 3, *x.shape[2:]):
            raise ValueError(f"expected input (B, {self.in_channels}, H, W) and base network "
                             f"output (B, 3, H, W), got {tuple(x.shape)} and {tuple(base.shape)}")
        radial = self.in_channels % 3  # 1: the last channel is the radial distance
        views = x[:, : self.in_channels - radial]
        y = torch.cat([views, base, x[:, self.in_channels - radial :]], dim=1)
        y, height, width = pad_to_multiple(y, self.size_multiple)
        y = F.pixel_unshuffle(y, 2)
        skips = []
        for encoder in self.encoders:
            y = encoder(y)
            skips.append(y)
            y = F.max_pool2d(y, 2)
        y = self.middle(y)
        for upconv, decoder, skip in zip(self.upconvs, self.decoders, reversed(skips)):
            y = F.interpolate(y, scale_factor=2.0, mode="bilinear", align_corners=False)
            y = F.leaky_relu(upconv(y), NEGATIVE_SLOPE, inplace=True)
            y = decoder(torch.cat([skip, y], dim=1))
        correction = F.pixel_shuffle(self.head(y), 2)[..., :height, :width]
        return (base + correction).clamp(0.0, 1.0)
