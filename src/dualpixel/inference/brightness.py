"""Outputs whose brightness is tied to the input's (ours): blur moves light, it makes none.

Every PSF of the paper's model sums to one (Eq. 2-4), and a lens blurs light, not stored values,
so a defocused capture holds, in linear light and over any region wider than its blur, the same
light as the sharp scene. A network trained on synthetic data can still brighten or darken its
output (by about 1 % over a frame on real photographs: its training frames were blurred in the
stored values, where the sharp target is brighter than the blurred input). :func:`tie_brightness`
removes that: it scales the output in linear light so that its low-pass (a Gaussian of
:func:`tie_sigma` px, 1/35 of the frame width: as wide as the largest blur of the training data,
so the detail the network restores is kept) equals the input's, the views' mean. One gain per
pixel, the same for R, G and B, so colours are kept.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from dualpixel.errors import ParameterError
from dualpixel.filters import channel_mean
from dualpixel.names import BRIGHTNESS_MODES, DEFAULT_BRIGHTNESS
from dualpixel.optics.tone import CombinedImage, linear_to_srgb_array, srgb_to_linear_array

__all__ = [
    "BRIGHTNESS_MODES", "DEFAULT_BRIGHTNESS", "DITHER_SIGMA", "check_brightness",
    "is_palette_image", "resolved_sigma", "smooth", "tie_brightness", "tie_sigma",
]

#: Gaussian std (px) that smooths a palette image's dither in its stored values before they are
#: linearised: dither added there averages out there, and would brighten the linear mean.
DITHER_SIGMA = 1.0
#: Linear light added to both low-passes, so black regions keep a gain of about one.
_FLOOR = 1e-4


def tie_sigma(width: int) -> float:
    """Gaussian std (px) of the low-pass held for a frame ``width`` px wide: 1/35 of it (24 px
    at 840 px, the scale of the largest CoC radius of the training data's DSLR profile there,
    30 px). A wider one leaves local shifts of brightness; no narrower one is needed."""
    return width / 35.0


def resolved_sigma(sigma: float | None, width: int) -> float:
    """The tie's low-pass std (px): ``sigma``, or :func:`tie_sigma` of ``width`` when None; a
    :class:`ParameterError` unless positive and finite."""
    if sigma is None:
        sigma = tie_sigma(width)
    if not (math.isfinite(sigma) and sigma > 0):
        raise ParameterError(f"sigma must be a positive number of pixels, got {sigma}")
    return sigma


def check_brightness(mode: str) -> str:
    if mode not in BRIGHTNESS_MODES:
        raise ParameterError(f"brightness must be one of {', '.join(BRIGHTNESS_MODES)}, "
                             f"got {mode!r}")
    return mode


def is_palette_image(image: np.ndarray) -> bool:
    """Whether ``image`` (``(H, W, C)`` in [0, 1]) holds at most 256 distinct colours of the
    8-bit grid, as a GIF frame does (its palette's dither was added to the stored values).
    Values off that grid (16-bit files, raw views made display values by
    :func:`~dualpixel.inference.encoding.to_model`) are no GIF frame, however few their
    colours (a grey view has one per level)."""
    image = np.asarray(image)
    scaled = image[:: max(1, image.shape[0] // 64)] * 255  # rows enough to see a finer grid
    if float(np.abs(scaled - np.rint(scaled)).max()) > 1e-3:  # 16-bit or float values
        return False
    levels = np.rint(image * 255).astype(np.int64).reshape(-1, image.shape[-1])
    codes = levels @ (256 ** np.arange(levels.shape[1]))
    if np.unique(codes[:: max(1, codes.size // 20000)]).size > 256:  # most photographs: quick
        return False
    return np.unique(codes).size <= 256


def smooth(image: np.ndarray, sigma: float) -> np.ndarray:
    """A Gaussian of ``sigma`` px over ``(H, W, C)`` (or ``(H, W)``), borders reflected."""
    smoothed = cv2.GaussianBlur(np.ascontiguousarray(image, np.float32), (0, 0), sigma,
                                borderType=cv2.BORDER_REFLECT)
    return smoothed.reshape(image.shape)


def _low_pass(grey: np.ndarray, sigma: float) -> np.ndarray:
    """Gaussian of ``sigma`` px, computed on a grid ``sigma / 16`` times coarser (area-averaged)
    and interpolated back: within 0.3 % of the full-size filter for so wide a Gaussian, and
    about 10x faster."""
    factor = max(1, int(sigma // 16))
    height, width = grey.shape
    if factor == 1 or min(height, width) < 4 * factor:
        return cv2.GaussianBlur(grey, (0, 0), sigma, borderType=cv2.BORDER_REFLECT)
    small = cv2.resize(grey, (max(1, round(width / factor)), max(1, round(height / factor))),
                       interpolation=cv2.INTER_AREA)
    small = cv2.GaussianBlur(small, (0, 0), sigma / factor, borderType=cv2.BORDER_REFLECT)
    return cv2.resize(small, (width, height), interpolation=cv2.INTER_LINEAR)


def tie_brightness(output: np.ndarray, left: np.ndarray, right: np.ndarray | None = None, *,
                   sigma: float | None = None,
                   combined: CombinedImage | None = None) -> np.ndarray:
    """``output`` ``(H, W, 3)`` display (sRGB) values in [0, 1], scaled in linear light so that
    its Gaussian low-pass (std ``sigma`` px, default :func:`tie_sigma`) of the channel mean
    equals that of the input, the
    mean of ``left`` and ``right`` in linear light (``left`` alone for a one-view model).
    For palette images (:func:`is_palette_image`) both sides are measured after a Gaussian of
    :data:`DITHER_SIGMA` px in the stored values. ``combined``: the views' combined image when
    already made (a frame's :class:`~dualpixel.optics.tone.CombinedImage`)."""
    sigma = resolved_sigma(sigma, output.shape[1])
    measured = output
    if is_palette_image(left):  # both sides measured alike, after the dither's smoothing
        combined = CombinedImage(*(None if v is None else smooth(v, DITHER_SIGMA)
                                   for v in (left, right)))
        measured = smooth(output, DITHER_SIGMA)
    elif combined is None:
        combined = CombinedImage(left, right)
    linear_in = combined.light
    linear_out = srgb_to_linear_array(output)
    linear_measured = linear_out if measured is output else srgb_to_linear_array(measured)
    gain = ((_low_pass(channel_mean(linear_in), sigma) + _FLOOR)
            / (_low_pass(channel_mean(linear_measured), sigma) + _FLOOR))
    tied = np.clip(linear_out * gain[..., None], 0.0, 1.0)
    return linear_to_srgb_array(tied)
