"""Calibration (supplement S1-S3): patterns, DP PSF estimation, PSF model fit, distortion fit,
and the camera's DP blur from real pairs, with sharp targets (:mod:`dualpixel.calibration.camera`)
or from the two views alone (:mod:`dualpixel.calibration.target_free`).

Names are imported on first use, so ``import dualpixel.calibration.camera`` (what ``synth
--camera`` needs) does not pay for SciPy's signal and optimisation modules.
"""

from __future__ import annotations

import importlib
from typing import Any

_EXPORTS = {
    "DistortionFit": "distortion_fit",
    "fit_distortion": "distortion_fit",
    "DiskGrid": "patterns",
    "disk_grid_pattern": "patterns",
    "render_disk": "patterns",
    "square_grid_pattern": "patterns",
    "PSFEstimate": "psf_estimation",
    "estimate_psfs": "psf_estimation",
    "locate_disks": "psf_estimation",
    "PAPER_SEARCH_GRID": "psf_fit",
    "PSFFit": "psf_fit",
    "SearchGrid": "psf_fit",
    "fit_psf_models": "psf_fit",
    "psf_correlation": "psf_fit",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    if name in _EXPORTS:
        return getattr(importlib.import_module(f"{__name__}.{_EXPORTS[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(__all__)
