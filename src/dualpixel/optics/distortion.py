"""Radial lens distortion with the division model (paper Sec. 2.3 and supplement S3, Eq. 5).

.. math:: p_d = p_o + \\frac{p_u - p_o}{1 + c_1 R^2 + c_2 R^4 + c_3 R^6}

Which radius: ``R = |p_u - p_o| / h`` is the **undistorted** radius, normalised by the image's
half-diagonal ``h = sqrt(W^2 + H^2) / 2``, so the equation maps undistorted to distorted points
explicitly. ``p_o`` is the image centre ``((W - 1) / 2, (H - 1) / 2)`` in pixel coordinates
(x = column, y = row, pixel centres at integers). Positive coefficients pull points inwards
(barrel), negative push them outwards (pincushion).

Images are warped backwards: each output (distorted) pixel looks up its undistorted source
position, found by Newton's method on the radius, and samples it bilinearly with
``torch.nn.functional.grid_sample``.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass

import torch
import torch.nn.functional as F

from dualpixel.errors import ParameterError

__all__ = [
    "DISTORTION_PRESETS",
    "DivisionDistortion",
    "distort_image",
    "distort_points",
    "distort_window",
    "undistort_points",
    "window_sources",
]


@dataclass(frozen=True)
class DivisionDistortion:
    """Coefficients (c1, c2, c3) of the division model on the half-diagonal-normalised radius."""

    c1: float = 0.0
    c2: float = 0.0
    c3: float = 0.0
    name: str = "custom"

    @property
    def coefficients(self) -> tuple[float, float, float]:
        return (float(self.c1), float(self.c2), float(self.c3))

    def denominator(self, radius_u: torch.Tensor) -> torch.Tensor:
        """1 + c1 R^2 + c2 R^4 + c3 R^6 at undistorted radii R."""
        r2 = radius_u * radius_u
        return 1.0 + r2 * (self.c1 + r2 * (self.c2 + r2 * self.c3))

    def distorted_radius(self, radius_u: torch.Tensor) -> torch.Tensor:
        """R_d = R_u / (1 + c1 R_u^2 + c2 R_u^4 + c3 R_u^6)."""
        return radius_u / self.denominator(radius_u)

    def undistorted_radius(self, radius_d: torch.Tensor, iterations: int = 30) -> torch.Tensor:
        """Invert :meth:`distorted_radius` by Newton's method (monotone over the image)."""
        c1, c2, c3 = self.coefficients
        radius_u = radius_d.clone()
        for _ in range(iterations):
            r2 = radius_u * radius_u
            den = 1.0 + r2 * (c1 + r2 * (c2 + r2 * c3))
            dden = radius_u * (2 * c1 + r2 * (4 * c2 + r2 * 6 * c3))
            value = radius_u / den - radius_d
            slope = (den - radius_u * dden) / (den * den)
            radius_u = radius_u - value / slope
        return radius_u

    def check_monotone(self, max_radius: float) -> None:
        """Raise :class:`ParameterError` if R_u -> R_d is not invertible on [0, max_radius]."""
        radius = torch.linspace(0.0, max_radius, 2049, dtype=torch.float64)
        r2 = radius * radius
        # d/dR [R / p(R)] > 0  <=>  p(R) - R p'(R) > 0
        slope = 1.0 - r2 * (self.c1 + r2 * (3 * self.c2 + r2 * 5 * self.c3))
        den = self.denominator(radius)
        if bool((slope <= 0).any()) or bool((den <= 0).any()):
            raise ParameterError(
                f"distortion coefficients {self.coefficients} fold the image over itself within "
                f"radius {max_radius:g}; choose smaller magnitudes"
            )


def _centre_and_scale(width: int, height: int) -> tuple[float, float, float]:
    return (width - 1) / 2.0, (height - 1) / 2.0, 0.5 * (width**2 + height**2) ** 0.5


def _polar(points: torch.Tensor, width: int, height: int):
    """(centre, offset from it, half-diagonal-normalised radius) of pixel coordinates."""
    cx, cy, half_diag = _centre_and_scale(width, height)
    centre = points.new_tensor([cx, cy])
    offset = points - centre
    return centre, offset, offset.norm(dim=-1, keepdim=True) / half_diag


def distort_points(
    points: torch.Tensor, distortion: DivisionDistortion, width: int, height: int
) -> torch.Tensor:
    """Map undistorted pixel coordinates ``(..., 2)`` (x, y) to distorted ones (Eq. 5)."""
    centre, offset, radius_u = _polar(points, width, height)
    return centre + offset / distortion.denominator(radius_u)


def undistort_points(
    points: torch.Tensor, distortion: DivisionDistortion, width: int, height: int
) -> torch.Tensor:
    """Map distorted pixel coordinates ``(..., 2)`` back to undistorted ones (inverse of Eq. 5)."""
    centre, offset, radius_d = _polar(points, width, height)
    radius_u = distortion.undistorted_radius(radius_d)
    scale = torch.where(radius_d > 0, radius_u / radius_d.clamp_min(1e-30), 1.0)
    return centre + offset * scale


# the five presets and one more, at two frame sizes, in the four variants a process rendering
# on a GPU asks for (float32 and float64, on the CPU and on the GPU)
@functools.lru_cache(maxsize=48)
def _sampling_grid(distortion: DivisionDistortion, width: int, height: int, dtype: torch.dtype,
                   device: torch.device) -> torch.Tensor:
    """``grid_sample``'s ``(H, W, 2)`` grid of the undistorted source of every output pixel, in
    ``dtype``. Cached: a dataset's frames share their size and their sequence's distortion, and
    the Newton inversion over every pixel costs several times the warp itself."""
    distortion.check_monotone(1.0 + 1e-6)
    work_dtype = torch.float64 if dtype == torch.float64 else torch.float32
    # a plain tensor even when first asked for under inference mode: a later call that records
    # gradients saves the grid for backward
    with torch.inference_mode(False), torch.no_grad():
        ys = torch.arange(height, dtype=work_dtype, device=device)
        xs = torch.arange(width, dtype=work_dtype, device=device)
        grid_y, grid_x = torch.meshgrid(ys, xs, indexing="ij")
        points = torch.stack((grid_x, grid_y), dim=-1)
        source = undistort_points(points, distortion, width, height)
        # grid_sample with align_corners=True maps -1 / +1 to the centres of the edge pixels.
        norm = source.new_tensor([2.0 / max(width - 1, 1), 2.0 / max(height - 1, 1)])
        return (source * norm - 1.0).to(dtype)


def distort_image(
    image: torch.Tensor,
    distortion: DivisionDistortion,
    *,
    padding_mode: str = "border",
    mode: str = "bilinear",
) -> torch.Tensor:
    """Apply radial distortion to images by backward warping.

    Args:
        image: ``(C, H, W)`` or ``(B, C, H, W)`` float tensor, any size.
        distortion: division-model coefficients.
        padding_mode: what a source position outside the frame reads ("border", "zeros",
            "reflection"); barrel distortion looks outside the frame near the corners.
        mode: "bilinear" (default) or "nearest" (for label-like maps).

    Returns:
        The distorted image(s), same shape, dtype and device.
    """
    if image.ndim not in (3, 4):
        raise ParameterError(
            f"image must be (C, H, W) or (B, C, H, W), got shape {tuple(image.shape)}"
        )
    batched = image if image.ndim == 4 else image[None]
    height, width = batched.shape[-2:]
    grid = _sampling_grid(distortion, width, height, batched.dtype, image.device)
    grid = grid[None].expand(batched.shape[0], -1, -1, -1)
    out = F.grid_sample(batched, grid, mode=mode, padding_mode=padding_mode, align_corners=True)
    return out if image.ndim == 4 else out[0]


def window_sources(distortion: DivisionDistortion, frame_size: tuple[int, int],
                   window: tuple[int, int, int, int]) -> tuple[int, int, int, int]:
    """Half-open ``(row0, row1, col0, col1)`` of the undistorted frame (``frame_size``
    ``(H, W)``) that :func:`distort_window` reads for ``window`` ``(top, left, height, width)``
    of the distorted one: every source position with its bilinear neighbours, clipped to the
    frame."""
    height, width = frame_size
    top, left, rows, cols = window
    grid = _sampling_grid(distortion, width, height, torch.float64, torch.device("cpu"))
    part = grid[top : top + rows, left : left + cols]
    x = (part[..., 0] + 1.0) * (width - 1) / 2.0
    y = (part[..., 1] + 1.0) * (height - 1) / 2.0
    return (max(int(torch.floor(y.min())) - 1, 0), min(int(torch.ceil(y.max())) + 2, height),
            max(int(torch.floor(x.min())) - 1, 0), min(int(torch.ceil(x.max())) + 2, width))


def distort_window(
    image: torch.Tensor,
    distortion: DivisionDistortion,
    frame_size: tuple[int, int],
    origin: tuple[int, int],
    window: tuple[int, int, int, int],
    *,
    padding_mode: str = "border",
    mode: str = "bilinear",
) -> torch.Tensor:
    """``window`` ``(top, left, height, width)`` of :func:`distort_image` of a whole frame of
    ``frame_size`` ``(H, W)``, from ``image`` ``(C, h, w)``: the region of the undistorted frame
    whose top-left pixel is ``origin`` ``(row, col)`` and that holds :func:`window_sources`
    (a training crop rendered on the fly). Equal to that window of the whole frame's warp to
    float rounding (the positions are mapped in float64)."""
    height, width = frame_size
    top, left, rows, cols = window
    row0, col0 = origin
    region_h, region_w = image.shape[-2:]
    need = window_sources(distortion, frame_size, window)
    if need[0] < row0 or need[1] > row0 + region_h or need[2] < col0 or need[3] > col0 + region_w:
        raise ParameterError(f"the region {region_w}x{region_h} from ({col0}, {row0}) does not "
                             f"hold the window's sources (rows {need[0]}-{need[1]}, columns "
                             f"{need[2]}-{need[3]})")
    grid = _sampling_grid(distortion, width, height, torch.float64, image.device)
    part = grid[top : top + rows, left : left + cols]
    x = (part[..., 0] + 1.0) * (width - 1) / 2.0 - col0
    y = (part[..., 1] + 1.0) * (height - 1) / 2.0 - row0
    local = torch.stack((x * 2.0 / max(region_w - 1, 1) - 1.0,
                         y * 2.0 / max(region_h - 1, 1) - 1.0), dim=-1)
    out = F.grid_sample(image[None], local[None].to(image.dtype), mode=mode,
                        padding_mode=padding_mode, align_corners=True)
    return out[0]


def _presets(sets: Sequence[tuple[float, float, float]]) -> dict[str, DivisionDistortion]:
    return {f"set{i}": DivisionDistortion(*c, name=f"set{i}") for i, c in enumerate(sets)}


#: The supplement's five coefficient sets (S3), matched by index to the camera presets set0..set4.
DISTORTION_PRESETS: dict[str, DivisionDistortion] = _presets(
    [
        (2e-2, 2e-2, 3e-2),
        (8e-3, 2e-3, 2.2e-3),
        (-4e-3, 9e-4, -9e-4),
        (-7e-3, -3.8e-3, -3.6e-3),
        (-8e-3, -5e-3, -4.5e-3),
    ]
)
