"""NIQE, the no-reference "naturalness" score of Mittal, Soundararajan & Bovik (2013), with a
reference model fitted from any folder of sharp images (paper Sec. 5: "a reference model derived
from the DP GT images").

Features (the standard 36): on the luminance (0-255), at the original scale and at half scale
(bicubic), mean-subtracted contrast-normalised (MSCN) coefficients with a 7x7 Gaussian window
(sigma 7/6); per block of 96x96 pixels (48x48 at half scale) an asymmetric generalised Gaussian fit
of the MSCN values (shape, mean scale) and of their products with the four neighbours (horizontal,
vertical, two diagonals: shape, mean, left and right scale). A reference model is the mean and
covariance of the features of the sharpest blocks (sharpness > 0.75 x the image's sharpest) of the
reference images; an image's score is the Mahalanobis-like distance between its block statistics
and the model's. Lower is more natural.

The built-in model (``niqe_builtin.npz``) is fitted by us on scikit-image's bundled photographs
(:func:`fit_builtin_model` regenerates it); it is *not* the LIVE-trained MATLAB model, so its scores
are not comparable with published NIQE values. Fit your own with ``dualpixel niqe fit``.
"""

from __future__ import annotations

from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import cv2
import numpy as np
from scipy import ndimage
from scipy.special import gamma as gamma_fn

from dualpixel.errors import InputFileError, ParameterError
from dualpixel.io.atomic import atomic_path

__all__ = ["NIQEModel", "fit_niqe_model", "load_builtin_model", "niqe", "niqe_features"]

BLOCK = 96
SHARPNESS_FRACTION = 0.75
_SHAPES = np.arange(0.2, 10.001, 0.001)
_RATIO = gamma_fn(2 / _SHAPES) ** 2 / (gamma_fn(1 / _SHAPES) * gamma_fn(3 / _SHAPES))
_SHIFTS = ((0, 1), (1, 0), (1, 1), (1, -1))


@dataclass(frozen=True)
class NIQEModel:
    """Multivariate Gaussian of natural-scene features: mean (36,) and covariance (36, 36)."""

    mean: np.ndarray
    cov: np.ndarray
    source: str = ""

    def save(self, path: str | Path) -> None:
        with atomic_path(path) as tmp, open(tmp, "wb") as handle:
            np.savez(handle, mean=self.mean, cov=self.cov, source=np.array(self.source))

    @classmethod
    def load(cls, path: str | Path) -> NIQEModel:
        path = Path(path)
        if not path.is_file():
            raise InputFileError(path, "NIQE model not found")
        try:
            with np.load(path) as data:
                mean, cov, source = data["mean"], data["cov"], str(data["source"])
        except (OSError, KeyError, ValueError):
            raise InputFileError(path, "not a NIQE model (.npz with mean and cov)") from None
        if mean.shape != (36,) or cov.shape != (36, 36):
            raise InputFileError(path, f"NIQE model has shapes {mean.shape} and {cov.shape}")
        return cls(mean, cov, source)


def _luminance(image: np.ndarray) -> np.ndarray:
    """BT.601 luma in [0, 255] of a float RGB image in [0, 1] (grey images pass through)."""
    image = np.asarray(image, dtype=np.float64)
    if image.ndim == 3:
        image = image[..., :3] @ np.array([0.299, 0.587, 0.114])
    return image * 255.0


def _mscn(grey: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """MSCN coefficients and the local standard deviation (7x7 Gaussian, sigma 7/6)."""
    blur = lambda a: ndimage.gaussian_filter(a, 7 / 6, mode="nearest", truncate=3 / (7 / 6))  # noqa: E731
    mu = blur(grey)
    sigma = np.sqrt(np.abs(blur(grey * grey) - mu * mu))
    return (grey - mu) / (sigma + 1.0), sigma


def _aggd(values: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Asymmetric generalised Gaussian fit per row: (shape, left scale, right scale)."""
    neg, pos = values < 0, values > 0
    left = np.sqrt((values**2 * neg).sum(1) / np.maximum(neg.sum(1), 1))
    right = np.sqrt((values**2 * pos).sum(1) / np.maximum(pos.sum(1), 1))
    ratio = left / np.maximum(right, 1e-12)
    r_hat = np.abs(values).mean(1) ** 2 / np.maximum((values**2).mean(1), 1e-12)
    r_norm = r_hat * (ratio**3 + 1) * (ratio + 1) / (ratio**2 + 1) ** 2
    shape = _SHAPES[np.argmin((_RATIO[None, :] - r_norm[:, None]) ** 2, axis=1)]
    factor = np.sqrt(gamma_fn(1 / shape) / gamma_fn(3 / shape))
    return shape, left * factor, right * factor


def _blocks(array: np.ndarray, size: int) -> np.ndarray:
    rows, cols = array.shape[0] // size, array.shape[1] // size
    array = array[: rows * size, : cols * size]
    return array.reshape(rows, size, cols, size).swapaxes(1, 2).reshape(rows * cols, size, size)


def _scale_features(mscn: np.ndarray, size: int) -> np.ndarray:
    blocks = _blocks(mscn, size)
    flat = blocks.reshape(len(blocks), -1)
    shape, left, right = _aggd(flat)
    features = [shape, (left + right) / 2]
    for dy, dx in _SHIFTS:
        product = (blocks * np.roll(blocks, (-dy, -dx), axis=(1, 2))).reshape(len(blocks), -1)
        p_shape, p_left, p_right = _aggd(product)
        mean = (p_right - p_left) * gamma_fn(2 / p_shape) / gamma_fn(1 / p_shape)
        features += [p_shape, mean, p_left, p_right]
    return np.stack(features, axis=1)


def niqe_features(image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-block features ``(n_blocks, 36)`` and block sharpness ``(n_blocks,)`` of an image."""
    grey = _luminance(image)
    if min(grey.shape) < BLOCK:
        raise ParameterError(f"NIQE needs images of at least {BLOCK}x{BLOCK}, got {grey.shape}")
    rows, cols = grey.shape[0] // BLOCK * BLOCK, grey.shape[1] // BLOCK * BLOCK
    grey = grey[:rows, :cols]
    mscn, sigma = _mscn(grey)
    half = cv2.resize(grey, (cols // 2, rows // 2), interpolation=cv2.INTER_CUBIC)
    features = np.concatenate(
        [_scale_features(mscn, BLOCK), _scale_features(_mscn(half)[0], BLOCK // 2)], axis=1
    )
    sharpness = _blocks(sigma, BLOCK).mean(axis=(1, 2))
    return features, sharpness


def fit_niqe_model(images, *, source: str = "") -> NIQEModel:
    """Fit the reference model from an iterable of sharp float RGB images in [0, 1]."""
    selected = []
    for image in images:
        features, sharpness = niqe_features(image)
        keep = sharpness > SHARPNESS_FRACTION * sharpness.max() if sharpness.max() > 0 else []
        selected.append(features[keep])
    if not selected:
        raise ParameterError("no images to fit a NIQE model")
    stacked = np.concatenate(selected)
    if len(stacked) < 2:
        raise ParameterError("too few sharp blocks to fit a NIQE model; give more/larger images")
    return NIQEModel(stacked.mean(0), np.cov(stacked, rowvar=False), source)


def niqe(image: np.ndarray, model: NIQEModel | None = None) -> float:
    """NIQE score of a float RGB image in [0, 1] under ``model`` (the built-in one by default)."""
    model = model if model is not None else load_builtin_model()
    features, _ = niqe_features(image)
    mean = np.nanmean(features, axis=0)
    cov = np.cov(features, rowvar=False) if len(features) > 1 else np.zeros_like(model.cov)
    diff = model.mean - mean
    return float(np.sqrt(diff @ np.linalg.pinv((model.cov + cov) / 2) @ diff))


_BUILTIN = "niqe_builtin.npz"


def fit_builtin_model() -> NIQEModel:
    """Fit the built-in model from scikit-image's bundled photographs (no download)."""
    import skimage.data

    images = []
    for name in ("astronaut", "coffee", "chelsea", "rocket", "camera"):
        image = getattr(skimage.data, name)().astype(np.float64) / 255.0
        images.append(image)
    return fit_niqe_model(images, source="scikit-image photographs: astronaut, coffee, chelsea, "
                                         "rocket, camera")


def load_builtin_model() -> NIQEModel:
    """The shipped model (see the module docstring)."""
    return NIQEModel.load(Path(str(resources.files("dualpixel.evaluation").joinpath(_BUILTIN))))
