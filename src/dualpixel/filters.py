"""Image gradients used across the package (flat-patch rejection, figure crops), in one place."""

from __future__ import annotations

import cv2
import numpy as np

__all__ = ["gradient_magnitude", "sharpness"]


def gradient_magnitude(image: np.ndarray) -> np.ndarray:
    """Sobel gradient magnitude of the grey (channel-mean) image, ``(H, W)`` float32.

    ``image`` is ``(H, W, C)``, float in [0, 1] or uint8 (read as /255, so both give the same
    values); borders reflect (``d c b a | a b c d``, SciPy's ``ndimage.sobel`` default).
    """
    grey = image.mean(axis=-1, dtype=np.float32)
    if image.dtype == np.uint8:
        grey *= np.float32(1 / 255)
    gx = cv2.Sobel(grey, cv2.CV_32F, 1, 0, ksize=3, borderType=cv2.BORDER_REFLECT)
    gy = cv2.Sobel(grey, cv2.CV_32F, 0, 1, ksize=3, borderType=cv2.BORDER_REFLECT)
    return cv2.magnitude(gx, gy)


def sharpness(image: np.ndarray) -> float:
    """Mean Sobel gradient magnitude of the grey image (units of [0, 1] intensity per pixel),
    a cheap flat-patch detector."""
    return float(gradient_magnitude(image).mean())
