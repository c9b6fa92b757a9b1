"""The output modes on the network's device (ours): the overshoot limit and the brightness tie
of :mod:`~dualpixel.inference.overshoot` and :mod:`~dualpixel.inference.brightness` as torch
operations, so a frame deblurred on a GPU is finished there and crosses to the CPU once.

On the CPU the NumPy/OpenCV versions run (OpenCV's running minimum and maximum are several
times faster there than any torch formulation); these compute the same: the window's extremes
exactly (a sparse table of maxima per axis; edge-replicated borders hold the same extremes as
OpenCV's reflected ones), the low-pass to within a few parts in a thousand (the same Gaussian,
area reduction and bilinear return; the reduction's bins differ where the frame is not a whole
number of them).
"""

from __future__ import annotations

import torch
import torch.nn.functional as F

from dualpixel.filters import gaussian_blur
from dualpixel.inference.brightness import _FLOOR, resolved_sigma
from dualpixel.inference.overshoot import OVERSHOOT_MARGIN, overshoot_radius
from dualpixel.optics.tone import linear_to_srgb, srgb_to_linear

__all__ = ["box_extremes", "limit_overshoot_tensor", "low_pass_tensor", "tie_brightness_tensor"]


def _window_maximum(values: torch.Tensor, size: int, dim: int) -> torch.Tensor:
    """The maximum over every window of ``size`` along ``dim`` (length n -> n - size + 1), in
    about log2(size) passes: maxima over 1, 2, 4, ... then two overlapping powers of two."""
    length = values.shape[dim]
    span, table = 1, values
    while 2 * span <= size:
        table = torch.maximum(table.narrow(dim, 0, table.shape[dim] - span),
                              table.narrow(dim, span, table.shape[dim] - span))
        span *= 2
    count = length - size + 1
    return torch.maximum(table.narrow(dim, 0, count), table.narrow(dim, size - span, count))


def box_extremes(image: torch.Tensor, radius: int) -> tuple[torch.Tensor, torch.Tensor]:
    """Minimum and maximum of ``image`` ``(N, C, H, W)`` over the square window of half-side
    ``radius`` px around every pixel (borders: the nearest pixel's value)."""
    if radius == 0:
        return image, image
    padded = F.pad(image, (radius,) * 4, mode="replicate")
    size = 2 * radius + 1
    high = _window_maximum(_window_maximum(padded, size, -1), size, -2)
    low = -_window_maximum(_window_maximum(-padded, size, -1), size, -2)
    return low, high


def limit_overshoot_tensor(output: torch.Tensor, combined: torch.Tensor, *,
                           radius: int | None = None,
                           margin: float = OVERSHOOT_MARGIN) -> torch.Tensor:
    """:func:`~dualpixel.inference.overshoot.limit_overshoot` for ``(C, H, W)`` tensors:
    ``output`` clipped per channel to the range of ``combined`` (display values) over the
    window, widened by ``margin`` levels of 255."""
    if radius is None:
        radius = overshoot_radius(output.shape[-1])
    low, high = box_extremes(combined[None], radius)
    spare = margin / 255.0
    return torch.minimum(torch.maximum(output, low[0] - spare), high[0] + spare)


def low_pass_tensor(grey: torch.Tensor, sigma: float) -> torch.Tensor:
    """:func:`~dualpixel.inference.brightness._low_pass` of ``(H, W)``: a Gaussian of ``sigma``
    px, on a grid ``sigma // 16`` times coarser (area-averaged) and brought back bilinearly."""
    height, width = grey.shape
    factor = max(1, int(sigma // 16))
    image = grey[None, None]
    if factor == 1 or min(height, width) < 4 * factor:
        return gaussian_blur(image, sigma)[0, 0]
    small = F.interpolate(image, size=(max(1, round(height / factor)),
                                       max(1, round(width / factor))), mode="area")
    small = gaussian_blur(small, sigma / factor)
    return F.interpolate(small, size=(height, width), mode="bilinear", align_corners=False)[0, 0]


def tie_brightness_tensor(output: torch.Tensor, light: torch.Tensor, *,
                          sigma: float | None = None) -> torch.Tensor:
    """:func:`~dualpixel.inference.brightness.tie_brightness` for ``(C, H, W)`` tensors:
    ``output`` (display values) scaled in linear light so that its low-pass equals that of
    ``light``, the views' combined image in linear light (not for palette images: their
    dither is measured on the CPU)."""
    sigma = resolved_sigma(sigma, output.shape[-1])
    linear = srgb_to_linear(output)
    gain = ((low_pass_tensor(light.mean(0), sigma) + _FLOOR)
            / (low_pass_tensor(linear.mean(0), sigma) + _FLOOR))
    return linear_to_srgb((linear * gain).clamp_(0.0, 1.0))
