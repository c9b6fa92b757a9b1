"""Image gradients used across the package (flat-patch rejection, figure crops), in one place."""

from __future__ import annotations

import numpy as np
from scipy import ndimage

__all__ = ["gradient_magnitude", "sharpness"]


def gradient_magnitude(image: np.ndarray) -> np.ndarray:
    """Sobel gradient magnitude of the grey (channel-mean) image, ``(H, W)``."""
    grey = image.mean(axis=-1)
    return np.hypot(ndimage.sobel(grey, 0), ndimage.sobel(grey, 1))


def sharpness(image: np.ndarray) -> float:
    """Mean Sobel gradient magnitude of the grey image, a cheap flat-patch detector."""
    return float(gradient_magnitude(image).mean())
