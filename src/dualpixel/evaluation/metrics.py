"""Image-quality metrics as the DPDD papers compute them (paper Sec. 5, Table 1).

Images are float arrays in [0, 1], ``(H, W, 3)``. PSNR uses peak 1 over all pixels and channels
(identical to peak 255 on 8-bit data), SSIM is scikit-image's ``structural_similarity`` over the
colour image (``channel_axis=-1, data_range=1``), MAE the mean absolute error.
"""

from __future__ import annotations

import numpy as np
from skimage.metrics import structural_similarity

__all__ = ["mae", "psnr", "ssim"]


def _pair(prediction: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    prediction = np.asarray(prediction, dtype=np.float64)
    target = np.asarray(target, dtype=np.float64)
    if prediction.shape != target.shape:
        raise ValueError(f"shapes differ: {prediction.shape} vs {target.shape}")
    return prediction, target


def psnr(prediction: np.ndarray, target: np.ndarray) -> float:
    """Peak signal-to-noise ratio in dB for values in [0, 1] (inf for identical images)."""
    prediction, target = _pair(prediction, target)
    mse = float(np.mean((prediction - target) ** 2))
    return float("inf") if mse == 0 else 10.0 * np.log10(1.0 / mse)


def ssim(prediction: np.ndarray, target: np.ndarray) -> float:
    """Structural similarity over the colour image (scikit-image, data range 1)."""
    prediction, target = _pair(prediction, target)
    channel_axis = -1 if prediction.ndim == 3 else None
    return float(
        structural_similarity(prediction, target, channel_axis=channel_axis, data_range=1.0)
    )


def mae(prediction: np.ndarray, target: np.ndarray) -> float:
    """Mean absolute error for values in [0, 1]."""
    prediction, target = _pair(prediction, target)
    return float(np.mean(np.abs(prediction - target)))
