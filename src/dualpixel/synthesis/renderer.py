"""Layered, occlusion-aware rendering of dual-pixel views (paper Sec. 3 and Eq. 7).

The signed CoC map is split into at most ``max_layers`` layers of nearly equal CoC. Each layer's
premultiplied image ``I m`` and its mask ``m`` are convolved with the layer's left and right PSFs,
and the layers are alpha-composited **back to front** (largest r, i.e. farthest, first) with the
blurred masks as alpha::

    colour <- (I m) * H  +  (1 - m * H) colour
    cover  <-      m * H  +  (1 - m * H) cover

so a blurred foreground spreads over an in-focus background, while a blurred background is hidden
behind a sharp foreground and cannot bleed over it.

Hidden background. Behind a foreground edge the background layer has a hole (those pixels belong to
the foreground), and blurring that hole lowers the background's alpha near the edge. Compositing
alone would let black show through there (a dark seam). We divide the composite by the accumulated
coverage ``cover`` at the end (normalised compositing): every output pixel is then a convex
combination of the layer colours that reach it, weighted by how much of each is visible. A uniform
scene therefore renders exactly uniform at any depth, with no dark or bright seams; where the hidden
background is unknown, the visible surfaces that reach a pixel fill in for it. The same
normalisation removes the darkening at the frame border that zero padding would cause.

Efficiency. Each layer is processed only inside its bounding box grown by its kernel radius; the
kernels are built for the layer's own radius; convolution is direct for small kernels and FFT for
large ones (:mod:`dualpixel.synthesis.convolution`). Memory is the output plus one layer's crop.

That loop is ``mode="exact"``, the reference. The default, ``mode="fast"``, composites the same
way with fewer and cheaper convolutions (:mod:`dualpixel.synthesis.fast_renderer`).
"""

from __future__ import annotations

import torch

from dualpixel.errors import ParameterError
from dualpixel.optics.psf import PSFModel, PSFParams, dp_psf
from dualpixel.synthesis.convolution import convolve_same
from dualpixel.synthesis.fast_renderer import render_fast
from dualpixel.synthesis.layers import (
    RENDER_MODES,
    bounding_boxes,
    check_render_mode,
    grown_box,
    quantise_layers,
)

__all__ = ["RENDER_MODES", "quantise_layers", "render_dp_views"]


def render_dp_views(
    image: torch.Tensor,
    coc: torch.Tensor,
    params: PSFParams | None = None,
    *,
    model: PSFModel = "ours",
    max_layers: int = 500,
    convolution: str = "auto",
    mode: str = "fast",
) -> tuple[torch.Tensor, torch.Tensor]:
    """Render the left and right DP views of an all-in-focus image (paper Eq. 7, layered).

    Args:
        image: ``(C, H, W)`` all-in-focus image, linear values, on any device.
        coc: ``(H, W)`` signed CoC radius in pixels (see :func:`dualpixel.optics.coc_radius`).
        params: PSF shape (our model); paper defaults if None.
        model: PSF model, see :func:`dualpixel.optics.dp_psf`.
        max_layers: at most this many depth layers (the paper: 500).
        convolution: "auto", "direct" or "fft" (``mode="exact"`` only).
        mode: "fast" (the default: :func:`dualpixel.synthesis.fast_renderer.render_fast`,
            >= 45 dB from exact, ``benchmarks/bench_synthesis.py``) or "exact" (the paper's
            ``max_layers`` equal CoC steps, each at full resolution: the reference).

    Returns:
        ``(left, right)``, each ``(C, H, W)`` at the brightness of the combined image (as stored
        in the DPDD dataset): the paper's views are half of these, ``I_l = left / 2``, and the
        combined image is ``I_b = I_l + I_r = (left + right) / 2``.
    """
    if image.ndim != 3 or coc.shape != image.shape[-2:]:
        raise ParameterError(
            f"image must be (C, H, W) and coc (H, W) of the same size; got image "
            f"{tuple(image.shape)} and coc {tuple(coc.shape)}"
        )
    if check_render_mode(mode) == "fast":
        return render_fast(image, coc, params, model=model, max_layers=max_layers)
    channels, height, width = image.shape
    labels, layer_coc = quantise_layers(coc, max_layers, mode="exact")
    boxes = bounding_boxes(labels, layer_coc.numel()).tolist()
    colour = torch.zeros(2, channels, height, width, dtype=image.dtype, device=image.device)
    cover = torch.zeros(2, 1, height, width, dtype=image.dtype, device=image.device)
    for index in torch.argsort(layer_coc, descending=True).tolist():  # far to near
        radius = float(layer_coc[index])
        # kernels normalised to 1 per view: alpha of an opaque layer must reach 1
        left, right = dp_psf(radius, params, model=model, dtype=image.dtype, device=image.device)
        kernels = 2.0 * torch.stack((left, right))
        half = kernels.shape[-1] // 2
        r0, r1, c0, c1 = grown_box(boxes[index], half, height, width)
        mask = (labels[r0:r1, c0:c1] == index).to(image.dtype)
        planes = torch.cat((image[:, r0:r1, c0:c1] * mask, mask[None]))
        blurred = convolve_same(planes, kernels, method=convolution)  # (2, C + 1, h, w)
        alpha = blurred[:, channels:]
        keep = 1.0 - alpha
        colour[:, :, r0:r1, c0:c1] = blurred[:, :channels] + keep * colour[:, :, r0:r1, c0:c1]
        cover[:, :, r0:r1, c0:c1] = alpha + keep * cover[:, :, r0:r1, c0:c1]
    views = colour / cover.clamp_min(torch.finfo(image.dtype).eps)
    return views[0], views[1]
