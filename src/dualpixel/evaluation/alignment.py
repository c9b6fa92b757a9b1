"""Registering an output to its target before scoring (``dualpixel eval --align``).

Real DP pairs are two captures (the blurred one at a wide aperture, the target at f/22), and the
camera moves between them by a fraction of a pixel: on the Canon dev scenes at 1620x980 the views'
sum lies 0.2-0.8 px (median per scene) from its target, with up to 0.3 % scale between the two.
Every method's output inherits its input's misregistration, and PSNR charges it to the method,
more the sharper the output. As RealBlur's evaluation does (Rim et al., ECCV 2020), the output is
warped onto the target by the translation or affine map that maximises their enhanced
correlation coefficient (OpenCV's ECC on the grey images), and the border the warp leaves
undefined is cropped from both before the metrics.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from dualpixel.errors import ParameterError
from dualpixel.names import ALIGN_MODE_NAMES

__all__ = ["ALIGN_MODES", "AlignedPair", "AlignmentError", "align_to_target", "check_align_mode"]

#: ``--align`` choices and OpenCV's motion models.
ALIGN_MODES = dict(zip(ALIGN_MODE_NAMES, (cv2.MOTION_TRANSLATION, cv2.MOTION_AFFINE),
                       strict=True))


class AlignmentError(ParameterError):
    """ECC found no registration (images without common structure, or not converging)."""


@dataclass(frozen=True)
class AlignedPair:
    """The output warped onto the target and the target, both cropped by ``margin`` px on each
    side (float32 ``(H - 2 margin, W - 2 margin, 3)``); ``warp`` (2x3) maps target pixel
    coordinates to the output's."""

    prediction: np.ndarray
    target: np.ndarray
    warp: np.ndarray
    margin: int


def check_align_mode(mode: str) -> str:
    """``mode`` if it names a registration of :data:`ALIGN_MODES`, else a ParameterError."""
    if mode not in ALIGN_MODES:
        raise ParameterError(f"align mode must be one of {', '.join(ALIGN_MODES)}, got {mode!r}")
    return mode


def _grey(image: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(np.asarray(image, np.float32).mean(axis=-1))


def align_to_target(prediction: np.ndarray, target: np.ndarray, mode: str = "affine", *,
                    iterations: int = 100, tolerance: float = 1e-6) -> AlignedPair:
    """Register ``prediction`` onto ``target`` (float ``(H, W, 3)`` in [0, 1], one size) by the
    ``mode`` ("translation" or "affine") map of ECC, warp it (bicubic) and crop the border the
    warp does not cover, plus one pixel.

    Raises:
        ParameterError: unknown mode or mismatched sizes.
        AlignmentError: ECC did not converge.
    """
    check_align_mode(mode)
    prediction = np.asarray(prediction, np.float32)
    target = np.asarray(target, np.float32)
    if prediction.shape != target.shape or prediction.ndim != 3:
        raise ParameterError(f"prediction {prediction.shape} and target {target.shape} must be "
                             "(H, W, C) of one size")
    warp = np.eye(2, 3, dtype=np.float32)
    criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, iterations, tolerance)
    try:
        _, warp = cv2.findTransformECC(_grey(target), _grey(prediction), warp, ALIGN_MODES[mode],
                                       criteria, None, 5)
    except cv2.error as error:
        raise AlignmentError(f"no {mode} registration found: "
                             f"{str(error).strip().splitlines()[-1]}") from None
    height, width = target.shape[:2]
    corners = np.array([[0, 0, 1], [width - 1, 0, 1], [0, height - 1, 1],
                        [width - 1, height - 1, 1]], np.float64)
    moved = corners @ warp.T.astype(np.float64) - corners[:, :2]
    margin = math.ceil(float(np.abs(moved).max())) + 1
    if 2 * margin >= min(height, width):
        raise AlignmentError(f"the {mode} registration moves the image by {margin} px or more")
    warped = cv2.warpAffine(prediction, warp, (width, height),
                            flags=cv2.INTER_CUBIC | cv2.WARP_INVERSE_MAP,
                            borderMode=cv2.BORDER_REFLECT)
    inner = (slice(margin, height - margin), slice(margin, width - margin))
    return AlignedPair(np.clip(warped[inner], 0.0, 1.0), target[inner], warp, margin)
