"""Image-quality metrics as the DPDD papers compute them (paper Sec. 5, Table 1).

Images follow the package's array convention (:mod:`dualpixel.io.arrays`): NumPy ``(H, W, C)`` or
``(H, W)``, torch ``(C, H, W)``, PIL, floats in [0, 1] or uint8 / uint16 by their range, so every
metric gives scikit-image's value for its ``data_range``. A batch (NumPy ``(N, H, W, C)``, torch
``(N, C, H, W)``) gives the mean of the per-image values, as DPDD tables average per image. PSNR
uses peak 1 over all pixels and channels (identical to peak 255 on 8-bit data), SSIM is
scikit-image's ``structural_similarity`` over the colour image (``channel_axis=-1,
data_range=1``), MAE the mean absolute error.
"""

from __future__ import annotations

import numpy as np
from skimage.metrics import structural_similarity

from dualpixel.errors import ParameterError
from dualpixel.io.arrays import as_image_batch

__all__ = ["mae", "psnr", "ssim"]


def _pairs(prediction, target) -> list[tuple[np.ndarray, np.ndarray]]:
    """The (prediction, target) images as float64 ``(H, W, 3)`` pairs, one per batch item."""
    predictions, _ = as_image_batch(prediction, "prediction", np.float64)
    targets, _ = as_image_batch(target, "target", np.float64)
    if predictions.shape != targets.shape:
        raise ParameterError(f"shapes differ: prediction {predictions.shape[:3]}, "
                             f"target {targets.shape[:3]} (N, H, W)")
    return list(zip(predictions, targets))


def _psnr(prediction: np.ndarray, target: np.ndarray) -> float:
    mse = float(np.mean((prediction - target) ** 2))
    return float("inf") if mse == 0 else 10.0 * np.log10(1.0 / mse)


def _ssim(prediction: np.ndarray, target: np.ndarray) -> float:
    if min(prediction.shape[:2]) < 7:
        raise ParameterError(f"SSIM needs images of at least 7x7 pixels, got {prediction.shape}")
    return float(structural_similarity(prediction, target, channel_axis=-1, data_range=1.0))


def psnr(prediction, target) -> float:
    """Peak signal-to-noise ratio in dB, peak 1 after scaling (inf for identical images)."""
    return float(np.mean([_psnr(p, t) for p, t in _pairs(prediction, target)]))


def ssim(prediction, target) -> float:
    """Structural similarity over the colour image (scikit-image, data range 1)."""
    return float(np.mean([_ssim(p, t) for p, t in _pairs(prediction, target)]))


def mae(prediction, target) -> float:
    """Mean absolute error on the [0, 1] scale."""
    return float(np.mean([np.mean(np.abs(p - t)) for p, t in _pairs(prediction, target)]))
