"""Each block's blur in a camera's own DP photographs, from the two views alone.

The whitened cross-convolution identity (:mod:`dualpixel.calibration.target_free`) at the
camera's known disparity ratios gives, per block of a pair, the CoC radius (px, at the pair's
own width), the side of the focal plane and whether the block is informative (textured and
blurred enough for the views to tell). :mod:`dualpixel.training.formation` blurs a network's
output with the camera's left and right PSFs at those radii and compares it with each view: a
loss on real photographs that needs no sharp target (issue on cameras without targets).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from dualpixel.calibration.target_free import (
    RATIO_GRID,
    PooledFit,
    blocks_at_ratios,
    grey_as_one_channel,
    view_energies,
)
from dualpixel.data.views import IN_FOCUS_RADIUS, BlurMap
from dualpixel.errors import ParameterError
from dualpixel.optics.camera import DPCamera
from dualpixel.optics.tone import srgb_to_linear_array

__all__ = ["blur_maps", "maps_from_fit"]

def _camera_ratios(camera: DPCamera, channels: int) -> list[float]:
    if channels == 1:  # a phone's green-only views: its green ratio
        return [float(camera.disparity_ratio[1])]
    return [float(v) for v in camera.disparity_ratio]


#: A block is in focus when the views' difference keeps at most this share of the combined
#: view's gradient energy (the views agree where the blur is nil; texture is what shows it).
IN_FOCUS_SHARE = 0.25


def _in_focus(left: np.ndarray, right: np.ndarray, radius: np.ndarray, patch: int,
              margin: int) -> np.ndarray:
    """Per block: textured, the views' difference small beside that texture, radius small."""
    from dualpixel.data.statistics import block_sums, noise_level

    rows, cols = radius.shape
    inner = (slice(margin, margin + rows * patch), slice(margin, margin + cols * patch))
    grey_left, grey_right = left.mean(axis=-1)[inner], right.mean(axis=-1)[inner]
    combined = (grey_left + grey_right) / 2
    gradient = np.diff(combined, axis=1, append=combined[:, -1:]) ** 2
    detail = block_sums(gradient, patch, np.float64)
    difference = block_sums((grey_left - grey_right) ** 2, patch, np.float64)
    noise = (noise_level(np.stack([left.mean(axis=-1)] * 3, axis=-1)) * patch) ** 2
    return ((radius <= IN_FOCUS_RADIUS) & (detail > 16 * noise)
            & (difference <= IN_FOCUS_SHARE * detail))


def blur_maps(
    pairs: Sequence[tuple[str, str, np.ndarray, np.ndarray]], camera: DPCamera, *,
    patch: int = 48, max_radius: float = 12.0, progress: bool = False,
) -> list[BlurMap]:
    """The :class:`BlurMap` of each ``(left path, right path, left, right)`` pair (views float
    ``(H, W, 3)`` stored values in [0, 1]) at ``camera``'s ratios, PSF shape and light space.
    Radii on a 0.25 px grid up to ``max_radius``."""
    from dualpixel.progress import progress_bar

    if not pairs:
        raise ParameterError("no pairs to map")
    radii = np.arange(0.25, max_radius + 0.125, 0.25)
    energies = []
    for _, _, left, right in progress_bar(pairs, desc="blur per block", enabled=progress):
        left, right = grey_as_one_channel(left, right)
        if camera.light == "linear":
            left, right = srgb_to_linear_array(left), srgb_to_linear_array(right)
        energies.append(view_energies(left, right, camera.psf, radii, RATIO_GRID, patch=patch))
    channels = {e.energy.shape[0] for e in energies}
    if len(channels) > 1:
        raise ParameterError("pairs mix grey and colour views: map one camera's pairs at a time")
    fit = blocks_at_ratios(energies, _camera_ratios(camera, channels.pop()))
    return maps_from_fit(pairs, fit, [e.centres for e in energies], patch)


def maps_from_fit(pairs: Sequence[tuple[str, str, np.ndarray, np.ndarray]], fit: PooledFit,
                  centres: Sequence[np.ndarray], patch: int) -> list[BlurMap]:
    """The :class:`BlurMap` of each pair from a pooled fit at the camera's ratios (as
    :func:`blur_maps` makes one, or the fit of a camera measured from these very pairs:
    :attr:`~dualpixel.calibration.target_free.TargetFreeCalibration.fit`, no second pass);
    ``centres``: each pair's block centres ``(rows, cols, 2)`` (x, y) px."""
    maps = []
    for i, ((lp, rp, left, right), centre) in enumerate(zip(pairs, centres, strict=True)):
        margin = round(float(centre[0, 0, 0]) - patch / 2)
        in_focus = _in_focus(np.atleast_3d(left), np.atleast_3d(right), fit.radius[i], patch,
                             margin)
        maps.append(BlurMap(str(lp), str(rp), fit.radius[i], fit.side[i].astype(np.int8),
                            fit.informative[i], in_focus, patch, margin))
    return maps


