"""Calibration targets to show on a display (supplement S1, Fig. S1-A, and S3, Fig. S3-A).

* :func:`disk_grid_pattern`: white disks of equal radius on black, on a regular grid. The radius is
  a known fraction of the spacing, so the sharp disk can be re-drawn at the scale of a capture.
* :func:`square_grid_pattern`: a uniform grid of black squares on white, for radial distortion.

Both are anti-aliased (each pixel integrated over ``SUPERSAMPLING`` x ``SUPERSAMPLING`` samples)
and returned as float32 ``(H, W)`` images in [0, 1].
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dualpixel.errors import ParameterError
from dualpixel.memory import require_memory

__all__ = ["DiskGrid", "disk_grid_pattern", "render_disk", "square_grid_pattern"]

SUPERSAMPLING = 8


@dataclass(frozen=True)
class DiskGrid:
    """Geometry of the disk pattern: image size, centre spacing and disk radius / spacing."""

    width: int = 1920
    height: int = 1080
    spacing: int = 60
    radius_fraction: float = 0.1

    def __post_init__(self) -> None:
        if not 0 < self.radius_fraction < 0.5:
            raise ParameterError(f"radius_fraction must be in (0, 0.5), got {self.radius_fraction}")
        if self.spacing < 8 or self.spacing > min(self.width, self.height):
            raise ParameterError(f"spacing {self.spacing} does not fit a "
                                 f"{self.width}x{self.height} pattern")

    @property
    def radius(self) -> float:
        return self.radius_fraction * self.spacing

    def centres(self) -> np.ndarray:
        """Disk centres ``(N, 2)`` as (x, y), row-major, the grid centred in the image."""
        cols, rows = self.width // self.spacing, self.height // self.spacing
        x0 = (self.width - (cols - 1) * self.spacing - 1) / 2
        y0 = (self.height - (rows - 1) * self.spacing - 1) / 2
        ys, xs = np.mgrid[:rows, :cols]
        return np.stack([x0 + xs.ravel() * self.spacing, y0 + ys.ravel() * self.spacing], axis=1)


def render_disk(size: int, centre: tuple[float, float], radius: float) -> np.ndarray:
    """An anti-aliased disk of ``radius`` at sub-pixel ``centre`` (x, y) in a ``size`` square."""
    ss = SUPERSAMPLING
    axis = (np.arange(size * ss) + 0.5) / ss - 0.5
    dy = axis[:, None] - centre[1]
    dx = axis[None, :] - centre[0]
    inside = (dx * dx + dy * dy <= radius * radius).astype(np.float32)
    return inside.reshape(size, ss, size, ss).mean(axis=(1, 3))


def _require_pattern_memory(width: int, height: int) -> None:
    # the float32 image, its 3-channel copy and the 8-bit output: about 20 bytes per pixel
    require_memory(20.0 * width * height, f"a {width}x{height} pattern")


def disk_grid_pattern(grid: DiskGrid) -> np.ndarray:
    """The disk-grid target: white disks on black."""
    _require_pattern_memory(grid.width, grid.height)
    image = np.zeros((grid.height, grid.width), np.float32)
    half = int(np.ceil(grid.radius)) + 2
    size = 2 * half + 1
    for x, y in grid.centres():
        ix, iy = round(x), round(y)
        disk = render_disk(size, (half + x - ix, half + y - iy), grid.radius)
        image[iy - half : iy + half + 1, ix - half : ix + half + 1] += disk
    return np.clip(image, 0, 1)


def square_grid_pattern(width: int = 1920, height: int = 1080, *, square: int = 20,
                        spacing: int = 40) -> np.ndarray:
    """The distortion target: black ``square``-pixel squares every ``spacing`` pixels on white,
    centred in the image."""
    if not 0 < square < spacing:
        raise ParameterError(f"need 0 < square < spacing, got {square} and {spacing}")
    _require_pattern_memory(width, height)
    ss = SUPERSAMPLING

    def coverage(length: int) -> np.ndarray:
        samples = (np.arange(length * ss) + 0.5) / ss - (length - 1) / 2  # centred coordinates
        phase = np.mod(samples + square / 2, spacing)
        return (phase < square).reshape(length, ss).mean(axis=1)

    return (1.0 - np.outer(coverage(height), coverage(width))).astype(np.float32)
