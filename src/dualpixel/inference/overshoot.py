"""Outputs kept within the input's local range (ours): deblurring steepens edges, it adds no rims.

A defocused edge is a convex blend of the two sides the sharp edge separates (every PSF of the
paper's model is non-negative and sums to one, Eq. 2-4), so once a window is wider than the blur
the blurred image spans the sharp one's range there. A network that over-sharpens (a blur it
takes for larger than it is, as on views of a camera it was not trained on) draws a dark or bright
rim beyond that range: a halo. :func:`limit_overshoot` clips every output value to the combined
input's range over a square window of ``radius`` px, widened by ``margin``. Fine features whose
contrast the blur lowered below that range keep what fits in it.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from dualpixel.errors import ParameterError
from dualpixel.names import DEFAULT_OVERSHOOT, OVERSHOOT_MODES
from dualpixel.optics.tone import CombinedImage

__all__ = [
    "DEFAULT_OVERSHOOT", "OVERSHOOT_MARGIN", "OVERSHOOT_MODES", "check_overshoot",
    "combined_view", "limit_overshoot", "overshoot_radius",
]

#: How far (levels of 255) an output value may go beyond the input's local range.
OVERSHOOT_MARGIN = 2.0


def check_overshoot(mode: str) -> str:
    if mode not in OVERSHOOT_MODES:
        raise ParameterError(f"overshoot must be one of {', '.join(OVERSHOOT_MODES)}, "
                             f"got {mode!r}")
    return mode


def overshoot_radius(width: int) -> int:
    """Half-side (px) of the window whose range bounds the output: 1/64 of the frame width
    (13 px at 840 px, 25 at 1620), wider than the blur of all but the most defocused regions."""
    return max(2, round(width / 64))


def combined_view(left: np.ndarray, right: np.ndarray | None) -> np.ndarray:
    """The combined image (display values, ``(H, W, C)``): the views' mean in linear light
    (:func:`~dualpixel.optics.tone.combined_image`); ``left`` alone where there is no right."""
    return CombinedImage(left, right).encoded


def limit_overshoot(output: np.ndarray, left: np.ndarray, right: np.ndarray | None = None, *,
                    radius: int | None = None, margin: float = OVERSHOOT_MARGIN,
                    combined: np.ndarray | None = None) -> np.ndarray:
    """``output`` ``(H, W, C)`` display values in [0, 1], clipped per channel to the combined
    input's (:func:`combined_view`) minimum and maximum over a square window of half-side
    ``radius`` px (default :func:`overshoot_radius`), widened by ``margin`` levels of 255.
    ``combined``: that image when already made (a frame's
    :class:`~dualpixel.optics.tone.CombinedImage`), else made here from the views."""
    if radius is None:
        radius = overshoot_radius(output.shape[1])
    if not (isinstance(radius, int) and radius >= 0):
        raise ParameterError(f"radius must be a whole number of pixels >= 0, got {radius!r}")
    if not (math.isfinite(margin) and margin >= 0):
        raise ParameterError(f"margin must be >= 0 levels of 255, got {margin}")
    combined = np.ascontiguousarray(combined_view(left, right) if combined is None
                                    else combined, np.float32)
    window = np.ones((2 * radius + 1, 2 * radius + 1), np.uint8)
    low = cv2.erode(combined, window, borderType=cv2.BORDER_REFLECT).reshape(combined.shape)
    high = cv2.dilate(combined, window, borderType=cv2.BORDER_REFLECT).reshape(combined.shape)
    spare = margin / 255.0
    return np.clip(output, low - spare, high + spare).astype(np.float32)
