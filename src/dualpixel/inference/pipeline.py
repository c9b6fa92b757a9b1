"""From weights to a deblurrer, one way: the network of a shipped name, a checkpoint, an exported
ONNX graph or a network already loaded, with the output settings its weights run with
(:func:`dualpixel.weights.run_settings`) and the device and backend it runs on.

``dualpixel deblur``, ``eval``, ``check-model``, the demo, a recipe's evaluation and
:func:`dualpixel.deblur` all build their :class:`~dualpixel.inference.Deblurrer` here, so a
model runs alike wherever it is named (``tests/inference/test_settings_travel.py``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import torch

from dualpixel.errors import ParameterError
from dualpixel.inference.deblur import Deblurrer
from dualpixel.inference.onnx_runtime import backend_device, load_onnx_checkpoint
from dualpixel.models.checkpoint import load_model
from dualpixel.models.unet import DeblurNet
from dualpixel.weights import output_settings, resolve_checkpoint, run_settings

__all__ = ["LoadedNetwork", "build_deblurrer", "is_graph", "load_network"]


def is_graph(source: Any) -> bool:
    """Whether ``source`` names an exported ONNX graph (run by ONNX Runtime)."""
    return isinstance(source, (str, Path)) and str(source).lower().endswith(".onnx")


@dataclass(frozen=True)
class LoadedNetwork:
    """A network ready to run: ``net`` (for a graph, the network it describes, untrained),
    ``device``, and what :class:`~dualpixel.inference.Deblurrer` needs besides (``backend``
    and, for a graph, ``graph``)."""

    net: DeblurNet
    device: torch.device
    runtime: dict[str, Any]


def load_network(source: Any, *, device: str | torch.device = "auto",
                 backend: str = "torch") -> LoadedNetwork:
    """The network of ``source``, resolved and read once: a shipped name (its registry row's
    output settings), a ``.safetensors`` path (those its file carries), a ``.onnx`` graph (run
    by onnxruntime on the CPU; those its description carries), a :class:`DeblurNet` (its own)
    or a :class:`LoadedNetwork` (as it is).
    ``device``: ``auto`` is the GPU when there is one (the CPU for onnxruntime)."""
    if isinstance(source, LoadedNetwork):
        return source
    if isinstance(source, DeblurNet):
        return LoadedNetwork(source, backend_device(backend, str(device)), {"backend": backend})
    if not isinstance(source, (str, Path)):
        raise ParameterError("model must be a name (dualpixel models), a checkpoint path or a "
                             f"network from load_model, got {type(source).__name__}")
    path = resolve_checkpoint(source)
    if is_graph(source):
        resolved = backend_device("onnxruntime", str(device))
        return LoadedNetwork(load_onnx_checkpoint(path), resolved,
                             {"backend": "onnxruntime", "graph": path})
    resolved = backend_device(backend, str(device))  # names a missing extra before any loading
    net = load_model(path, device=resolved)  # with the settings its file carries
    if path != Path(source):  # a shipped name: its registry row's settings
        net.output_settings = output_settings(source)
    return LoadedNetwork(net, resolved, {"backend": backend})


def build_deblurrer(source: Any, *, device: str | torch.device = "auto", backend: str = "torch",
                    brightness: str | None = None, overshoot: str | None = None,
                    flips: bool | None = None, fuse_frames: int | None = None,
                    **options: Any) -> Deblurrer:
    """A :class:`~dualpixel.inference.Deblurrer` for ``source`` (:func:`load_network`) running
    as its weights run: ``brightness``, ``overshoot``, ``flips`` and ``fuse_frames`` None take
    the model's own setting (a preset's: ``rdpd-light-video`` fuses frames), a value given wins.
    ``options``: the rest of ``Deblurrer`` (``tile``, ``overlap``, ``precision``,
    ``multiscale``, ...)."""
    loaded = load_network(source, device=device, backend=backend)
    settings = run_settings(loaded.net, brightness=brightness, overshoot=overshoot, flips=flips,
                            fuse_frames=fuse_frames)
    return Deblurrer(loaded.net, device=loaded.device, **loaded.runtime, **settings, **options)
