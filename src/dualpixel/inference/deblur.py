"""Deblurring whole frames and sequences with a trained network (paper Sec. 5, "full resolution").

A sequence runs frame by frame with the ConvLSTM state carried from each frame to the next, which
gives the same result as running the frames as one sequence through ``DeblurNet.forward``.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator

import numpy as np
import torch

from dualpixel.data.layout import DPSequence
from dualpixel.data.radial import radial_distance
from dualpixel.errors import ParameterError
from dualpixel.io.images import read_rgb
from dualpixel.models.convlstm import LSTMState
from dualpixel.models.unet import DeblurNet

__all__ = ["deblur_frame", "deblur_sequence", "frame_tensor", "load_sequence_frames"]


def load_sequence_frames(sequence: DPSequence) -> list[dict[str, np.ndarray]]:
    """Decode the views (and targets, where present) of a sequence as float32 (H, W, 3)."""
    frames = []
    for paths in sequence.frames:
        frame = {"left": read_rgb(paths.left), "right": read_rgb(paths.right)}
        if paths.target is not None:
            frame["target"] = read_rgb(paths.target)
        frames.append(frame)
    return frames


def frame_tensor(model: DeblurNet, left: np.ndarray, right: np.ndarray | None) -> torch.Tensor:
    """The network input ``(1, C, H, W)`` for one frame: views and the full-frame radial channel."""
    height, width = left.shape[:2]
    if right is not None and right.shape != left.shape:
        raise ValueError(f"left {left.shape} and right {right.shape} views differ in size")
    as_tensor = lambda a: torch.from_numpy(np.ascontiguousarray(a)).permute(2, 0, 1)[None]  # noqa: E731
    radial = torch.from_numpy(radial_distance(height, width))[None, None]
    return model.spec.make_input(
        as_tensor(left), None if right is None else as_tensor(right), radial
    )


@torch.inference_mode()
def deblur_frame(
    model: DeblurNet,
    left: np.ndarray,
    right: np.ndarray | None,
    *,
    state: LSTMState | None = None,
    device: str | torch.device = "cpu",
) -> tuple[np.ndarray, LSTMState | None]:
    """Deblur one frame (float32 (H, W, 3) views in [0, 1]); returns the output and next state."""
    x = frame_tensor(model, left, right).to(device)
    out, state = model.step(x, state)
    return out[0].permute(1, 2, 0).float().cpu().numpy(), state


def iter_deblur(
    model: DeblurNet,
    frames: Iterable[dict[str, np.ndarray]],
    *,
    device: str | torch.device = "cpu",
) -> Iterator[np.ndarray]:
    """Deblur frames in order, carrying the recurrent state; yields each output as it is ready."""
    state = None
    for frame in frames:
        output, state = deblur_frame(model, frame["left"], frame.get("right"), state=state,
                                     device=device)
        yield output


def deblur_sequence(
    model: DeblurNet, frames: list[dict[str, np.ndarray]], *, device: str | torch.device = "cpu"
) -> list[np.ndarray]:
    """Deblur a list of frames (dicts with ``left`` and ``right``) carrying the recurrent state."""
    if not frames:
        raise ParameterError("no frames to deblur")
    return list(iter_deblur(model, frames, device=device))
