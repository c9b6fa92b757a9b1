"""DP view crosstalk: how much of its disparity a camera's views keep, per colour channel (ours).

The paper's model (Eq. 2-4) splits each PSF into two views whose centroids lie a fixed distance
apart for a given blur. Real sensors keep less of that separation, and less in red than in green
(light of longer wavelength is absorbed deeper in the silicon, below the split photodiodes). We
model it as crosstalk between the two photodiodes under one microlens::

    L' = (1 + a) / 2 * L + (1 - a) / 2 * R,    R' = (1 + a) / 2 * R + (1 - a) / 2 * L

per channel, with ``a`` the camera's *disparity ratio*: the views' centroids then lie ``a`` times
as far apart as the model's, the combined image ``L' + R' = L + R`` (so the blur) is unchanged,
and ``a = 1`` is the paper's model. ``dualpixel calibrate camera`` measures ``a`` per channel from
real DP pairs (:mod:`dualpixel.calibration.camera`).

Real views keep more of it in the middle of the frame than at its left and right sides (the
split photodiodes see the exit pupil from another angle there; ``docs/formation.md``): with a
*disparity falloff* ``f`` the ratio at horizontal position ``x`` (-1 at the left edge, 1 at the
right) is ``a (1 - f x^2) / (1 - f / 3)``, whose mean over the width stays ``a``.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch

from dualpixel.errors import ParameterError, check_range

__all__ = ["apply_crosstalk", "check_disparity_falloff", "check_disparity_ratio", "field_ratio"]


def check_disparity_ratio(ratio: Sequence[float], channels: int = 3) -> tuple[float, ...]:
    """The ratios as a tuple of ``channels`` finite floats in [0, 1.5], or a clear error."""
    values = tuple(check_range(f"disparity_ratio[{i}]", v) for i, v in enumerate(ratio))
    if len(values) != channels:
        raise ParameterError(f"disparity_ratio needs one value per channel ({channels}), "
                             f"got {len(values)}")
    if not all(0.0 <= v <= 1.5 for v in values):  # NaN fails the comparison too
        raise ParameterError(f"disparity_ratio values must be in [0, 1.5], got {list(values)}")
    return values


def check_disparity_falloff(falloff: float) -> float:
    """The falloff as a float in [0, 0.9], or a clear error."""
    return check_range("disparity_falloff", falloff, 0.0, 0.9)


def field_ratio(ratio: Sequence[float], falloff: float, columns: int, first_column: int = 0,
                frame_width: int | None = None, device=None) -> torch.Tensor:
    """``(C, 1, columns)`` disparity ratio of each channel at columns ``first_column ...`` of a
    frame ``frame_width`` px wide (default ``columns``): ``ratio[c] (1 - f x^2) / (1 - f / 3)``."""
    width = columns if frame_width is None else frame_width
    x = (torch.arange(columns, dtype=torch.float32, device=device) + first_column + 0.5)
    x = x / width * 2.0 - 1.0
    profile = (1.0 - falloff * x**2) / (1.0 - falloff / 3.0)
    values = torch.tensor(ratio, dtype=torch.float32, device=device)
    return (values[:, None] * profile[None, :])[:, None, :]


def apply_crosstalk(
    left: torch.Tensor, right: torch.Tensor, ratio: Sequence[float], falloff: float = 0.0,
    first_column: int = 0, frame_width: int | None = None,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Mix ``left`` and ``right`` ``(C, H, W)`` (any brightness) per channel so their disparity
    is ``ratio[c]`` times as large; ``left + right`` is unchanged. With a ``falloff`` the ratio
    changes across the frame (module docstring): the inputs are columns ``first_column ...`` of
    a frame ``frame_width`` px wide (default: the whole frame).

    >>> l, r = torch.zeros(3, 1, 2), torch.zeros(3, 1, 2)
    >>> l[:, 0, 0], r[:, 0, 1] = 1.0, 1.0
    >>> a, b = apply_crosstalk(l, r, (1.0, 0.5, 0.0))
    >>> a[:, 0].tolist()
    [[1.0, 0.0], [0.75, 0.25], [0.5, 0.5]]
    """
    values = check_disparity_ratio(ratio, left.shape[-3])
    if check_disparity_falloff(falloff) > 0.0:
        a = field_ratio(values, falloff, left.shape[-1], first_column, frame_width,
                        left.device).to(left.dtype)
    else:
        a = torch.tensor(values, dtype=left.dtype, device=left.device)[:, None, None]
    keep, swap = (1.0 + a) / 2.0, (1.0 - a) / 2.0
    return keep * left + swap * right, keep * right + swap * left
