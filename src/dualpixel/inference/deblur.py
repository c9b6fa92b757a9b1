"""Deblurring whole frames and sequences with a trained network (paper Sec. 5, "full resolution").

:class:`Deblurrer` runs frames in order and carries the ConvLSTM state from each frame to the next
(call :meth:`Deblurrer.reset` between sequences) when the model is temporal (trained on
sequences; ``DeblurNet.temporal``); a model trained on single frames starts every frame afresh.
Carrying gives the same result as running the frames as one sequence through
``DeblurNet.forward``. With ``tile`` set, frames are processed in
overlapping tiles (see :mod:`dualpixel.inference.tiling`) so memory stays bounded by the tile size.
On CUDA, ``half=True`` runs in float16 autocast and the model uses channels-last memory.

``flips=True`` (ours, a self-ensemble) averages the outputs for the frame as it is, flipped
upside down, and flipped left-right with the views swapped (and both): the flips that keep DP
geometry, which training augments with (a left-right flip turns the left view's PSF into the
right's). 4x the time (2x for a single-view model, which has only the vertical flip).

``multiscale=True`` (ours) also runs the network on the views at half resolution and takes the
output's coarse structure from there (:mod:`dualpixel.inference.multiscale`): a second pass on a
quarter of the pixels (at most 1.25x the time). Each scale (and each flip) carries its own
recurrent state.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from dualpixel.data.layout import DPSequence, read_frame
from dualpixel.data.radial import radial_distance
from dualpixel.errors import ParameterError
from dualpixel.inference.multiscale import (
    FUSION_SIGMA,
    check_fusion_sigma,
    fuse_scales,
    half_resolution,
)
from dualpixel.inference.tiling import TileGrid, deblur_tiled
from dualpixel.models.unet import DeblurNet

__all__ = [
    "Deblurrer", "deblur_sequence", "default_overlap", "frame_tensor", "load_sequence_frames",
]


def default_overlap(tile: int) -> int:
    """192 px (wide enough for the network's receptive field at full width), at most half the
    tile, in steps of 16.

    >>> default_overlap(512), default_overlap(128)
    (192, 64)
    """
    return min(192, tile // 2 // 16 * 16)


def load_sequence_frames(sequence: DPSequence) -> list[dict[str, np.ndarray]]:
    """Decode the views (and targets, where present) of a sequence as float32 (H, W, 3)."""
    return [read_frame(paths) for paths in sequence.frames]


def _chw(image: np.ndarray) -> torch.Tensor:
    return torch.from_numpy(np.ascontiguousarray(image, dtype=np.float32)).permute(2, 0, 1)[None]


def frame_tensor(model: DeblurNet, left: np.ndarray, right: np.ndarray | None) -> torch.Tensor:
    """The network input ``(1, C, H, W)`` for one frame: views and the full-frame radial channel."""
    if left.ndim != 3 or left.shape[2] != 3:
        raise ParameterError(f"expected an RGB view (H, W, 3), got shape {left.shape}")
    if right is not None and right.shape != left.shape:
        raise ParameterError(f"left {left.shape} and right {right.shape} views differ in size")
    radial = torch.from_numpy(radial_distance(*left.shape[:2]))[None, None]
    return model.spec.make_input(_chw(left), None if right is None else _chw(right), radial)


@dataclass
class Deblurrer:
    """Stateful frame-by-frame deblurring with a trained model.

    Args:
        model: the network (put in eval mode here).
        device: where it runs.
        tile: tile size (multiple of 16) for bounded memory, or ``None`` for whole frames.
        overlap: tile overlap in pixels (default: :func:`default_overlap` of the tile).
        half: float16 autocast on CUDA (ignored on the CPU).
        flips: average over the DP-preserving flips (self-ensemble; module docstring).
        multiscale: fuse with a pass at half resolution (module docstring).
        fusion_sigma: where the two scales are split (Gaussian std, px at full resolution).
    """

    model: DeblurNet
    device: str | torch.device = "cpu"
    tile: int | None = None
    overlap: int | None = None
    half: bool = False
    flips: bool = False
    multiscale: bool = False
    fusion_sigma: float = FUSION_SIGMA

    def __post_init__(self) -> None:
        if self.tile is not None:
            if self.overlap is None:
                self.overlap = default_overlap(self.tile)
            TileGrid(self.tile, self.overlap)  # refuse a bad tile or overlap now
        self.device = torch.device(self.device)
        self.model = self.model.to(self.device).eval()
        if self.device.type == "cuda":
            self.model = self.model.to(memory_format=torch.channels_last)
        # (flip upside down, flip left-right with the views swapped) per ensemble member.
        self._flips = [(False, False)]
        if self.flips:
            self._flips.append((True, False))
            if self.model.spec.views == 2:
                self._flips += [(False, True), (True, True)]
        if self.multiscale:
            check_fusion_sigma(self.fusion_sigma)
        self.reset()

    def reset(self) -> None:
        """Forget the recurrent state (start of a new sequence)."""
        # One state per ensemble member and scale.
        self._states: list = [None] * len(self._flips) * (2 if self.multiscale else 1)

    @torch.inference_mode()
    def __call__(self, left: np.ndarray, right: np.ndarray | None = None) -> np.ndarray:
        """Deblur the next frame (float32 (H, W, 3) views in [0, 1]); returns (H, W, 3)."""
        if not self.multiscale:
            return self._ensemble(left, right, first_state=0)
        small = [None if v is None else half_resolution(v) for v in (left, right)]
        out = self._ensemble(left, right, first_state=0)
        coarse = self._ensemble(*small, first_state=len(self._flips))
        return fuse_scales(out, coarse, self.fusion_sigma)

    def _ensemble(self, left: np.ndarray, right: np.ndarray | None, first_state: int
                  ) -> np.ndarray:
        """The mean output over the flips; member ``i`` uses state ``first_state + i``."""
        total = None
        for index, (vertical, horizontal) in enumerate(self._flips):
            views = (left, right)
            if horizontal:  # mirrored, the left view's PSF is the right view's
                views = (right[:, ::-1], left[:, ::-1])
            if vertical:
                views = tuple(None if v is None else v[::-1] for v in views)
            out = self._run(first_state + index, frame_tensor(self.model, *views))
            out = out.flip(-2) if vertical else out
            out = out.flip(-1) if horizontal else out
            total = out if total is None else total + out
        return (total[0] / len(self._flips)).permute(1, 2, 0).cpu().numpy()

    def _run(self, member: int, x: torch.Tensor) -> torch.Tensor:
        """One network pass carrying state ``member`` (flip and scale); float32 output."""
        x = x.to(self.device)
        state = self._states[member] if self.model.temporal else None  # single-frame models
        autocast = self.half and self.device.type == "cuda"
        with torch.autocast("cuda", dtype=torch.float16, enabled=autocast):
            if self.tile is None:
                out, state = self.model.step(x, state)
            else:
                out, state = deblur_tiled(
                    self.model, x, tile=self.tile, overlap=self.overlap, states=state
                )
        self._states[member] = state
        return out.float()


def deblur_sequence(
    model: DeblurNet, frames: list[dict[str, np.ndarray]], *, device: str | torch.device = "cpu",
    tile: int | None = None,
) -> list[np.ndarray]:
    """Deblur a list of frames (dicts with ``left`` and ``right``) carrying the recurrent state."""
    if not frames:
        raise ParameterError("no frames to deblur")
    deblurrer = Deblurrer(model, device=device, tile=tile)
    return [deblurrer(frame["left"], frame.get("right")) for frame in frames]
