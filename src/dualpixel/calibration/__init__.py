"""Calibration (supplement S1-S3): patterns, DP PSF estimation, PSF model fit, distortion fit."""

from dualpixel.calibration.distortion_fit import DistortionFit, fit_distortion
from dualpixel.calibration.patterns import (
    DiskGrid,
    disk_grid_pattern,
    render_disk,
    square_grid_pattern,
)
from dualpixel.calibration.psf_estimation import PSFEstimate, estimate_psfs, locate_disks
from dualpixel.calibration.psf_fit import (
    PAPER_SEARCH_GRID,
    PSFFit,
    SearchGrid,
    fit_psf_models,
    psf_correlation,
)

__all__ = [
    "PAPER_SEARCH_GRID",
    "DiskGrid",
    "DistortionFit",
    "PSFEstimate",
    "PSFFit",
    "SearchGrid",
    "disk_grid_pattern",
    "estimate_psfs",
    "fit_distortion",
    "fit_psf_models",
    "locate_disks",
    "psf_correlation",
    "render_disk",
    "square_grid_pattern",
]
