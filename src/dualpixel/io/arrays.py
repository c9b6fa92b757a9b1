"""The array convention at the library's public boundary.

Images are float in [0, 1], or integers read by their dtype's range (uint8 / 255, uint16 / 65535,
any other integer type by its maximum). Floats far outside [0, 1] (e.g. 0-255 values stored as
float) are refused rather than silently misread.
"""

from __future__ import annotations

import numpy as np

from dualpixel.errors import ParameterError

__all__ = ["to_unit_float"]

#: A float image may overshoot [0, 1] a little (a network's output); beyond this it is refused.
FLOAT_TOLERANCE = 0.5


def to_unit_float(image, name: str = "image", dtype=np.float64) -> np.ndarray:
    """``image`` (array-like, any shape) as ``dtype`` values in [0, 1] by the convention above.

    >>> to_unit_float(np.array([0, 255], np.uint8)).tolist()
    [0.0, 1.0]
    """
    array = np.asarray(image)
    if array.dtype == np.bool_:
        raise ParameterError(f"{name}: boolean arrays are not images")
    if np.issubdtype(array.dtype, np.integer):
        info = np.iinfo(array.dtype)
        if info.min < 0 and array.size and array.min() < 0:
            raise ParameterError(f"{name}: integer image has negative values")
        return (array.astype(np.float64) / info.max).astype(dtype)
    if not np.issubdtype(array.dtype, np.floating):
        raise ParameterError(f"{name}: expected a numeric image, got dtype {array.dtype}")
    if array.size:
        if not np.isfinite(array).all():
            raise ParameterError(f"{name}: has NaN or infinite values")
        low, high = float(array.min()), float(array.max())
        if low < -FLOAT_TOLERANCE or high > 1.0 + FLOAT_TOLERANCE:
            raise ParameterError(
                f"{name}: float values must lie in [0, 1], got [{low:.4g}, {high:.4g}] "
                "(scale 8-bit values by 1/255, or pass the integer array)"
            )
    return array.astype(dtype, copy=False)
