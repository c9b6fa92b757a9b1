"""Views as the models take them, and outputs back as the views came: grey and linear raw views.

The shipped models take RGB views stored as display values (the sRGB curve, as 8-bit photographs
and the DPDD store them). A phone's DP data are often neither: the Google Pixel's are one green
channel of the raw frame (grey), and raw views are linear in light above a black level, with the
right view a little darker or brighter than the left (DP shading). :class:`ViewEncoding` says how a
pair stores light; :func:`to_model` turns the views into what the models take (black level off,
scaled by the white level, the right view's gain applied, sRGB-encoded, grey copied to R, G and B)
and :func:`from_model` turns the output back (decoded to linear, black level back on, one
channel for grey views). Linear views are also brought to the exposure the models were trained
at (:meth:`ViewEncoding.exposed`): a phone's raw views often peak at a third of full scale,
darker than any training frame; their light is scaled up for the network and the output scaled
back. :func:`encoding_findings` warns when the views look linear but are
declared display-encoded, or the reverse.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from dualpixel.errors import InputFileError, ParameterError
from dualpixel.inference.view_checks import ViewFinding, thinned, views_from_sum
from dualpixel.names import ENCODINGS
from dualpixel.optics.tone import (
    CombinedImage,
    check_encoding,
    combined_image,
    combined_light,
    linear_to_srgb_array,
    srgb_to_linear_array,
)

__all__ = [
    "ENCODINGS", "EXPOSURE_TARGET", "LINEAR_LIGHT", "ViewEncoding", "deblur_encoded",
    "encoding_findings", "exposure_gain", "flat_field_gain", "from_model", "linear_light",
    "pair_exposed", "to_model", "view_encoding_from_files",
]

#: Views whose median lies below this fraction of full scale, with 99 % of values below
#: :data:`LINEAR_P99`, look like linear raw data.
LINEAR_MEDIAN = 0.08
LINEAR_P99 = 0.5
#: Views declared linear whose median lies above this look display-encoded.
ENCODED_MEDIAN = 0.3
#: Where the training frames put the light of a high percentile (:data:`EXPOSURE_PERCENTILE`)
#: of the combined image, linear, full scale 1: the median over procedural "photo" scenes is
#: 0.67, over scenes of the validation photographs 0.78.
EXPOSURE_TARGET = 0.7
EXPOSURE_PERCENTILE = 99.0
#: The brightest values kept below full scale by the exposure: all but this percentile's tail.
EXPOSURE_PEAK_PERCENTILE = 99.99
#: The largest exposure gain (dark views are noisy: beyond this the noise, not the light, is
#: what the network would see).
EXPOSURE_MAX_GAIN = 16.0


@dataclass(frozen=True)
class ViewEncoding:
    """How a DP pair stores light.

    ``encoding``: :data:`ENCODINGS`. For ``"linear"`` views ``black_level`` and ``white_level``
    are required, in the views' own units (the file's numbers for 8/16-bit files and integer
    arrays, fractions of 1 for float arrays); ``right_gain`` multiplies the right view (after
    the black level is taken off) to match the left: a number, or an ``(H, W)`` map from a
    flat-field capture (:func:`flat_field_gain`). ``auto_exposure``: linear views are brought
    to the training frames' exposure (:meth:`exposed`; on by default); ``light_gain``: the
    factor on their light that does it, per image (a number, or an array ``(..., 1, 1, 1)``
    over a batch), undone on the output.
    """

    encoding: str = "srgb"
    black_level: float | None = None
    white_level: float | None = None
    right_gain: float | np.ndarray = 1.0
    auto_exposure: bool = True
    light_gain: float | np.ndarray = 1.0

    def __post_init__(self) -> None:
        if check_encoding(self.encoding) == "srgb":
            if (self.black_level is not None or self.white_level is not None
                    or not np.all(np.asarray(self.right_gain) == 1.0)
                    or not np.all(np.asarray(self.light_gain) == 1.0)):
                raise ParameterError("black_level, white_level and right_gain are for linear "
                                     "views; pass encoding='linear' (--encoding linear) with them")
            return
        if self.black_level is None or self.white_level is None:
            missing = "black_level" if self.black_level is None else "white_level"
            raise ParameterError(f"linear views need {missing} (--{missing.replace('_', '-')}): "
                                 "the raw value of no light and of saturation, from the camera's "
                                 "metadata (e.g. 1024 and 16383 for 14-bit data with that offset)")
        black, white = float(self.black_level), float(self.white_level)
        if not (math.isfinite(black) and math.isfinite(white) and 0 <= black < white):
            raise ParameterError(f"need 0 <= black_level < white_level, got {black} and {white}")
        for name in ("right_gain", "light_gain"):
            gain = np.asarray(getattr(self, name), np.float64)
            if not np.isfinite(gain).all() or (gain <= 0).any():
                raise ParameterError(f"{name} must be positive and finite")
        if not isinstance(self.auto_exposure, (bool, np.bool_)):
            raise ParameterError(f"auto_exposure must be True or False, got "
                                 f"{self.auto_exposure!r}")

    @property
    def linear(self) -> bool:
        return self.encoding == "linear"

    def check_levels(self, left: np.ndarray, right: np.ndarray, *, scale: float = 1.0) -> None:
        """Refuse levels that do not fit views ``(..., H, W, C)`` read as fractions of
        ``scale`` (the full scale of their own units: 255 or 65535 for 8- or 16-bit data, 1 for
        floats): a white level beyond that full scale (levels of another bit depth), a black
        level at or above every value (the image would be black), or a right-gain map of
        another size. A :class:`ParameterError`
        saying what was given and what the views hold."""
        if not self.linear:
            return
        _check_gain_shape(np.asarray(self.right_gain), left.shape[-3:-1])
        black, white = float(self.black_level), float(self.white_level)
        unit = "" if scale == 1.0 else f" of {scale:g}"
        if white > scale * (1 + 1e-9):
            raise ParameterError(f"white_level {white:g} is beyond these views' full scale "
                                 f"({scale:g}): levels of another bit depth? give them in the "
                                 "views' own units")
        peak = float(max(np.max(left), np.max(right))) * scale
        if black >= peak:
            raise ParameterError(f"black_level {black:g} is at or above every value of the "
                                 f"views (largest {peak:g}{unit}): nothing would be left above "
                                 "it")

    def exposed(self, left: np.ndarray, right: np.ndarray, *, scale: float = 1.0,
                views_sum: bool = False, check: bool = True) -> ViewEncoding:
        """This encoding with the :attr:`light_gain` of views ``(..., H, W, C)``
        (:func:`exposure_gain`) when they are linear and :attr:`auto_exposure` is on; else
        itself. Compute it once per photograph or sequence (a sequence keeps one exposure).
        ``check``: first :meth:`check_levels` (off for training crops, which may be all black)."""
        if check:
            self.check_levels(left, right, scale=scale)
        if not (self.linear and self.auto_exposure):
            return self
        plain = dataclasses.replace(self, light_gain=1.0)
        gain = exposure_gain(*linear_light(left, right, plain, scale=scale, views_sum=views_sum))
        return dataclasses.replace(self, light_gain=gain)


def _check_gain_shape(gain: np.ndarray, shape: tuple[int, int]) -> None:
    """Refuse a right-gain map ``(H, W)`` of another size than views of ``shape`` ``(H, W)``."""
    if gain.ndim and gain.shape[:2] != shape:
        raise ParameterError(f"the right view's gain map (a flat field, --flat-field) is "
                             f"{gain.shape[1]}x{gain.shape[0]} but the views are "
                             f"{shape[1]}x{shape[0]}: capture the flat field at the views' size")


#: Linear views already in light units: black level 0, saturation 1 (what :func:`linear_light`
#: gives; the target-free checks take linear views so).
LINEAR_LIGHT = ViewEncoding("linear", 0.0, 1.0)


def linear_light(left: np.ndarray, right: np.ndarray, encoding: ViewEncoding, *,
                 scale: float = 1.0, views_sum: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Linear raw views ``(..., H, W, C)`` (fractions of ``scale``, the full scale of the
    views' own units) as light in [0, 1]: the black level taken off, divided by the span to the
    white level, the right view's gain applied, each doubled with ``views_sum``, times the
    encoding's :attr:`~ViewEncoding.light_gain` (its exposure)."""
    black = float(encoding.black_level) / scale
    white = float(encoding.white_level) / scale
    gain = np.asarray(encoding.right_gain, np.float32)
    _check_gain_shape(gain, left.shape[-3:-1])
    gain = gain[..., None] if gain.ndim == 2 else gain
    span = white - black
    factor = (2.0 if views_sum else 1.0) * np.asarray(encoding.light_gain, np.float32)
    return (np.clip((left - black) / span * factor, 0.0, 1.0),
            np.clip((right - black) / span * gain * factor, 0.0, 1.0))


def exposure_gain(left: np.ndarray, right: np.ndarray) -> float | np.ndarray:
    """The factor on linear light ``(..., H, W, C)`` in [0, 1] that puts the
    :data:`EXPOSURE_PERCENTILE` of the combined image (the views' mean) at
    :data:`EXPOSURE_TARGET`, where the training frames have it: at least 1 (bright views are
    left as they are), at most :data:`EXPOSURE_MAX_GAIN` and what keeps all but the brightest
    0.01 % below full scale (nothing that was not clipped is clipped). A number for one pair,
    ``(N, 1, 1, 1)`` for a batch.

    >>> dark = np.full((8, 8, 1), 0.1, np.float32)
    >>> round(float(exposure_gain(dark, dark)), 4)
    7.0
    """
    combined = combined_light(left, right, "linear")
    flat = combined.reshape(*combined.shape[:-3], -1)
    high, peak = np.percentile(flat, [EXPOSURE_PERCENTILE, EXPOSURE_PEAK_PERCENTILE], axis=-1)
    with np.errstate(divide="ignore"):
        gain = np.minimum(EXPOSURE_TARGET / high, 1.0 / peak)
    gain = np.clip(np.nan_to_num(gain, nan=1.0, posinf=EXPOSURE_MAX_GAIN), 1.0,
                   EXPOSURE_MAX_GAIN)
    return float(gain) if np.ndim(gain) == 0 else gain.reshape(*gain.shape, 1, 1, 1)


def to_model(left: np.ndarray, right: np.ndarray, encoding: ViewEncoding, *,
             scale: float = 1.0, views_sum: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Views ``(..., H, W, C)`` float in [0, 1] (``C`` 1 or 3) as the models take them:
    ``(..., H, W, 3)`` display values in [0, 1]. ``scale``: full scale of the views' own units
    (65535 for 16-bit data read as fractions), by which the levels are divided.
    ``views_sum``: the views sum to the combined image (a raw A/B split): each is doubled (in
    linear light for linear views; :func:`~dualpixel.inference.view_checks.views_from_sum`)."""
    return _to_model(left, right, encoding, scale=scale, views_sum=views_sum)[0]


def _to_model(left: np.ndarray, right: np.ndarray, encoding: ViewEncoding, *,
              scale: float = 1.0, views_sum: bool = False):
    """:func:`to_model`'s views, and for linear views their combined light ``(..., H, W, 3)``
    (the mean of their light before encoding), else None."""
    light = None
    if encoding.linear:
        left, right = linear_light(left, right, encoding, scale=scale, views_sum=views_sum)
        light = combined_light(left, right, "linear")
        left, right = linear_to_srgb_array(left), linear_to_srgb_array(right)
    elif views_sum:
        left, right = views_from_sum(left, right)
    if left.shape[-1] == 1:
        left, right = np.repeat(left, 3, axis=-1), np.repeat(right, 3, axis=-1)
        light = None if light is None else np.repeat(light, 3, axis=-1)
    return (left.astype(np.float32, copy=False), right.astype(np.float32, copy=False)), light


def from_model(output: np.ndarray, encoding: ViewEncoding, channels: int, *,
               scale: float = 1.0) -> np.ndarray:
    """A model's output ``(..., 3)`` in display values back in the views' encoding and
    channel count (grey: the mean of the three channels)."""
    if channels == 1:
        output = output.mean(axis=-1, keepdims=True)
    if encoding.linear:
        black = float(encoding.black_level) / scale
        white = float(encoding.white_level) / scale
        light = srgb_to_linear_array(output) / np.asarray(encoding.light_gain, np.float32)
        output = np.clip(light * (white - black) + black, 0.0, 1.0)
    return output.astype(np.float32, copy=False)


def flat_field_gain(left: np.ndarray, right: np.ndarray, *, black_level: float = 0.0,
                    sigma: float = 16.0) -> np.ndarray:
    """Gain map ``(H, W)`` that brings the right view to the left's, from a DP capture of a
    flat, evenly lit surface (DP shading varies smoothly over the frame): the ratio of the
    views' Gaussian-smoothed values above ``black_level`` (same units as the views)."""
    if left.shape != right.shape:
        raise ParameterError(f"flat-field views differ in shape: {left.shape} and {right.shape}")
    grey = [np.asarray(v, np.float32).reshape(*v.shape[:2], -1).mean(axis=2) - black_level
            for v in (left, right)]
    smooth = [cv2.GaussianBlur(g, (0, 0), sigma, borderType=cv2.BORDER_REFLECT) for g in grey]
    if (smooth[1] <= 0).any() or (smooth[0] <= 0).any():
        raise ParameterError("flat-field views must lie above the black level everywhere "
                             "(an evenly lit surface, not clipped to black)")
    return (smooth[0] / smooth[1]).astype(np.float32)


def encoding_findings(left: np.ndarray, right: np.ndarray, encoding: str) -> list[ViewFinding]:
    """A warning when views ``(H, W, C)`` in [0, 1] look linear (raw) but are declared
    display-encoded, or the reverse; empty when they look as declared."""
    values = combined_image(thinned(left), thinned(right), light="encoded")  # as declared
    median, p99 = (float(v) for v in np.percentile(values, (50, 99)))
    if encoding == "srgb" and median < LINEAR_MEDIAN and p99 < LINEAR_P99:
        return [ViewFinding("looks-linear", (
            f"the views look linear (raw): half their values lie below {100 * median:.1f} % "
            f"of full scale and 99 % below {100 * p99:.0f} %, as raw sensor data do; if they "
            "are raw, pass --encoding linear with --black-level and --white-level "
            "(encoding='linear' in the API)"))]
    if encoding == "linear" and median > ENCODED_MEDIAN:
        return [ViewFinding("looks-encoded", (
            f"the views look display-encoded (median {100 * median:.0f} % of full scale, "
            "brighter than raw data usually are); if they are ordinary images, drop "
            "--encoding linear"))]
    return []


def view_encoding_from_files(encoding: str, black_level: float | None, white_level: float | None,
                             right_gain: float = 1.0,
                             flat_field: tuple[str | Path, str | Path] | None = None, *,
                             auto_exposure: bool = True) -> ViewEncoding:
    """A :class:`ViewEncoding` as ``dualpixel deblur`` takes it: the right view's gain a number
    or, with ``flat_field`` (left and right image files of a flat-field DP capture), the map
    :func:`flat_field_gain` makes from them (levels in the files' own units)."""
    from dualpixel.io.images import max_level, read_views

    if flat_field is None:
        return ViewEncoding(encoding, black_level, white_level, right_gain,
                            auto_exposure=auto_exposure)
    if encoding != "linear" or black_level is None:
        raise ParameterError("--flat-field is for linear views: give --encoding linear with "
                             "--black-level and --white-level")
    if right_gain != 1.0:
        raise ParameterError("give --flat-field or --right-gain, not both")
    left, right, (bits, _) = read_views(*flat_field)
    try:
        gain = flat_field_gain(left, right, black_level=black_level / max_level(bits))
    except ParameterError as error:
        raise InputFileError(flat_field[0], f"as a flat field: {error}") from None
    return ViewEncoding(encoding, black_level, white_level, gain, auto_exposure=auto_exposure)


def pair_exposed(encoding: ViewEncoding | None, left: np.ndarray, right: np.ndarray | None, *,
                 scale: float = 1.0, views_sum: bool = False) -> ViewEncoding:
    """``encoding`` (display values when None) with the exposure of one pair found
    (:meth:`ViewEncoding.exposed`); ``right`` None: a single-view model's pair."""
    return (encoding or ViewEncoding()).exposed(
        left, left if right is None else right, scale=scale,
        views_sum=views_sum and right is not None)


def deblur_encoded(deblurrer: Callable[[np.ndarray, np.ndarray | None], np.ndarray],
                   left: np.ndarray, right: np.ndarray | None,
                   encoding: ViewEncoding | None = None, *, scale: float = 1.0,
                   views_sum: bool = False, exposed: ViewEncoding | None = None,
                   inspect: Callable[[np.ndarray, np.ndarray], None] | None = None
                   ) -> np.ndarray:
    """One pair ``(H, W, C)`` in its own encoding through ``deblurrer`` (a
    :class:`~dualpixel.inference.Deblurrer`): the output in the same encoding and channels.

    The one place views go to the network's values and back (``dualpixel deblur``, the API and
    the target-free checks). ``right`` None: a single-view model. ``exposed``: the encoding with
    its exposure already found (a sequence keeps its first pair's; :meth:`ViewEncoding.exposed`),
    else found here from ``encoding``. ``inspect(left, right)`` sees the views as the network
    will (checks of a sequence's first pair)."""
    from dualpixel.inference.deblur import Deblurrer

    views_sum = views_sum and right is not None
    other = left if right is None else right
    if exposed is None:
        exposed = pair_exposed(encoding, left, right, scale=scale, views_sum=views_sum)
    (model_left, model_right), light = _to_model(left, other, exposed, scale=scale,
                                                 views_sum=views_sum)
    if right is None:
        model_right = None
    elif inspect is not None:
        inspect(model_left, model_right)
    if light is not None and right is not None and isinstance(deblurrer, Deblurrer):
        # linear views: the combined image's light as it was before encoding, not decoded again
        output = deblurrer(model_left, model_right,
                           combined=CombinedImage.of_light(model_left, model_right, light))
    else:
        output = deblurrer(model_left, model_right)
    return from_model(output, exposed, left.shape[-1], scale=scale)
