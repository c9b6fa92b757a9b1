"""The radial distance channel (paper Sec. 4, supplement Fig. S5).

Each pixel's distance from the *full* image's centre, divided by the centre-to-corner distance, so
it is 0 at the centre and 1 at the corners. Training crops it with the patch, so the network knows
where a patch lies relative to the optical centre (PSFs vary radially).
"""

from __future__ import annotations

import numpy as np

__all__ = ["radial_distance"]


def radial_distance(
    height: int,
    width: int,
    *,
    full_size: tuple[int, int] | None = None,
    top: int = 0,
    left: int = 0,
) -> np.ndarray:
    """Normalised radial distance of a ``height x width`` window at ``(top, left)`` of an image.

    Args:
        height, width: size of the window to return.
        full_size: ``(H, W)`` of the full image whose centre counts; defaults to the window's own.
        top, left: position of the window in the full image.

    Returns:
        float32 ``(height, width)`` with values in [0, 1] (1 at the full image's corner pixels).
    """
    full_h, full_w = full_size if full_size is not None else (height, width)
    cy, cx = (full_h - 1) / 2.0, (full_w - 1) / 2.0
    ys = np.arange(top, top + height, dtype=np.float64) - cy
    xs = np.arange(left, left + width, dtype=np.float64) - cx
    corner = max(np.hypot(cy, cx), 1e-12)
    return (np.hypot(ys[:, None], xs[None, :]) / corner).astype(np.float32)
