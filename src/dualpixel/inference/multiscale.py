"""Two-scale inference (ours, not in the paper): the network's output at full resolution
for the fine detail, and its output on the views at half resolution for the coarse structure.

At half resolution a blur of radius r px becomes r / 2 px, where the network does better: on a
tuning set of the default model's kind (unseen photo scenes, seed 22000, not the test set) the
half-resolution pass, upsampled, beat the full-resolution one on pixels blurred by 8 px or more
(20.76 against 20.35 dB on its first 20 frames) and on noisy, nearly sharp frames (averaging
four pixels halves the noise), but lost the fine detail of in-focus pixels (29.4 against 35.6
dB). Splitting the two by frequency keeps the best of each: with ``G`` a
Gaussian of standard deviation ``sigma`` (px at full resolution) and ``U`` bicubic upsampling,

fused = fine - G * fine + G * U(coarse) = fine + G * (U(coarse) - fine).

``sigma`` = 3 px was the best of 1, 2, 3, 4 and 6 px on all 40 tuning frames (28.09 -> 28.16 dB
with an earlier light RDPD); a third, quarter-
resolution scale added nothing (+0.01 dB on the first 20). Large blur gains, mild blur can lose a
little: see the README for the held-out and real-photograph numbers.
"""

from __future__ import annotations

import cv2
import numpy as np

from dualpixel.errors import ParameterError

__all__ = [
    "FUSION_SIGMA", "MIN_MULTISCALE_SIZE", "check_fusion_sigma", "fuse_scales", "half_resolution",
    "upsample",
]

#: Standard deviation (px at full resolution) of the Gaussian that splits the two scales.
FUSION_SIGMA = 3.0
#: The smallest frame side two-scale inference accepts (the half-resolution pass needs 16 px).
MIN_MULTISCALE_SIZE = 32


def check_fusion_sigma(sigma: float) -> None:
    """Refuse a split that is no Gaussian."""
    if not sigma > 0:
        raise ParameterError(f"the fusion sigma must be > 0 px, got {sigma}")


def half_resolution(view: np.ndarray) -> np.ndarray:
    """A view ``(H, W, 3)`` at half resolution ``(H // 2, W // 2, 3)`` by area averaging.

    >>> half_resolution(np.ones((65, 40, 3), np.float32)).shape
    (32, 20, 3)
    """
    height, width = view.shape[:2]
    if min(height, width) < MIN_MULTISCALE_SIZE:
        side = MIN_MULTISCALE_SIZE
        raise ParameterError(f"multiscale (two-scale) inference needs frames of at least "
                             f"{side}x{side} px, got {width}x{height}")
    return cv2.resize(np.ascontiguousarray(view), (width // 2, height // 2),
                      interpolation=cv2.INTER_AREA)


def upsample(coarse: np.ndarray, height: int, width: int) -> np.ndarray:
    """A half-resolution result ``(h, w, 3)`` back at ``(height, width, 3)``, bicubic, float32."""
    return cv2.resize(np.ascontiguousarray(coarse, dtype=np.float32), (width, height),
                      interpolation=cv2.INTER_CUBIC)


def fuse_scales(fine: np.ndarray, coarse: np.ndarray, sigma: float = FUSION_SIGMA) -> np.ndarray:
    """The frequencies above ``sigma`` from ``fine`` ``(H, W, 3)``, those below from ``coarse``
    ``(h, w, 3)`` upsampled to ``(H, W)`` (module docstring); clipped to [0, 1], float32.

    >>> flat = np.full((8, 8, 3), 0.25, np.float32)
    >>> float(fuse_scales(flat, np.full((4, 4, 3), 0.75, np.float32)).mean())
    0.75
    """
    check_fusion_sigma(sigma)
    low = cv2.GaussianBlur(upsample(coarse, *fine.shape[:2]) - fine, (0, 0), sigma)
    return np.clip(fine + low, 0.0, 1.0).astype(np.float32)
