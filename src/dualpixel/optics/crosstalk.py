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
"""

from __future__ import annotations

from collections.abc import Sequence

import torch

from dualpixel.errors import ParameterError, check_range

__all__ = ["apply_crosstalk", "check_disparity_ratio"]


def check_disparity_ratio(ratio: Sequence[float], channels: int = 3) -> tuple[float, ...]:
    """The ratios as a tuple of ``channels`` finite floats in [0, 1.5], or a clear error."""
    values = tuple(check_range(f"disparity_ratio[{i}]", v) for i, v in enumerate(ratio))
    if len(values) != channels:
        raise ParameterError(f"disparity_ratio needs one value per channel ({channels}), "
                             f"got {len(values)}")
    if not all(0.0 <= v <= 1.5 for v in values):  # NaN fails the comparison too
        raise ParameterError(f"disparity_ratio values must be in [0, 1.5], got {list(values)}")
    return values


def apply_crosstalk(
    left: torch.Tensor, right: torch.Tensor, ratio: Sequence[float]
) -> tuple[torch.Tensor, torch.Tensor]:
    """Mix ``left`` and ``right`` ``(C, H, W)`` (any brightness) per channel so their disparity
    is ``ratio[c]`` times as large; ``left + right`` is unchanged.

    >>> l, r = torch.zeros(3, 1, 2), torch.zeros(3, 1, 2)
    >>> l[:, 0, 0], r[:, 0, 1] = 1.0, 1.0
    >>> a, b = apply_crosstalk(l, r, (1.0, 0.5, 0.0))
    >>> a[:, 0].tolist()
    [[1.0, 0.0], [0.75, 0.25], [0.5, 0.5]]
    """
    values = check_disparity_ratio(ratio, left.shape[-3])
    a = torch.tensor(values, dtype=left.dtype, device=left.device)[:, None, None]
    keep, swap = (1.0 + a) / 2.0, (1.0 - a) / 2.0
    return keep * left + swap * right, keep * right + swap * left
