"""Optics of dual-pixel image formation (paper Sec. 2): thin lens, DP PSFs, distortion, noise."""

from dualpixel.names import renamed_attributes
from dualpixel.optics.distortion import (
    DISTORTION_PRESETS,
    DivisionDistortion,
    distort_image,
    distort_points,
    undistort_points,
)
from dualpixel.optics.noise import PAPER_NOISE_SIGMAS, add_noise, sample_noise_sigma
from dualpixel.optics.psf import (
    PSF_MODELS,
    DPKernels,
    PSFParams,
    dp_psf,
    kernel_size,
)
from dualpixel.optics.psf_bank import (
    BROAD_PSF_BANK,
    PAPER_PSF_BANK,
    PIXEL4_PSF_BANK,
    PSF_BANKS,
    PSFBank,
)
from dualpixel.optics.thin_lens import (
    DEFOCUS_PROFILES,
    PAPER_LENS_SETS,
    RENAMED_LENS_NAMES,
    DefocusProfile,
    ThinLens,
    coc_radius,
)

__all__ = [
    "BROAD_PSF_BANK",
    "DEFOCUS_PROFILES",
    "DISTORTION_PRESETS",
    "PAPER_LENS_SETS",
    "PAPER_NOISE_SIGMAS",
    "PAPER_PSF_BANK",
    "PIXEL4_PSF_BANK",
    "PSF_BANKS",
    "PSF_MODELS",
    "DPKernels",
    "DefocusProfile",
    "DivisionDistortion",
    "PSFBank",
    "PSFParams",
    "ThinLens",
    "add_noise",
    "coc_radius",
    "distort_image",
    "distort_points",
    "dp_psf",
    "kernel_size",
    "sample_noise_sigma",
    "undistort_points",
]


__getattr__ = renamed_attributes(__name__, RENAMED_LENS_NAMES, globals())
