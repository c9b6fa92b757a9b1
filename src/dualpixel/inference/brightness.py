"""Outputs whose brightness is tied to the input's (ours): blur moves light, it makes none.

Every PSF of the paper's model sums to one (Eq. 2-4), and a lens blurs light, not stored values,
so a defocused capture holds, in linear light and over any region wider than its blur, the same
light as the sharp scene. A network trained on synthetic data can still brighten or darken its
output (by about 1 % over a frame on real photographs: its training frames were blurred in the
stored values, where the sharp target is brighter than the blurred input). :func:`tie_brightness`
removes that: it scales the output in linear light so that its low-pass (a Gaussian of ``sigma``
px, wider than the largest blur, so the detail the network restores is untouched) equals the
input's, the views' mean. One gain per pixel, the same for R, G and B, so colours are kept.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import torch

from dualpixel.errors import ParameterError
from dualpixel.names import BRIGHTNESS_MODES, DEFAULT_BRIGHTNESS
from dualpixel.optics.tone import linear_to_srgb, srgb_to_linear

__all__ = [
    "BRIGHTNESS_MODES", "DEFAULT_BRIGHTNESS", "TIE_SIGMA", "check_brightness", "tie_brightness",
]

#: Gaussian std (px) of the low-pass held: twice the largest CoC radius of the training data's
#: DSLR profile at 840 px (30 px), so no blur the network removes is wider than it.
TIE_SIGMA = 64.0
#: Linear light added to both low-passes, so black regions keep a gain of about one.
_FLOOR = 1e-4


def check_brightness(mode: str) -> str:
    if mode not in BRIGHTNESS_MODES:
        raise ParameterError(f"brightness must be one of {', '.join(BRIGHTNESS_MODES)}, "
                             f"got {mode!r}")
    return mode


def _linear(image: np.ndarray) -> np.ndarray:
    return srgb_to_linear(torch.from_numpy(np.ascontiguousarray(image, np.float32))).numpy()


def _low_pass(grey: np.ndarray, sigma: float) -> np.ndarray:
    return cv2.GaussianBlur(grey, (0, 0), sigma, borderType=cv2.BORDER_REFLECT)


def tie_brightness(output: np.ndarray, left: np.ndarray, right: np.ndarray | None = None, *,
                   sigma: float = TIE_SIGMA) -> np.ndarray:
    """``output`` ``(H, W, 3)`` display (sRGB) values in [0, 1], scaled in linear light so that
    its Gaussian low-pass (std ``sigma`` px) of the channel mean equals that of the input, the
    mean of ``left`` and ``right`` in linear light (``left`` alone for a one-view model)."""
    if not (math.isfinite(sigma) and sigma > 0):
        raise ParameterError(f"sigma must be a positive number of pixels, got {sigma}")
    linear_in = _linear(left) if right is None else 0.5 * (_linear(left) + _linear(right))
    linear_out = _linear(output)
    gain = ((_low_pass(linear_in.mean(axis=2), sigma) + _FLOOR)
            / (_low_pass(linear_out.mean(axis=2), sigma) + _FLOOR))
    tied = np.clip(linear_out * gain[..., None], 0.0, 1.0)
    return linear_to_srgb(torch.from_numpy(tied)).numpy()
