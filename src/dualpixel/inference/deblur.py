"""Deblurring whole frames and sequences with a trained network (paper Sec. 5, "full resolution").

:class:`Deblurrer` runs frames in order and carries the ConvLSTM state from each frame to the next
(call :meth:`Deblurrer.reset` between sequences) when the model is temporal (trained on
sequences; ``DeblurNet.temporal``); a model trained on single frames starts every frame afresh.
Carrying gives the same result as running the frames as one sequence through
``DeblurNet.forward``. With ``tile`` set, frames are processed in batches of
overlapping tiles (see :mod:`dualpixel.inference.tiling`) so memory stays bounded by the tile size.
``precision`` (:mod:`dualpixel.inference.precision`; ``auto`` by default) picks bfloat16 or
float16 autocast where the device computes it natively, and channels-last memory.

``flips=True`` (ours, a self-ensemble) averages the outputs for the frame as it is, flipped
upside down, and flipped left-right with the views swapped (and both): the flips that keep DP
geometry, which training augments with (a left-right flip turns the left view's PSF into the
right's). On a GPU the flipped copies go through the network as one batch while their pixels fit
in :data:`BATCH_PIXELS`; on the CPU whole frames go one by one, which measured faster there
(four members took 3.8x one pass at 1680x1120 one by one, 4.5x in batches of two); tiles go
:data:`~dualpixel.inference.tiling.MAX_BATCH` at a time. 4x the arithmetic (2x for a
single-view model, which has only the vertical flip).

On the CPU the network runs as a copy with each convolution and its activation fused into one
oneDNN call (:mod:`dualpixel.inference.fusion`; the same outputs, a quarter faster in bfloat16);
the model passed in is left as it is.

``backend="onnxruntime"`` runs the network with ONNX Runtime on the CPU in float32
(:mod:`dualpixel.inference.onnx_runtime`); everything above works the same.

``fuse_frames=N`` (ours) averages each frame's views with those of up to ``N - 1`` earlier frames
of the sequence, registered onto it, before the network (:mod:`dualpixel.inference.frame_fusion`:
temporal noise reduction; :meth:`Deblurrer.reset` forgets them too). Off (1) by default.

``multiscale=True`` (ours) also runs the network on the views at half resolution and takes the
output's coarse structure from there (:mod:`dualpixel.inference.multiscale`): a second pass on a
quarter of the pixels (at most 1.25x the time). Each scale (and each flip) carries its own
recurrent state.

Whole frames that would not fit in the memory available (:func:`pass_memory` against free RAM,
or the GPU's free memory) are deblurred in tiles instead, with a warning that says so and the
tile size taken (:meth:`Deblurrer.tile_for`); a frame no faithful tile fits is refused, naming
the numbers, before any work.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from dualpixel.data.layout import DPSequence, read_frame
from dualpixel.data.radial import radial_distance
from dualpixel.errors import ParameterError
from dualpixel.inference.brightness import (
    DEFAULT_BRIGHTNESS,
    check_brightness,
    is_palette_image,
    tie_brightness,
)
from dualpixel.inference.device_finish import limit_overshoot_tensor, tie_brightness_tensor
from dualpixel.inference.frame_fusion import FrameFusion
from dualpixel.inference.fusion import fused_copy
from dualpixel.inference.multiscale import (
    FUSION_SIGMA,
    check_fusion_sigma,
    fuse_scales,
    half_resolution,
)
from dualpixel.inference.onnx_runtime import OnnxRuntimeNet, check_backend
from dualpixel.inference.overshoot import DEFAULT_OVERSHOOT, check_overshoot, limit_overshoot
from dualpixel.inference.precision import Precision, resolve_precision
from dualpixel.inference.tiling import MAX_BATCH, TileGrid, deblur_tiled
from dualpixel.memory import GIB, available_memory
from dualpixel.models.unet import DeblurNet, pass_memory
from dualpixel.optics.tone import CombinedImage

#: Smallest tile and overlap (px) whose output matches whole-frame deblurring closely: below
#: them a tile's border sees too little of the image, and outputs change by tens of levels.
MIN_FAITHFUL_TILE = 128
MIN_FAITHFUL_OVERLAP = 32

__all__ = [
    "BATCH_PIXELS", "Deblurrer", "deblur_sequence", "default_overlap", "frame_tensor",
    "load_sequence_frames", "pass_memory",
]

#: On a GPU, whole-frame ensemble members go through the network together while their pixels
#: stay under this (two 1680x1120 frames); larger frames, and every frame on the CPU, run member
#: by member.
BATCH_PIXELS = 2 * 1680 * 1120


#: Tile overlap (px) unless given: see default_overlap.
DEFAULT_OVERLAP = 64


def default_overlap(tile: int) -> int:
    """:data:`DEFAULT_OVERLAP` px, at most half the tile, in steps of 16. At 64 px the default
    model's tiled output of a 1620x980 Canon photograph lies within 0.02 of the whole-frame
    output everywhere (71 dB apart), for 1.3x the pixels at ``tile=512``.

    >>> default_overlap(512), default_overlap(64)
    (64, 32)
    """
    return min(DEFAULT_OVERLAP, tile // 2 // 16 * 16)


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
        model: the network; like ``nn.Module.to``, this moves it in place to ``device``, to the
            precision's memory layout (channels-last or contiguous) and into eval mode.
        device: where it runs.
        tile: largest tile size (multiple of 16) for bounded memory, or ``None`` for whole frames.
        overlap: tile overlap in pixels (default: :func:`default_overlap` of the tile).
        precision: ``auto``, ``fp32``, ``bf16`` or ``fp16`` (:func:`resolve_precision`).
        flips: average over the DP-preserving flips (self-ensemble; module docstring).
        multiscale: fuse with a pass at half resolution (module docstring).
        fusion_sigma: where the two scales are split (Gaussian std, px at full resolution).
        half: deprecated spelling of ``precision="fp16"``.
        backend: ``torch``, or ``onnxruntime`` (CPU, float32; the ``onnx`` extra).
        graph: with ``onnxruntime``, an exported graph to run (``dualpixel export``; ``model``
            then only describes it: :func:`~dualpixel.inference.onnx_runtime.load_onnx_checkpoint`).
        brightness: ``"tied"``: the output's low-pass brightness in linear light held at the
            input's (:mod:`dualpixel.inference.brightness`); ``"model"``: as the network gives it.
        overshoot: ``"limited"``: the output kept within the input's local range (no halos;
            :mod:`dualpixel.inference.overshoot`), before any tie; ``"model"``: as it comes.
        fuse_frames: average each frame's views with those of up to ``fuse_frames - 1``
            earlier frames of the sequence, registered onto it (module docstring; 1: off).
    """

    model: DeblurNet
    device: str | torch.device = "cpu"
    tile: int | None = None
    overlap: int | None = None
    precision: str = "auto"
    flips: bool = False
    multiscale: bool = False
    fusion_sigma: float = FUSION_SIGMA
    half: bool = False
    backend: str = "torch"
    graph: str | Path | None = None
    brightness: str = DEFAULT_BRIGHTNESS
    overshoot: str = DEFAULT_OVERSHOOT
    fuse_frames: int = 1

    def __post_init__(self) -> None:
        check_brightness(self.brightness)
        self._fusion = FrameFusion(self.fuse_frames)  # refuses a bad count now
        check_overshoot(self.overshoot)
        if self.tile is not None:
            if self.overlap is None:
                self.overlap = default_overlap(self.tile)
            TileGrid(self.tile, self.overlap)  # refuse a bad tile or overlap now
            if self.tile < MIN_FAITHFUL_TILE or self.overlap < MIN_FAITHFUL_OVERLAP:
                warnings.warn(
                    f"tile {self.tile} px with overlap {self.overlap} px gives the network too "
                    f"little context: the output can differ from whole-frame deblurring by tens "
                    f"of levels near tile edges; use a tile of at least {MIN_FAITHFUL_TILE} px "
                    f"and an overlap of at least {MIN_FAITHFUL_OVERLAP} px",
                    stacklevel=3)  # the caller of the generated __init__
        self.device = torch.device(self.device)
        precision = "fp16" if self.half else self.precision
        check_backend(self.backend)
        if self.backend == "onnxruntime":
            self.numerics = _onnxruntime_precision(precision, self.device)
            self.model = self.model.cpu().eval()
            self._net = OnnxRuntimeNet(self.model, graph=self.graph)
        else:
            self.numerics = resolve_precision(precision, self.device)
            memory = (torch.channels_last if self.numerics.channels_last
                      else torch.contiguous_format)
            self.model = self.model.to(self.device, memory_format=memory).eval()
            # on the CPU a copy with convolution + activation pairs fused (outputs unchanged)
            self._net, _ = fused_copy(self.model, self.numerics.dtype)
        # (flip upside down, flip left-right with the views swapped) per ensemble member.
        self._flips = [(False, False)]
        if self.flips:
            self._flips.append((True, False))
            if self.model.spec.views == 2:
                self._flips += [(False, True), (True, True)]
        if self.multiscale:
            check_fusion_sigma(self.fusion_sigma)
        self._auto_tile: int | None = None  # set once a frame was too large to run whole
        # the output modes where the network ran (a GPU), one crossing to the CPU per frame
        self._finish_on_device = self.device.type != "cpu" and not self.multiscale
        self.reset()

    def reset(self) -> None:
        """Forget the recurrent state and the earlier frames (start of a new sequence)."""
        self._states: dict = {}  # by (scale, batch of members)
        self._fusion.reset()

    def free_memory(self) -> int:
        """Bytes free for a pass: the GPU's free memory on CUDA, else the RAM available."""
        if self.device.type == "cuda":
            return torch.cuda.mem_get_info(self.device)[0]
        return available_memory()

    def tile_for(self, height: int, width: int) -> int | None:
        """The tile a ``height x width`` frame runs in: this deblurrer's ``tile``; else ``None``
        (whole) while a whole pass fits in :meth:`free_memory`, or else the largest tile (a
        multiple of 16, at least :data:`MIN_FAITHFUL_TILE`) whose batches fit in half of it.
        Raises :class:`ParameterError` when not even that fits."""
        if self.tile is not None or self._auto_tile is not None:
            return self.tile or self._auto_tile
        free = self.free_memory()
        whole = pass_memory(self.model, height * width)
        if whole <= free:
            return None
        tile = min(max(height, width), 4096) // 16 * 16
        while tile >= MIN_FAITHFUL_TILE and pass_memory(self.model, MAX_BATCH * tile**2) > free / 2:
            tile -= 16
        if tile < MIN_FAITHFUL_TILE:
            raise ParameterError(
                f"a {width}x{height} frame needs about {whole / GIB:.1f} GiB of memory whole, "
                f"and even {MIN_FAITHFUL_TILE}-px tiles do not fit in the "
                f"{free / GIB:.1f} GiB available; free memory or use smaller images")
        warnings.warn(
            f"a {width}x{height} frame needs about {whole / GIB:.1f} GiB of memory whole, "
            f"{free / GIB:.1f} GiB is available: deblurring in tiles of {tile} px (overlap "
            f"{default_overlap(tile)} px; --tile sets it)", stacklevel=3)
        self._auto_tile = tile
        self._states = {}  # a tiled pass carries per-tile state: start the sequence afresh
        return tile

    def __call__(self, left: np.ndarray, right: np.ndarray | None = None, *,
                 combined: CombinedImage | None = None) -> np.ndarray:
        """Deblur the next frame (float32 (H, W, 3) views in [0, 1]); returns (H, W, 3).
        ``combined``: the views' combined image when its light is known already
        (:meth:`~dualpixel.optics.tone.CombinedImage.of_light`). On a GPU the output modes run
        there (:mod:`~dualpixel.inference.device_finish`) and the frame crosses to the CPU
        once. With ``fuse_frames`` above 1 the views are first averaged with the earlier
        frames' (the output modes then read the averaged views, ``combined`` is made anew)."""
        if self._fusion.frames > 1:
            left, right = self._fusion(left, right)
            combined = None
        if self._finish_on_device:
            with torch.inference_mode():
                out = self._ensemble(left, right, scale=0, on_device=True)
                return self.finish(out, left, right, combined=combined)
        return self.finish(self.network_output(left, right), left, right, combined=combined)

    @torch.inference_mode()
    def network_output(self, left: np.ndarray, right: np.ndarray | None = None) -> np.ndarray:
        """The next frame as the network gives it (flips and scales fused), before the output
        modes of :meth:`finish`."""
        out = self._ensemble(left, right, scale=0)
        if self.multiscale:
            small = [None if v is None else half_resolution(v) for v in (left, right)]
            coarse = self._ensemble(*small, scale=1)
            out = fuse_scales(out, coarse, self.fusion_sigma)
        return out

    def finish(self, out: np.ndarray | torch.Tensor, left: np.ndarray,
               right: np.ndarray | None = None, *, brightness: str | None = None,
               overshoot: str | None = None,
               combined: CombinedImage | None = None) -> np.ndarray:
        """``out`` of :meth:`network_output` for these views with the output modes applied:
        the overshoot limit, then the brightness tie (``None``: this deblurrer's modes), both
        reading one combined image of the views (``combined``, else made here). ``out`` a
        ``(3, H, W)`` tensor: the modes run on its device (the same results,
        :mod:`~dualpixel.inference.device_finish`); the frame comes back ``(H, W, 3)``."""
        limited = check_overshoot(overshoot or self.overshoot) == "limited"
        tied = check_brightness(brightness or self.brightness) == "tied"
        if isinstance(out, torch.Tensor):
            if tuple(out.shape) != (3, *left.shape[:2]):
                raise ParameterError(f"a network output tensor must be (3, H, W) of the views' "
                                     f"size {left.shape[1]}x{left.shape[0]}, got "
                                     f"{tuple(out.shape)}")
            if (limited or tied) and not is_palette_image(left):  # a GIF's dither: the CPU's
                out = _finish_tensor(out, left, right, combined, limited=limited, tied=tied)
                return out.permute(1, 2, 0).float().cpu().numpy()
            out = out.permute(1, 2, 0).float().cpu().numpy()
        if combined is None:
            combined = CombinedImage(left, right)  # each light made once, when first read
        if limited:
            out = limit_overshoot(out, left, right, combined=combined.encoded)
        if tied:
            out = tie_brightness(out, left, right, combined=combined)
        return out

    def _ensemble(self, left: np.ndarray, right: np.ndarray | None, scale: int, *,
                  on_device: bool = False) -> np.ndarray | torch.Tensor:
        """The mean output over the flips, run as batches of members: ``(H, W, 3)``, or with
        ``on_device`` a ``(3, H, W)`` tensor where the network ran."""
        inputs = []
        for vertical, horizontal in self._flips:
            views = (left, right)
            if horizontal:  # mirrored, the left view's PSF is the right view's
                views = (right[:, ::-1], left[:, ::-1])
            if vertical:
                views = tuple(None if v is None else v[::-1] for v in views)
            inputs.append(frame_tensor(self.model, *views))
        x = torch.cat(inputs)
        tile = self.tile_for(*left.shape[:2])
        if tile is not None:
            outputs = self._run((scale, 0), x, tile=tile)
        else:
            budget = BATCH_PIXELS if self.device.type == "cuda" else 0
            per_pass = max(1, min(len(inputs), budget // (left.shape[0] * left.shape[1])))
            outputs = torch.cat([self._run((scale, first), x[first : first + per_pass])
                                 for first in range(0, len(inputs), per_pass)])
        total = torch.zeros_like(outputs[0])
        for out, (vertical, horizontal) in zip(outputs, self._flips):
            out = out.flip(-2) if vertical else out
            total += out.flip(-1) if horizontal else out
        total /= len(self._flips)
        return total if on_device else total.permute(1, 2, 0).cpu().numpy()

    def _run(self, key: tuple[int, int], x: torch.Tensor, tile: int | None = None
             ) -> torch.Tensor:
        """One network pass over a batch of members carrying the state ``key`` (in tiles of
        ``tile`` px when given); float32, where the network ran."""
        x = x.to(self.device)
        state = self._states.get(key) if self.model.temporal else None  # single-frame models
        with self.numerics.autocast(self.device):
            if tile is None:
                if self.numerics.channels_last:
                    x = x.contiguous(memory_format=torch.channels_last)
                out, state = self._net.step(x, state)
            else:
                overlap = self.overlap if tile == self.tile else default_overlap(tile)
                out, state = deblur_tiled(
                    self._net, x, tile=tile, overlap=overlap, states=state,
                    max_batch=MAX_BATCH, channels_last=self.numerics.channels_last,
                )
        self._states[key] = state
        return out.float()


def _finish_tensor(out: torch.Tensor, left: np.ndarray, right: np.ndarray | None,
                   combined: CombinedImage | None, *, limited: bool, tied: bool
                   ) -> torch.Tensor:
    """The output modes of :meth:`Deblurrer.finish` on ``out``'s device, reading the views'
    combined image made there (:meth:`~dualpixel.optics.tone.CombinedImage.tensors`)."""
    light, encoded = (combined or CombinedImage(left, right)).tensors(out.device)
    if limited:
        out = limit_overshoot_tensor(out, encoded)
    if tied:
        out = tie_brightness_tensor(out, light)
    return out


def _onnxruntime_precision(precision: str, device: torch.device) -> Precision:
    """ONNX Runtime runs float32 on the CPU: ``auto`` and ``fp32`` only."""
    if device.type != "cpu":
        raise ParameterError(f"backend onnxruntime runs on the CPU, got device {device}; use "
                             "--device cpu, or the torch backend on the GPU")
    if precision not in ("auto", "fp32"):
        raise ParameterError(f"backend onnxruntime runs in fp32, got precision {precision}; "
                             "use auto or fp32, or the torch backend")
    return Precision("fp32", None, channels_last=False)


def deblur_sequence(
    model: DeblurNet, frames: list[dict[str, np.ndarray]], *, device: str | torch.device = "cpu",
    tile: int | None = None, precision: str = "auto",
) -> list[np.ndarray]:
    """Deblur a list of frames (dicts with ``left`` and ``right``) carrying the recurrent state."""
    if not frames:
        raise ParameterError("no frames to deblur")
    deblurrer = Deblurrer(model, device=device, tile=tile, precision=precision)
    return [deblurrer(frame["left"], frame.get("right")) for frame in frames]
