"""dualpixel: dual-pixel defocus deblurring.

Implements Abuolaim, Delbracio, Kelly, Brown and Milanfar, "Learning to Reduce Defocus Blur by
Realistically Modeling Dual-Pixel Data", ICCV 2021: DP data synthesis (``dualpixel.optics``,
``dualpixel.synthesis``), deblurring networks and calibration.

The top level is what a notebook needs (arrays: NumPy ``(H, W, 3)`` or torch ``(3, H, W)`` /
``(B, 3, H, W)``, float in [0, 1] or integer images; see :mod:`dualpixel.api`)::

    import dualpixel
    frame = dualpixel.synthesize(rgb, depth, lens_set="dslr-840")
    sharp = dualpixel.deblur(frame["left"], frame["right"])       # the shipped rdpd-light
    dualpixel.psnr(sharp, frame["target"])
    dualpixel.list_models()

Attributes are imported on first use, so ``import dualpixel`` stays light.
"""

from __future__ import annotations

import importlib
from typing import Any

__version__ = "0.1.0"

_EXPORTS = {
    "check_views": "dualpixel.api",
    "deblur": "dualpixel.api",
    "synthesize": "dualpixel.api",
    "load_model": "dualpixel.api",
    "list_models": "dualpixel.weights",
    "psnr": "dualpixel.evaluation.metrics",
    "ssim": "dualpixel.evaluation.metrics",
    "mae": "dualpixel.evaluation.metrics",
    "niqe": "dualpixel.evaluation.niqe",
}

__all__ = ["__version__", "check_views", "deblur", "list_models", "load_model", "mae", "niqe",
           "psnr", "ssim", "synthesize"]


def __getattr__(name: str) -> Any:
    if name in _EXPORTS:
        return getattr(importlib.import_module(_EXPORTS[name]), name)
    raise AttributeError(f"module 'dualpixel' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(__all__)
