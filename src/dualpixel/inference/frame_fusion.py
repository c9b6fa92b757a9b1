"""Earlier frames of a sequence registered onto the current one and averaged with its views
(ours, not in the paper): temporal noise reduction before the network.

What earlier frames offer a DP video, measured on the held-out synthetic sequences of the
default's seven cameras (``docs/video.md``): the noise of the views costs the default 0.4-1.4 dB
against the same views without noise, while its ConvLSTM state, which lives at 1/16 of the
resolution, recovers almost none of it. Averaging registered frames at full resolution does.

For frame ``k`` and each of up to ``frames - 1`` earlier frames ``j``:

1. a dense optical flow (OpenCV's DIS, the "medium" preset) from a grey guide of frame ``k``
   (the views' mean, scaled by frame ``k``'s 99.5th percentile) to frame ``j``'s, both blurred
   by a Gaussian of :data:`FLOW_SMOOTHING_PX` (the flow then follows structure, not noise);
2. frame ``j``'s left and right views warped onto frame ``k`` by that flow (bilinear): with the
   camera moving, a static point keeps its depth, so its blur and disparity, and both views move
   as the guide does;
3. a weight per pixel, ``exp(-(d / (2 m))^2)`` with ``d`` the warped guide's difference from
   frame ``k``'s, smoothed by a Gaussian of :data:`SMOOTHING_PX`, and ``m`` :data:`MATCH_SPREADS`
   times the robust spread of ``d`` over the frame (1.4826 x its median absolute value: the
   noise of a matched pixel's difference), at most :data:`MAX_MATCH_LEVEL` of the guide's
   scale; the lowest weight within 2 px; zero where the flow leaves the frame. Where an object
   moved, was uncovered or is misregistered, the earlier frame drops out;
4. the views of frame ``k`` (weight 1) and the warped ones averaged with those weights.

The first frame of a sequence, and a frame no earlier one matches, come out as they went in.
The parameters were set on the fused views' error against the noise-free views, before any
deblurring, on sequences made for that alone (``experiments/scripts/fusion_probe.py``): a
level set by each frame's own noise (the match tight on a clean DSLR, loose on a noisy phone)
and flow on blurred guides fuse 0.5-0.8 dB closer to the noise-free views than one fixed level
did on two DSLR cameras, and as close on the phone.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

import cv2
import numpy as np

from dualpixel.errors import ParameterError
from dualpixel.filters import channel_mean

__all__ = ["FLOW_SMOOTHING_PX", "MATCH_SPREADS", "MAX_MATCH_LEVEL", "SMOOTHING_PX",
           "FrameFusion", "check_fuse_frames"]

#: Standard deviation (px) of the Gaussian that smooths a warped frame's difference.
SMOOTHING_PX = 1.0
#: The match level, in robust spreads of the smoothed difference: where the difference is the
#: level, an earlier pixel's weight falls to exp(-1/4); twice it, to exp(-1).
MATCH_SPREADS = 3.0
#: The loosest match level, a fraction of the guide's scale (a frame of many moving pixels
#: widens the spread; it never makes the match looser than this).
MAX_MATCH_LEVEL = 0.03
#: Standard deviation (px) of the Gaussian that blurs the guides the flow is found on.
FLOW_SMOOTHING_PX = 1.0
#: The neighbourhood over which a pixel takes the lowest weight (a mismatch widened by 2 px).
_NEAR = np.ones((5, 5), np.uint8)
#: The guide's percentile that is its full scale.
_GUIDE_PERCENTILE = 99.5


def check_fuse_frames(frames: object) -> int:
    """Refuse a frame count that is not a whole number of at least 1 (1: no fusion)."""
    if isinstance(frames, bool) or not isinstance(frames, (int, np.integer)) or frames < 1:
        raise ParameterError(f"fuse_frames must be a whole number of at least 1 (1: each frame "
                             f"alone), got {frames!r}")
    return int(frames)


@dataclass
class _Frame:
    left: np.ndarray
    right: np.ndarray | None
    guide: np.ndarray  # (H, W) float32, the views' grey mean
    flow_guide: np.ndarray  # the guide the flow is found on


@dataclass
class FrameFusion:
    """Stateful: call with each frame's views in order, :meth:`reset` between sequences.

    Args:
        frames: the current frame and up to ``frames - 1`` earlier ones are averaged.
        match_spreads: :data:`MATCH_SPREADS` (0: the match level is ``max_match_level``).
        max_match_level: :data:`MAX_MATCH_LEVEL`; smoothing_px: :data:`SMOOTHING_PX`.
        flow_smoothing_px: :data:`FLOW_SMOOTHING_PX` (0: the flow on the guides as they are);
            the weights compare the guides unblurred.
    """

    frames: int
    match_spreads: float = MATCH_SPREADS
    max_match_level: float = MAX_MATCH_LEVEL
    smoothing_px: float = SMOOTHING_PX
    flow_smoothing_px: float = FLOW_SMOOTHING_PX
    _earlier: deque = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self.frames = check_fuse_frames(self.frames)
        self.reset()

    def reset(self) -> None:
        """Forget the earlier frames (start of a new sequence)."""
        self._earlier = deque(maxlen=max(self.frames - 1, 0))

    def __call__(self, left: np.ndarray, right: np.ndarray | None = None
                 ) -> tuple[np.ndarray, np.ndarray | None]:
        """The views of the next frame (float32 ``(H, W, C)``) averaged with the registered
        earlier ones; the same shapes back."""
        left = np.asarray(left, dtype=np.float32)
        right = None if right is None else np.asarray(right, dtype=np.float32)
        if self.frames == 1:
            return left, right
        guide = _guide(left, right)
        if self._earlier and self._earlier[-1].guide.shape != guide.shape:
            raise ParameterError(f"frame of {guide.shape[1]}x{guide.shape[0]} after frames of "
                                 f"{self._earlier[-1].guide.shape[1]}x"
                                 f"{self._earlier[-1].guide.shape[0]} in one sequence")
        fused_left, fused_right = left.copy(), None if right is None else right.copy()
        total = np.ones(guide.shape, np.float32)
        flow_guide = self._for_flow(guide)
        if self._earlier:
            scale = max(float(np.percentile(guide, _GUIDE_PERCENTILE)), 1e-6)
            target = _as_u8(flow_guide, scale)
            flow_maker = cv2.DISOpticalFlow_create(cv2.DISOPTICAL_FLOW_PRESET_MEDIUM)
            rows, cols = guide.shape
            grid_x, grid_y = np.meshgrid(np.arange(cols, dtype=np.float32),
                                         np.arange(rows, dtype=np.float32))
            for earlier in self._earlier:
                flow = flow_maker.calc(target, _as_u8(earlier.flow_guide, scale), None)
                map_x, map_y = grid_x + flow[..., 0], grid_y + flow[..., 1]
                warped = _warp(earlier.guide, map_x, map_y)
                difference = cv2.GaussianBlur(warped - guide, (0, 0), self.smoothing_px) / scale
                weight = np.exp(-np.square(difference / (2.0 * self._level(difference))))
                weight *= (map_x >= 0) & (map_x <= cols - 1) & (map_y >= 0) & (map_y <= rows - 1)
                # each pixel takes the lowest weight near it: a mismatch's smoothed edges too
                weight = cv2.erode(weight.astype(np.float32), _NEAR)
                fused_left += _warp(earlier.left, map_x, map_y) * _per_channel(weight, left)
                if right is not None:
                    fused_right += (_warp(earlier.right, map_x, map_y)
                                    * _per_channel(weight, right))
                total += weight
        self._earlier.append(_Frame(left, right, guide, flow_guide))
        fused_left /= _per_channel(total, left)
        if fused_right is not None:
            fused_right /= _per_channel(total, right)
        return fused_left, fused_right

    def _level(self, difference: np.ndarray) -> float:
        """The match level of a smoothed difference (a fraction of the guide's scale)."""
        if self.match_spreads <= 0:
            return self.max_match_level
        # a matched pixel's noise; every other row and column (the smoothed difference is
        # correlated over more than that), 4x faster
        spread = 1.4826 * float(np.median(np.abs(difference[::2, ::2])))
        return max(min(self.match_spreads * spread, self.max_match_level), 1e-6)

    def _for_flow(self, guide: np.ndarray) -> np.ndarray:
        """The guide the flow is found on."""
        if self.flow_smoothing_px <= 0:
            return guide
        return cv2.GaussianBlur(guide, (0, 0), self.flow_smoothing_px)


def _guide(left: np.ndarray, right: np.ndarray | None) -> np.ndarray:
    """The grey mean of the views, ``(H, W)`` float32."""
    views = left if right is None else (left + right) / 2.0
    return channel_mean(views) if views.ndim == 3 else views.astype(np.float32)


def _as_u8(guide: np.ndarray, scale: float) -> np.ndarray:
    return np.clip(guide / scale * 255.0 + 0.5, 0, 255).astype(np.uint8)


def _warp(image: np.ndarray, map_x: np.ndarray, map_y: np.ndarray) -> np.ndarray:
    warped = cv2.remap(image, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    return warped.reshape(image.shape)  # remap drops a trailing axis of length 1


def _per_channel(weight: np.ndarray, like: np.ndarray) -> np.ndarray:
    return weight[..., None] if like.ndim == 3 else weight
