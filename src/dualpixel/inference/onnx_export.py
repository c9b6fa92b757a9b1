"""Export a trained network to ONNX: one frame, or one recurrent step with the state as I/O.

The single-frame graph maps the model input ``(1, C, H, W)`` to the output ``(1, 3, H, W)``
(a recurrent model starts from a zero state). The step graph takes ``input, hidden, cell`` and
returns ``output, next_hidden, next_cell``; the state is ``(1, 512*width, H/16, W/16)`` for
``H, W`` rounded up to multiples of 16, and zeros for the first frame. Height and width
are dynamic: a graph exported at one size runs at any other (``dynamic=False`` fixes them).
Every graph carries the network's architecture in its metadata (``dualpixel``: name, width,
residual, refiner, peepholes, whether it is the step graph), so ``deblur --checkpoint
model.onnx`` runs it (:func:`dualpixel.inference.onnx_runtime.load_onnx_checkpoint`).
Needs the ``onnx`` extra (``onnx``, ``onnxscript``; ``onnxruntime`` to verify).
"""

from __future__ import annotations

import contextlib
import json
import logging
from pathlib import Path

import numpy as np
import torch
from torch import nn

from dualpixel.errors import ParameterError
from dualpixel.io.atomic import atomic_path
from dualpixel.memory import require_memory
from dualpixel.models.unet import SIZE_MULTIPLE, DeblurNet, pass_memory

__all__ = ["METADATA_KEY", "export_onnx", "graph_metadata", "run_onnx", "state_shape"]

#: The metadata entry of an exported graph that describes its network.
METADATA_KEY = "dualpixel"


class _Frame(nn.Module):
    def __init__(self, model: DeblurNet) -> None:
        super().__init__()
        self.model = model

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.model.step(x, None)[0]


class _Step(nn.Module):
    def __init__(self, model: DeblurNet) -> None:
        super().__init__()
        self.model = model

    def forward(self, x: torch.Tensor, hidden: torch.Tensor, cell: torch.Tensor):
        out, (hidden, cell) = self.model.step(x, (hidden, cell))
        return out, hidden, cell


def state_shape(model: DeblurNet, height: int, width: int, batch: int = 1
                ) -> tuple[int, int, int, int]:
    """Shape of the ConvLSTM hidden and cell state for ``batch`` frames of ``height x width``."""
    if model.lstm is None:
        raise ParameterError(f"model {model.spec.name!r} is not recurrent")
    pad = lambda n: -(-n // SIZE_MULTIPLE)  # noqa: E731
    return (batch, model.lstm.hidden_channels, pad(height), pad(width))


def check_export_packages() -> None:
    """Refuse an ONNX export without the packages torch's exporter needs, naming the extra."""
    from importlib.util import find_spec

    missing = [name for name in ("onnx", "onnxscript") if find_spec(name) is None]
    if missing:
        raise ParameterError(f"ONNX export needs {', '.join(missing)}: pip install "
                             "'dualpixel[onnx]' (or --format safetensors-fp16)")


def export_onnx(
    model: DeblurNet, path: str | Path, *, height: int, width: int, step: bool = False,
    opset: int = 18, dynamic: bool = True, batch: int = 1,
) -> Path:
    """Write ``model`` as ONNX, traced at ``height x width`` (``step``: one recurrent step).
    ``batch`` > 1 traces that many frames at once and leaves the batch size dynamic too (a graph
    traced at batch 1 keeps it at 1)."""
    if batch < 1:
        raise ParameterError(f"batch must be >= 1, got {batch}")
    # tracing runs the network once at this size, with the input beside it: refused up front
    require_memory(pass_memory(model, batch * height * width)
                   + 4 * model.shape.in_channels * batch * height * width,
                   f"exporting at {width}x{height}")
    check_export_packages()
    model = model.cpu().eval()
    x = torch.rand(batch, model.shape.in_channels, height, width)
    if step:
        zeros = torch.zeros(state_shape(model, height, width, batch))
        wrapper, args = _Step(model), (x, zeros, zeros.clone())
        names_in, names_out = ["input", "hidden", "cell"], ["output", "next_hidden", "next_cell"]
    else:
        wrapper, args, names_in, names_out = _Frame(model), (x,), ["input"], ["output"]
    wrapper.eval()
    spatial = {2: torch.export.Dim.AUTO, 3: torch.export.Dim.AUTO}
    if batch > 1:
        spatial[0] = torch.export.Dim.AUTO
    dynamic_shapes = None
    if dynamic:
        dynamic_shapes = ({"x": spatial, "hidden": spatial, "cell": spatial} if step
                          else {"x": spatial})
    path = Path(path)
    with atomic_path(path) as tmp, _quiet_exporter():
        torch.onnx.export(
            wrapper, args, str(tmp), input_names=names_in, output_names=names_out,
            opset_version=opset, dynamo=True, external_data=False, verbose=False,
            dynamic_shapes=dynamic_shapes,
        )
        _describe(tmp, model, step=step, dynamic=dynamic)
    return path


@contextlib.contextmanager
def _quiet_exporter():
    """The exporter's notes that concern other packages (``torchvision is not installed.
    Skipping torchvision::nms`` and three more) kept off the console; its errors still show."""
    logger = logging.getLogger("torch.onnx")
    level = logger.level
    logger.setLevel(logging.ERROR)
    try:
        yield
    finally:
        logger.setLevel(level)


def _describe(path: Path, model: DeblurNet, *, step: bool, dynamic: bool) -> None:
    """Write the network's architecture into the graph's metadata."""
    import onnx

    graph = onnx.load(str(path))
    entry = graph.metadata_props.add()
    entry.key, entry.value = METADATA_KEY, json.dumps({
        "model": model.spec.name, "width": float(model.width),
        "residual": bool(model.shape.residual), "refiner": list(model.shape.refiner),
        "peepholes": bool(model.shape.peepholes), "head_relu": bool(model.shape.head_relu),
        "conv_bottleneck": bool(model.conv_bottleneck), "temporal": bool(model.temporal),
        "step": bool(step), "dynamic": bool(dynamic),
        "output": dict(model.output_settings)})  # how the weights run (brightness tied, ...)
    onnx.save(graph, str(path))


def graph_metadata(path: str | Path) -> dict:
    """The network description an exported graph carries (:data:`METADATA_KEY`)."""
    import onnx

    from dualpixel.errors import InputFileError

    try:
        graph = onnx.load(str(path), load_external_data=False)
    except Exception as error:  # onnx raises DecodeError and others for a bad file
        raise InputFileError(path, f"not a readable ONNX graph ({type(error).__name__})") from None
    for entry in graph.metadata_props:
        if entry.key == METADATA_KEY:
            try:
                return dict(json.loads(entry.value))
            except (ValueError, TypeError):
                break
    raise InputFileError(path, "is no graph written by `dualpixel export` (it carries no "
                               "network description); export the checkpoint again")


def run_onnx(path: str | Path, *inputs: np.ndarray) -> list[np.ndarray]:
    """Run an exported graph with ONNX Runtime on the CPU."""
    import onnxruntime

    session = onnxruntime.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    feeds = {i.name: a.astype(np.float32) for i, a in zip(session.get_inputs(), inputs)}
    return session.run(None, feeds)
