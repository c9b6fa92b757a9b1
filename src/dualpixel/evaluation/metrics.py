"""Image-quality metrics as the DPDD papers compute them (paper Sec. 5, Table 1).

Images are ``(H, W, 3)`` (or ``(H, W)``) arrays: float in [0, 1], or integer images read by
their dtype's range (uint8 / 255, uint16 / 65535; :func:`dualpixel.io.arrays.to_unit_float`), so
every metric gives scikit-image's value for its ``data_range``. PSNR uses peak 1 over all pixels
and channels (identical to peak 255 on 8-bit data), SSIM is scikit-image's
``structural_similarity`` over the colour image (``channel_axis=-1, data_range=1``), MAE the mean
absolute error.
"""

from __future__ import annotations

import numpy as np
from skimage.metrics import structural_similarity

from dualpixel.errors import ParameterError
from dualpixel.io.arrays import to_unit_float

__all__ = ["mae", "psnr", "ssim"]


def _pair(prediction: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    prediction = to_unit_float(prediction, "prediction")
    target = to_unit_float(target, "target")
    if prediction.shape != target.shape:
        raise ParameterError(f"shapes differ: prediction {prediction.shape}, target {target.shape}")
    if prediction.ndim not in (2, 3) or 0 in prediction.shape:
        raise ParameterError(f"expected (H, W) or (H, W, C) images, got shape {prediction.shape}")
    return prediction, target


def psnr(prediction: np.ndarray, target: np.ndarray) -> float:
    """Peak signal-to-noise ratio in dB, peak 1 after scaling (inf for identical images)."""
    prediction, target = _pair(prediction, target)
    mse = float(np.mean((prediction - target) ** 2))
    return float("inf") if mse == 0 else 10.0 * np.log10(1.0 / mse)


def ssim(prediction: np.ndarray, target: np.ndarray) -> float:
    """Structural similarity over the colour image (scikit-image, data range 1)."""
    prediction, target = _pair(prediction, target)
    if min(prediction.shape[:2]) < 7:
        raise ParameterError(f"SSIM needs images of at least 7x7 pixels, got {prediction.shape}")
    channel_axis = -1 if prediction.ndim == 3 else None
    return float(
        structural_similarity(prediction, target, channel_axis=channel_axis, data_range=1.0)
    )


def mae(prediction: np.ndarray, target: np.ndarray) -> float:
    """Mean absolute error on the [0, 1] scale."""
    prediction, target = _pair(prediction, target)
    return float(np.mean(np.abs(prediction - target)))
