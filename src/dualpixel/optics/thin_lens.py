"""Thin-lens circle of confusion (paper Sec. 2.1, Eq. 1).

Units. The paper gives its five camera sets {f, F, s} without units or pixel pitch. We follow the
authors' generator: ``focal_length`` and ``focus_distance`` are in the same unit as depth (metres
for SYNTHIA and our procedural scenes), the lens is a *virtual* one, and Eq. 1 gives the CoC
radius on the virtual sensor in that unit. ``pixel_pitch`` (same unit) turns it into pixels. The
presets use ``pixel_pitch = 0.5``, which reproduces the CoC sizes of the authors' generator (it
omits the factor 1/2 of Eq. 1, i.e. it reads the diameter as the radius in pixels). Every radius is
clamped to ``max_coc_radius`` pixels (40 by default, as in the authors' experiments).

Sign convention: positive behind the focal plane (d > s), negative in front (d < s), zero at focus.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TypeVar

import numpy as np
import torch

from dualpixel.errors import ParameterError, check_range
from dualpixel.names import renamed_attributes

__all__ = [
    "DEFOCUS_PROFILES",
    "PAPER_LENS_SETS",
    "DefocusProfile",
    "ThinLens",
    "coc_radius",
    "focus_from_depth",
    "validate_depth",
]

ArrayT = TypeVar("ArrayT", np.ndarray, torch.Tensor)


@dataclass(frozen=True)
class ThinLens:
    """A thin lens before the sensor (paper Eq. 1): what a lens set blurs a scene with, not a
    calibrated camera (:class:`~dualpixel.optics.camera.DPCamera`). Lengths share the depth
    map's unit; see the module docstring.

    Args:
        focal_length: f, > 0.
        f_number: F, > 0; the aperture diameter is q = f / F.
        focus_distance: s, > f.
        pixel_pitch: sensor pixel size, > 0; the CoC in pixels is r / pixel_pitch.
        max_coc_radius: |r| is clamped to this many pixels, > 0.
        name: a label for manifests and figures.
    """

    focal_length: float
    f_number: float
    focus_distance: float
    pixel_pitch: float = 0.5
    max_coc_radius: float = 40.0
    name: str = "custom"

    def __post_init__(self) -> None:
        check_range("focal_length", self.focal_length, 0.0, low_inclusive=False)
        check_range("f_number", self.f_number, 0.0, low_inclusive=False)
        check_range("pixel_pitch", self.pixel_pitch, 0.0, low_inclusive=False)
        check_range("max_coc_radius", self.max_coc_radius, 0.0, low_inclusive=False)
        if not float(self.focus_distance) > float(self.focal_length):
            raise ParameterError(
                f"focus_distance must be greater than focal_length ({self.focal_length:g}), "
                f"got {self.focus_distance!r}"
            )

    @property
    def sensor_distance(self) -> float:
        """s' = f s / (s - f), the lens-to-sensor distance."""
        return self.focal_length * self.focus_distance / (self.focus_distance - self.focal_length)

    @property
    def aperture_diameter(self) -> float:
        """q = f / F."""
        return self.focal_length / self.f_number

    @property
    def coc_scale(self) -> float:
        """(q / 2) (s' / s) / pixel_pitch: the CoC radius in pixels of a point at infinity."""
        return 0.5 * self.aperture_diameter * self.sensor_distance / self.focus_distance / (
            self.pixel_pitch
        )

    def coc_radius(self, depth: ArrayT) -> ArrayT:
        """Signed CoC radius in pixels for a depth map (NumPy or torch); see :func:`coc_radius`."""
        return coc_radius(depth, self)


def validate_depth(depth: np.ndarray | torch.Tensor, name: str = "depth") -> None:
    """Raise :class:`ParameterError` unless every depth value is finite and > 0."""
    values = depth if isinstance(depth, torch.Tensor) else torch.from_numpy(np.asarray(depth))
    if values.numel() and values.is_floating_point():
        low, high = torch.aminmax(values)  # one pass; NaN makes both NaN, failing both tests
        if bool(low > 0) and bool(high < math.inf):
            return
    finite = torch.isfinite(values)
    if not bool(finite.all()):
        bad = int((~finite).sum())
        raise ParameterError(f"{name} must be finite and > 0; it has {bad} NaN or infinite values")
    if not bool((values > 0).all()):
        bad = int((values <= 0).sum())
        raise ParameterError(
            f"{name} must be finite and > 0; it has {bad} zero or negative values "
            f"(minimum {float(values.min()):g})"
        )


def coc_radius(depth: ArrayT, lens: ThinLens, *, clamp: bool = True) -> ArrayT:
    r"""Signed circle-of-confusion radius in pixels (paper Eq. 1).

    .. math:: r = \frac{q}{2} \frac{s'}{s} \frac{d - s}{d}

    Args:
        depth: distances d > 0, any shape, NumPy array or torch tensor (same unit as the lens).
        lens: the thin lens.
        clamp: clamp |r| to ``lens.max_coc_radius``.

    Returns:
        r in pixels, same type, shape, dtype and device as ``depth``.

    Raises:
        ParameterError: depth with NaN, inf, zero or negative values.

    >>> lens = ThinLens(4.0, 5.0, 6.0)
    >>> float(coc_radius(np.array([6.0]), lens)[0])
    0.0
    """
    validate_depth(depth)
    radius = lens.coc_scale * (depth - lens.focus_distance) / depth
    if clamp:
        limit = lens.max_coc_radius
        radius = radius.clamp(-limit, limit) if isinstance(radius, torch.Tensor) else np.clip(
            radius, -limit, limit
        )
    return radius


#: The paper's five camera parameter sets {f, F, s} (Sec. 5), in order: the lens sets
#: ``set0``..``set4``; distortion presets match by index.
PAPER_LENS_SETS: dict[str, ThinLens] = {
    lens.name: lens
    for lens in (
        ThinLens(4, 5, 6, name="set0"),
        ThinLens(5, 8, 6, name="set1"),
        ThinLens(7, 5, 8, name="set2"),
        ThinLens(10, 13, 12, name="set3"),
        ThinLens(22, 10, 30, name="set4"),
    )
}


@dataclass(frozen=True)
class DefocusProfile:
    """A blur distribution relative to the frame, for any scene scale (ours, not the paper's).

    The paper's camera sets fix the CoC in pixels whatever the frame size, so a small frame gets
    a blur far larger, relative to its content, than a photograph has. A profile instead says how
    large the CoC is at a reference frame width: per sequence it draws the CoC radius of a point
    at infinity, ``|r_inf|``, log-uniformly from ``infinity_coc`` (px at ``reference_width``),
    scales it by ``width / reference_width`` and builds the thin lens of Eq. 1 that focuses
    at the given distance and gives that CoC (r = r_inf (d - s) / d). ``max_coc_radius`` (px at the
    reference width) clamps near, strongly defocused surfaces.

    >>> lens = DEFOCUS_PROFILES["dslr-840"].lens(np.random.default_rng(0), 2.0, 840)
    >>> round(float(coc_radius(np.array([2.0]), lens)[0]), 6)
    0.0
    """

    name: str
    reference_width: int
    infinity_coc: tuple[float, float]
    max_coc_radius: float
    description: str = ""
    # False: the CoC is the same in pixels for any frame width (frames that are crops of a
    # ``reference_width``-wide photograph).
    scale_with_width: bool = True

    def __post_init__(self) -> None:
        check_range("reference_width", self.reference_width, 1)
        low, high = self.infinity_coc
        check_range("infinity_coc low", low, 0.0, low_inclusive=False)
        check_range("infinity_coc high", high, low)
        check_range("max_coc_radius", self.max_coc_radius, 0.0, low_inclusive=False)

    def camera(self, rng: np.random.Generator, focus_distance: float, width: int) -> ThinLens:
        """Old name of :meth:`lens` (until release 0.3)."""
        from dualpixel.names import warn_renamed

        warn_renamed("DefocusProfile.camera()", "DefocusProfile.lens()", stacklevel=2)
        return self.lens(rng, focus_distance, width)

    def lens(self, rng: np.random.Generator, focus_distance: float, width: int) -> ThinLens:
        """The lens of one sequence: focused at ``focus_distance``, frame ``width`` px wide."""
        check_range("focus_distance", focus_distance, 0.0, low_inclusive=False)
        check_range("width", width, 1)
        low, high = self.infinity_coc
        scale = width / self.reference_width if self.scale_with_width else 1.0
        r_inf = float(np.exp(rng.uniform(np.log(low), np.log(high)))) * scale
        focal_length = min(0.05, 0.5 * float(focus_distance))  # any f < s: the pitch absorbs it
        f_number = 2.0
        lens = ThinLens(focal_length, f_number, float(focus_distance), pixel_pitch=1.0)
        return ThinLens(
            focal_length, f_number, float(focus_distance),
            pixel_pitch=lens.coc_scale / r_inf,
            max_coc_radius=self.max_coc_radius * scale,
            name=self.name,
        )


#: Where a defocus profile focuses when the scene does not say (depth percentile): the middle of
#: the 10..50 that dataset synthesis draws per sequence (ours; the paper's sets fix the focus).
FOCUS_PERCENTILE = 30.0


def focus_from_depth(depth: np.ndarray, percentile: float = FOCUS_PERCENTILE) -> float:
    """Focus distance (m) for a defocus profile: the ``percentile`` of a depth map (m, any
    shape), so that the nearer part of the scene is sharp and what lies behind it blurs.

    >>> focus_from_depth(np.array([1.0, 2.0, 3.0, 4.0, 5.0]), 50)
    3.0
    """
    check_range("percentile", percentile, 0.0, 100.0)
    return float(np.percentile(depth, percentile))


#: Defocus profiles. "dslr-840": a full-frame DSLR with a fast lens at a half-resolution DPDD frame
#: (840 px wide; the Canon EOS 5D Mark IV of the DPDD benchmark): backgrounds far behind the
#: subject blur by 3-20 px radius, near occluders by up to 30 px; "dslr-840-mild": 2-12 px, 20 px;
#: "dslr-1680-crop": dslr-840's blur at full resolution (6-40 px, 60 px) in frames of any width;
#: "phone-2016-crop": a phone's main camera at the size of its DP data (the Google Pixel 4's
#: green-channel DP frame, 2016 px wide): 1-12 px, 16 px, in frames of any width;
#: "phone-2016-close": the same phone focused close (a subject a hand's breadth away), so that
#: backgrounds blur twice as much: 2-24 px, 32 px.
DEFOCUS_PROFILES: dict[str, DefocusProfile] = {
    profile.name: profile
    for profile in (
        DefocusProfile("dslr-840", 840, (3.0, 20.0), 30.0,
                       "DSLR, fast lens, 840-px-wide frame (half-resolution DPDD)"),
        DefocusProfile("dslr-840-mild", 840, (2.0, 12.0), 20.0,
                       "as dslr-840 without its heavy tail: the shipped data measured about "
                       "0.75 px blurrier than real DPDD photographs at every percentile"),
        DefocusProfile("dslr-1680-crop", 1680, (6.0, 40.0), 60.0,
                       "dslr-840 at full resolution (1680 px wide, twice the blur in pixels), "
                       "for frames that are crops of such a photograph: the CoC does not scale "
                       "with the frame width", scale_with_width=False),
        DefocusProfile("phone-2016-crop", 2016, (1.0, 12.0), 16.0,
                       "phone main camera (f/1.7, small pixels: DP disparity of a few px) at "
                       "the size of its DP data, 2016 px wide (Google Pixel 4; its measured "
                       "PSFs have a 10-px radius), for frames that are crops of such a capture",
                       scale_with_width=False),
        DefocusProfile("phone-2016-close", 2016, (2.0, 24.0), 32.0,
                       "phone-2016-crop focused close (a subject 10-30 cm away): backgrounds "
                       "blur twice as much, for frames that are crops of such a capture",
                       scale_with_width=False),
    )
}


#: Old names (until release 0.3): "camera" now names a calibrated camera file alone.
RENAMED_LENS_NAMES = {"ThinLensCamera": "ThinLens", "CAMERA_PRESETS": "PAPER_LENS_SETS"}
__getattr__ = renamed_attributes(__name__, RENAMED_LENS_NAMES, globals())
