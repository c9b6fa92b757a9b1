"""Fitting division-model radial distortion to a capture of the square grid (supplement S3).

Searches ``(c1, c2, c3)`` maximising the normalised cross-correlation between the capture
``I_f`` and the pattern warped by the model ``I_d(c1, c2, c3)`` (Eq. S3), coarse to fine instead of
a blind triple loop: a 1-D scan of ``c1`` (the dominant term), then a local 3x3x3 grid around
the best point, climbed until its centre wins, whose step halves at every level. Both images are
compared at a reduced working resolution and lightly blurred so that the correlation varies
smoothly with the coefficients; the coefficients are resolution independent (R is normalised by
the half-diagonal). The capture must be centred on the pattern (the supplement re-centres
manually) and have its aspect ratio.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
import torch

from dualpixel.errors import ParameterError, check_range
from dualpixel.optics.distortion import DivisionDistortion, distort_image

__all__ = ["DistortionFit", "fit_distortion"]


@dataclass
class DistortionFit:
    distortion: DivisionDistortion
    correlation: float
    evaluations: int


def _prepare(image: np.ndarray, width: int, blur: float) -> np.ndarray:
    image = np.asarray(image, np.float32)
    if image.ndim == 3:
        image = image.mean(axis=2)
    height = max(8, round(image.shape[0] * width / image.shape[1]))
    small = cv2.resize(image, (width, height), interpolation=cv2.INTER_AREA)
    return cv2.GaussianBlur(small, (0, 0), blur) if blur > 0 else small


def _ncc(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    a = a - a.mean(dim=(-2, -1), keepdim=True)
    b = b - b.mean(dim=(-2, -1), keepdim=True)
    return (a * b).sum(dim=(-2, -1)) / torch.sqrt((a * a).sum(dim=(-2, -1)) *
                                                  (b * b).sum(dim=(-2, -1)))


#: Below this normalised cross-correlation the capture is not taken to show the pattern.
MIN_CORRELATION = 0.3


def fit_distortion(
    capture: np.ndarray,
    pattern: np.ndarray,
    *,
    working_width: int = 480,
    blur: float = 1.0,
    c1_range: tuple[float, float] = (-0.1, 0.1),
    levels: int = 6,
    initial_step: float = 0.01,
    progress: bool = False,
) -> DistortionFit:
    """Estimate division-model coefficients from an in-focus capture of ``pattern``.

    Args:
        capture: the captured pattern (grey or RGB), centred, same aspect ratio as ``pattern``.
        pattern: the undistorted pattern that was displayed.
        working_width: width both are resized to for the search.
        blur: Gaussian sigma (working pixels) applied to both.
        c1_range: range of the initial 1-D ``c1`` scan (41 values).
        levels: refinement levels of the local 3-D search (steps halve each level).
        initial_step: step of the first local level.
        progress: show a progress bar (one step per search level, with the correlation).
    """
    from dualpixel.progress import progress_bar

    check_range("working_width", working_width, 16)
    check_range("blur", blur, 0.0)
    if abs(capture.shape[0] / capture.shape[1] - pattern.shape[0] / pattern.shape[1]) > 0.01:
        raise ParameterError(f"capture {capture.shape[:2]} and pattern {pattern.shape[:2]} differ "
                             "in aspect ratio; crop the capture to the pattern first")
    target = torch.from_numpy(_prepare(capture, working_width, 0.0))
    source = torch.from_numpy(_prepare(pattern, working_width, 0.0))[None]
    blur_t = lambda t: torch.from_numpy(cv2.GaussianBlur(t.numpy(), (0, 0), blur))  # noqa: E731
    target = blur_t(target) if blur > 0 else target
    cache: dict[tuple[float, float, float], float] = {}

    def score(coefficients: tuple[float, float, float]) -> float:
        key = tuple(round(c, 9) for c in coefficients)
        if key not in cache:
            distortion = DivisionDistortion(*key)
            try:
                warped = distort_image(source, distortion)[0]
            except ParameterError:  # folds the image: not a valid lens
                cache[key] = -np.inf
            else:
                warped = blur_t(warped) if blur > 0 else warped
                cache[key] = float(_ncc(warped, target))
        return cache[key]

    bar = progress_bar(total=levels + 1, desc="fitting distortion", unit="level", enabled=progress)
    best = max(((c1, 0.0, 0.0) for c1 in np.linspace(*c1_range, 41)), key=score)
    bar.update()
    step = initial_step
    for _ in range(levels):
        moved = True
        while moved:  # climb at this step size until the centre is the best of its neighbours
            candidates = [tuple(b + step * (o - 1) for b, o in zip(best, d))
                          for d in np.ndindex(3, 3, 3)]
            new_best = max(candidates, key=score)
            moved = score(new_best) > score(best) + 1e-12
            best = new_best if moved else best
        step /= 2
        bar.set_postfix(correlation=f"{score(best):.4f}", evaluations=len(cache))
        bar.update()
    bar.close()
    if not np.isfinite(score(best)) or score(best) < MIN_CORRELATION:
        raise ParameterError(
            f"the capture does not match the pattern (best correlation {score(best):.3g} < "
            f"{MIN_CORRELATION}); capture the square pattern in focus, centred and cropped to it"
        )
    return DistortionFit(DivisionDistortion(*best, name="fitted"), score(best), len(cache))
