"""The array convention at the library's public boundary.

An *image* is any of

- NumPy ``(H, W, C)`` or grey ``(H, W)``, and batches ``(N, H, W, C)``;
- torch ``(C, H, W)`` or batches ``(N, C, H, W)``;
- a PIL image (any mode PIL can convert to RGB; 16-bit grey kept at 16 bits),

with ``C`` 1 (grey, copied to R, G and B), 3 (RGB) or 4 (RGBA, alpha dropped), as the command line
reads files. Values are floats in [0, 1] (a network's overshoot of up to :data:`FLOAT_TOLERANCE`
is clipped) or ``uint8`` / ``uint16`` read by their range (/ 255, / 65535). Other integer types
are refused: an ``int32`` array holding 0-255 would otherwise read as almost black. NaN and
infinite values are refused. Errors name the argument.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from dualpixel.errors import ParameterError

__all__ = [
    "FLOAT_TOLERANCE", "as_image_batch", "full_scale", "image_channels", "restore_layout",
    "to_unit_float",
]

#: How far outside [0, 1] a float image may lie and still be read (clipped): one 8-bit level.
FLOAT_TOLERANCE = 1.0 / 255.0

_CHANNELS = (1, 3, 4)


def to_unit_float(image: Any, name: str = "image", dtype=np.float64) -> np.ndarray:
    """``image`` (array-like, any shape) as ``dtype`` values in [0, 1] by the convention above.

    >>> to_unit_float(np.array([0, 255], np.uint8)).tolist()
    [0.0, 1.0]
    """
    array = np.asarray(image)
    if array.dtype == np.uint8 or array.dtype == np.uint16:
        return (array.astype(np.float64) / np.iinfo(array.dtype).max).astype(dtype)
    if array.dtype == np.bool_:
        raise ParameterError(f"{name}: boolean arrays are not images")
    if np.issubdtype(array.dtype, np.integer):
        raise ParameterError(
            f"{name}: {array.dtype} images are ambiguous; give uint8 (0-255), uint16 (0-65535) "
            "or floats in [0, 1] (e.g. image.astype(np.uint8) for 0-255 values)")
    if not np.issubdtype(array.dtype, np.floating):
        raise ParameterError(f"{name}: expected a numeric image, got dtype {array.dtype}")
    if array.size:
        finite = np.isfinite(array)
        if not finite.all():
            raise ParameterError(f"{name}: has {int((~finite).sum())} NaN or infinite values")
        low, high = float(array.min()), float(array.max())
        if low < -FLOAT_TOLERANCE or high > 1.0 + FLOAT_TOLERANCE:
            raise ParameterError(
                f"{name}: float values must lie in [0, 1], got [{low:.4g}, {high:.4g}] "
                "(scale 8-bit values by 1/255, or pass the uint8 array)")
        if low < 0.0 or high > 1.0:
            array = np.clip(array, 0.0, 1.0)
    return array.astype(dtype, copy=False)


def _from_pil(image: Any, name: str) -> np.ndarray:
    """A PIL image as a NumPy (H, W, C) array of its own bit depth."""
    if image.mode in ("I;16", "I;16B", "I;16L"):
        return np.asarray(image).astype(np.uint16)[..., None]
    if image.mode == "I":  # how PIL may open 16-bit grey files
        array = np.asarray(image)
        if array.size and (array.min() < 0 or array.max() > 65535):
            raise ParameterError(f"{name}: 32-bit PIL image outside 0-65535")
        return array.astype(np.uint16)[..., None]
    if image.mode == "F":
        return np.asarray(image)[..., None]
    if image.mode not in ("L", "RGB", "RGBA"):
        image = image.convert("RGBA" if "A" in image.getbands() else "RGB")
    array = np.asarray(image)
    return array[..., None] if array.ndim == 2 else array


def as_image_batch(image: Any, name: str = "image",
                   dtype=np.float32) -> tuple[np.ndarray, str]:
    """``image`` in any layout above as ``dtype`` ``(N, H, W, 3)`` in [0, 1], and its layout:
    ``"numpy"`` (one NumPy image or a PIL image), ``"numpy-batch"``, ``"torch"`` or
    ``"torch-batch"`` (see :func:`restore_layout`)."""
    if type(image).__module__.startswith("PIL."):
        array, layout = _from_pil(image, name)[None], "numpy"
    elif type(image).__module__.startswith("torch"):
        import torch

        if image.is_meta:
            raise ParameterError(f"{name}: a meta tensor holds no values")
        tensor = image.detach().cpu()
        if tensor.dtype in (torch.bfloat16, torch.float16):
            tensor = tensor.float()  # NumPy has no bfloat16; float32 holds both exactly
        if tensor.ndim == 3 and tensor.shape[0] in _CHANNELS:
            tensor, layout = tensor[None], "torch"
        elif tensor.ndim == 4 and tensor.shape[1] in _CHANNELS:
            layout = "torch-batch"
        elif tensor.ndim == 2:
            tensor, layout = tensor[None, None], "torch"
        else:
            raise ParameterError(f"{name}: expected a torch (C, H, W) or (N, C, H, W) image with "
                                 f"C 1, 3 or 4, got {tuple(tensor.shape)}")
        if tensor.dtype.is_complex:
            raise ParameterError(f"{name}: complex tensors are not images")
        array = tensor.permute(0, 2, 3, 1).numpy()
    else:
        array = np.asarray(image)
        if array.ndim == 2:
            array, layout = array[None, :, :, None], "numpy"
        elif array.ndim == 3 and array.shape[2] in _CHANNELS:
            array, layout = array[None], "numpy"
        elif array.ndim == 4 and array.shape[3] in _CHANNELS:
            layout = "numpy-batch"
        else:
            hint = (" (for (C, H, W) use np.moveaxis(image, 0, -1), or pass a torch tensor)"
                    if array.ndim == 3 and array.shape[0] in _CHANNELS else "")
            raise ParameterError(f"{name}: expected a NumPy (H, W), (H, W, C) or (N, H, W, C) "
                                 f"image with C 1, 3 or 4, got {array.shape}{hint}")
    if 0 in array.shape:
        raise ParameterError(f"{name}: image is empty, shape {array.shape}")
    if np.iscomplexobj(array):
        raise ParameterError(f"{name}: complex arrays are not images")
    channels = array.shape[3]
    if channels == 1:
        array = np.repeat(array, 3, axis=3)
    elif channels == 4:
        array = array[..., :3]
    return to_unit_float(array, name, dtype), layout


def restore_layout(images: np.ndarray, layout: str, like: Any = None) -> Any:
    """float32 ``(N, H, W, C)`` images back in the layout :func:`as_image_batch` reported;
    tensors on the device of ``like`` (the tensor they came from: CUDA in, CUDA out)."""
    if layout == "numpy":
        return images[0]
    if layout == "numpy-batch":
        return images
    import torch

    tensor = torch.from_numpy(np.ascontiguousarray(images)).permute(0, 3, 1, 2)
    if isinstance(like, torch.Tensor):
        tensor = tensor.to(like.device)
    return tensor[0] if layout == "torch" else tensor


def image_channels(image: Any) -> int:
    """How many channels ``image`` holds in any layout above (1 for grey, 2-D arrays and
    single-channel PIL modes included), without converting it."""
    if type(image).__module__.startswith("PIL."):
        return len(image.getbands())
    shape = tuple(image.shape) if hasattr(image, "shape") else np.shape(image)
    if type(image).__module__.startswith("torch"):
        return 1 if len(shape) == 2 else int(shape[-3])
    return 1 if len(shape) == 2 else int(shape[-1])


def full_scale(image: Any) -> float:
    """The value that stands for 1.0 in ``image``'s own units: 255 for uint8, 65535 for uint16
    (and 16-bit PIL images), 1 for floats."""
    if type(image).__module__.startswith("PIL."):
        return 65535.0 if image.mode.startswith("I") else 255.0 if image.mode != "F" else 1.0
    dtype = str(image.dtype) if hasattr(image, "dtype") else str(np.asarray(image).dtype)
    return {"uint8": 255.0, "torch.uint8": 255.0, "uint16": 65535.0,
            "torch.uint16": 65535.0}.get(dtype, 1.0)
