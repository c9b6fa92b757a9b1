"""Where the blur happens: in linear light, while images store encoded (sRGB) values (ours).

A lens mixes light, so a real camera's defocus blur is a convolution of scene radiance, and the
tone curve comes after it; the paper's generator (and ``light="encoded"``) convolves the stored
8-bit values instead. The difference shows at contrasty edges and highlights: blurred in linear
light, a bright region spreads further into a dark one. ``dualpixel calibrate camera`` measures
which of the two explains a camera's pairs (:mod:`dualpixel.calibration.camera`).

The transfer function is sRGB's (IEC 61966-2-1), applied to values in [0, 1].

>>> import torch
>>> round(float(linear_to_srgb(srgb_to_linear(torch.tensor(0.5)))), 6)
0.5
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Literal

import cv2
import numpy as np
import torch

from dualpixel.errors import ParameterError, check_range
from dualpixel.names import ENCODINGS, LIGHT_SPACES

__all__ = ["LIGHT_SPACES", "CombinedImage", "Light", "check_encoding", "check_light",
           "check_raw_storage", "combined_image", "combined_light", "linear_to_raw",
           "linear_to_srgb", "linear_to_srgb_array", "srgb_to_linear", "srgb_to_linear_array"]

Light = Literal["encoded", "linear"]  # LIGHT_SPACES


def check_light(light: str) -> str:
    if light not in LIGHT_SPACES:
        raise ParameterError(f"light must be one of {', '.join(LIGHT_SPACES)}, got {light!r}")
    return light


def _pow_(values: torch.Tensor, exponent: float) -> torch.Tensor:
    """``values ** exponent`` in place (values >= 0): OpenCV's for a float32 CPU tensor whose
    elements fill their memory in some order (contiguous or permuted, as a ``(H, W, C)`` image
    seen as ``(C, H, W)``; about 2.4x faster than torch's on a 1920x1080 RGB frame), torch's
    elsewhere."""
    if values.device.type == "cpu" and values.dtype == torch.float32 and values.ndim:
        dense = values.permute(sorted(range(values.ndim), key=lambda i: -values.stride(i)))
        if dense.is_contiguous():
            array = dense.numpy().reshape(-1, dense.shape[-1])
            cv2.pow(array, exponent, dst=array)
            return values
    return values.pow_(exponent)


def srgb_to_linear(values: torch.Tensor) -> torch.Tensor:
    """sRGB-encoded values in [0, 1] -> linear light in [0, 1] (any shape)."""
    values = values.clamp(0.0, 1.0)
    if values.requires_grad:  # autograd keeps each step's input: no step in place
        return torch.where(values <= 0.04045, values / 12.92, ((values + 0.055) / 1.055) ** 2.4)
    curve = _pow_(values.add(0.055).div_(1.055), 2.4)  # in place: a frame is 25 MB a pass
    return torch.where(values <= 0.04045, values.div_(12.92), curve, out=curve)


def linear_to_srgb(values: torch.Tensor) -> torch.Tensor:
    """Linear light in [0, 1] -> sRGB-encoded values in [0, 1] (any shape; clipped first)."""
    values = values.clamp(0.0, 1.0)
    # The linear segment lies above the power segment below the threshold and below it above
    # (the power segment is concave), so the smaller of the two is sRGB's piecewise function.
    if values.requires_grad:  # autograd keeps each step's input: no step in place
        return torch.minimum(12.92 * values, 1.055 * values.clamp_min(0.0031308) ** (1 / 2.4)
                             - 0.055)
    curve = _pow_(values.clamp_min(0.0031308), 1 / 2.4).mul_(1.055).sub_(0.055)
    return torch.minimum(values.mul_(12.92), curve, out=curve)


def srgb_to_linear_array(image: np.ndarray) -> np.ndarray:
    """:func:`srgb_to_linear` for a NumPy array (any shape): float32 linear light."""
    return srgb_to_linear(torch.from_numpy(np.ascontiguousarray(image, np.float32))).numpy()


def linear_to_srgb_array(image: np.ndarray) -> np.ndarray:
    """:func:`linear_to_srgb` for a NumPy array (any shape): float32 sRGB-encoded values."""
    return linear_to_srgb(torch.from_numpy(np.ascontiguousarray(image, np.float32))).numpy()


def check_encoding(encoding: str) -> str:
    """The one check of how images store light (:data:`~dualpixel.names.ENCODINGS`)."""
    if encoding not in ENCODINGS:
        raise ParameterError(f"encoding must be one of {', '.join(ENCODINGS)}, got {encoding!r}")
    return encoding


def combined_light(left: np.ndarray, right: np.ndarray, encoding: str = "srgb") -> np.ndarray:
    """The combined image in linear light: the light the two photodiodes gather (paper Eq. 7,
    ``I_b = I_l + I_r``; at the views' brightness, as DPDD stores them, their mean), from views
    stored in ``encoding`` ("srgb": display values; "linear": linear values, e.g. raw above
    the black level). float32, the views' shape."""
    if check_encoding(encoding) == "linear":
        return 0.5 * (np.asarray(left, np.float32) + np.asarray(right, np.float32))
    return 0.5 * (srgb_to_linear_array(left) + srgb_to_linear_array(right))


def combined_image(left: np.ndarray, right: np.ndarray, *, encoding: str = "srgb",
                   light: Light = "linear") -> np.ndarray:
    """The combined image stored as the views are (``encoding``): the views averaged in
    ``light``, "linear" (:func:`combined_light`, what a sensor sums: the package's definition)
    or "encoded" (their stored values' mean: the paper's generator, which blurs the stored
    values, and a DPDD folder's own combined frames). float32, the views' shape."""
    if check_light(light) == "encoded" or check_encoding(encoding) == "linear":
        return 0.5 * (np.asarray(left, np.float32) + np.asarray(right, np.float32))
    return linear_to_srgb_array(combined_light(left, right, encoding))


@dataclass(eq=False)
class CombinedImage:
    """One pair's combined image, made once and read in either light: :attr:`light` (linear,
    :func:`combined_light`) and :attr:`encoded` (display values, :func:`combined_image`), for
    views ``(H, W, C)`` stored as display values. ``right`` None: one view's own image. The
    output modes of a frame (the overshoot limit, the brightness tie) share one."""

    left: np.ndarray
    right: np.ndarray | None = None

    @classmethod
    def of_light(cls, left: np.ndarray, right: np.ndarray | None,
                 light: np.ndarray) -> CombinedImage:
        """The combined image of display-valued views whose linear light is known already
        (``light``, the views' mean in linear light, ``(H, W, C)``): raw views, linear before
        they were encoded for the network, need not be decoded again."""
        combined = cls(left, right)
        combined.__dict__["light"] = np.asarray(light, np.float32)  # what the property keeps
        return combined

    @cached_property
    def light(self) -> np.ndarray:
        """Linear light, float32 ``(H, W, C)``."""
        if self.right is None:
            return srgb_to_linear_array(self.left)
        return combined_light(self.left, self.right)

    @cached_property
    def encoded(self) -> np.ndarray:
        """Display values, float32 ``(H, W, C)``: :attr:`light` encoded (the view itself when
        there is one)."""
        if self.right is None:
            return np.asarray(self.left, np.float32)
        return linear_to_srgb_array(self.light)

    def tensors(self, device: torch.device) -> tuple[torch.Tensor, torch.Tensor]:
        """``(light, encoded)`` as float32 ``(C, H, W)`` tensors made on ``device`` (a GPU's
        output modes): a light already known moves there, else the views do and it is made
        there."""

        def tensor(image: np.ndarray) -> torch.Tensor:
            return torch.from_numpy(np.ascontiguousarray(image, np.float32)).to(
                device).permute(2, 0, 1)

        if "light" in self.__dict__:  # known (of_light) or already made here
            light = tensor(self.light)
            return light, linear_to_srgb(light) if self.right is not None else tensor(self.left)
        if self.right is None:
            encoded = tensor(self.left)
            return srgb_to_linear(encoded), encoded
        light = 0.5 * (srgb_to_linear(tensor(self.left)) + srgb_to_linear(tensor(self.right)))
        return light, linear_to_srgb(light)


def check_raw_storage(black_level: float, gains: tuple[float, float]) -> None:
    """Refuse a raw storage :func:`linear_to_raw` cannot make: ``black_level`` in [0, 0.5),
    ``gains`` a ``(low, high)`` range with 0 < low <= high <= 1."""
    check_range("black_level (of full scale)", black_level, 0.0, 0.5, high_inclusive=False)
    values = tuple(gains) if isinstance(gains, (list, tuple)) else ()
    if (len(values) != 2 or not all(isinstance(g, (int, float)) for g in values)
            or not 0.0 < values[0] <= values[1] <= 1.0):
        raise ParameterError(f"raw_gains must be (low, high) with 0 < low <= high <= 1, got "
                             f"{str(gains)[:80]}")


def linear_to_raw(values: torch.Tensor, black_level: float, gain: float) -> torch.Tensor:
    """Linear light in [0, 1] -> values stored as a raw sensor stores them (any shape): the black
    level (fraction of full scale) plus the light times an exposure ``gain`` (<= 1 leaves
    headroom below the white level), still linear in light."""
    return black_level + (1.0 - black_level) * gain * values.clamp(0.0, 1.0)
