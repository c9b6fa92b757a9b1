"""ONNX Runtime as an inference backend (``deblur --backend onnxruntime``).

The network is exported once per checkpoint (:mod:`dualpixel.inference.onnx_export`: the
recurrent step graph for a temporal model, the single-frame graph otherwise; batch, height and
width dynamic) into a cache folder, keyed by a SHA-256 of the weights and architecture, the
torch version and the opset, and run by ONNX Runtime on the CPU in float32. :class:`OnnxRuntimeNet`
offers what :class:`~dualpixel.inference.deblur.Deblurrer` uses of a network (``step(x, state)``,
``spec``, ``shape``, ``temporal``), so tiles, flips, two scales and the recurrent state work as
with PyTorch. Where it wins: on CPUs without native bfloat16, where the PyTorch default runs in
float32 (``docs/benchmarks.md`` has both on this project's CPU). Needs the ``onnx`` extra.

The cache folder is ``$DUALPIXEL_CACHE_DIR/onnx`` if set, else ``$XDG_CACHE_HOME/dualpixel/onnx``
or ``~/.cache/dualpixel/onnx``; files are written atomically, so an interrupted export leaves
nothing that looks finished.
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
import warnings
from pathlib import Path

import numpy as np
import torch

from dualpixel.device import resolve_device
from dualpixel.errors import ParameterError
from dualpixel.inference.onnx_export import export_onnx, state_shape
from dualpixel.models.unet import DeblurNet
from dualpixel.names import BACKENDS

__all__ = ["BACKENDS", "OnnxRuntimeNet", "backend_device", "cache_dir", "check_backend",
           "load_onnx_checkpoint"]

#: The opset of cached graphs (part of the cache key).
OPSET = 18

#: Export size (a multiple of 16; batch 2 keeps the batch dimension dynamic).
_EXPORT_SIZE = (2, 64, 64)


def check_backend(backend: str) -> str:
    """Refuse an unknown backend, and ``onnxruntime`` without its packages (naming the extra)."""
    if backend not in BACKENDS:
        raise ParameterError(f"backend must be one of {', '.join(BACKENDS)}, got {backend!r}")
    if backend == "onnxruntime":
        missing = [name for name in ("onnxruntime", "onnx", "onnxscript")
                   if not _importable(name)]
        if missing:
            raise ParameterError(
                f"backend onnxruntime needs {', '.join(missing)}: pip install 'dualpixel[onnx]'"
            )
    return backend


def backend_device(backend: str, device: str) -> torch.device:
    """Check ``backend`` and resolve ``device`` for it (``auto`` is the CPU for onnxruntime)."""
    check_backend(backend)
    return resolve_device("cpu" if backend == "onnxruntime" and device == "auto" else device)


def _importable(name: str) -> bool:
    import importlib.util

    return importlib.util.find_spec(name) is not None


def cache_dir() -> Path:
    """Where exported graphs are kept (module docstring)."""
    if os.environ.get("DUALPIXEL_CACHE_DIR"):
        return Path(os.environ["DUALPIXEL_CACHE_DIR"]) / "onnx"
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "dualpixel" / "onnx"


def _fingerprint(model: DeblurNet, step: bool) -> str:
    """SHA-256 of what the graph depends on: weights, architecture, torch version, opset."""
    digest = hashlib.sha256()
    digest.update(json.dumps({"spec": model.spec.name, "shape": repr(model.shape),
                              "step": step, "torch": torch.__version__, "opset": OPSET},
                             sort_keys=True).encode())
    for name, tensor in sorted(model.state_dict().items()):
        digest.update(name.encode())
        digest.update(tensor.detach().cpu().contiguous().numpy().tobytes())
    return digest.hexdigest()


class OnnxRuntimeNet:
    """A :class:`~dualpixel.models.unet.DeblurNet` run by ONNX Runtime on the CPU.

    Args:
        model: the network to export (once; later runs find the graph in :func:`cache_dir`).
        threads: ONNX Runtime's intra-op threads (default: torch's thread count).
        cache: the folder for exported graphs (default: :func:`cache_dir`).
        graph: an exported graph of ``model`` to run instead (``model`` then only describes
            it: :func:`load_onnx_checkpoint`).
    """

    def __init__(self, model: DeblurNet, *, threads: int | None = None,
                 cache: str | Path | None = None, graph: str | Path | None = None) -> None:
        check_backend("onnxruntime")
        import onnxruntime

        self.spec, self.shape, self.temporal = model.spec, model.shape, model.temporal
        self._state_shape = functools.partial(state_shape, model)
        folder = Path(cache) if cache is not None else cache_dir()
        path = (Path(graph) if graph is not None
                else folder / f"{_fingerprint(model, self.temporal)}.onnx")
        if graph is None and not path.is_file():  # a given graph is run, never written
            folder.mkdir(parents=True, exist_ok=True)
            batch, height, width = _EXPORT_SIZE
            export_onnx(model, path, height=height, width=width, step=self.temporal,
                        opset=OPSET, batch=batch)
        options = onnxruntime.SessionOptions()
        options.intra_op_num_threads = threads or torch.get_num_threads()
        options.inter_op_num_threads = 1
        self.path = path
        self.session = onnxruntime.InferenceSession(str(path), options,
                                                    providers=["CPUExecutionProvider"])

    def step(self, x: torch.Tensor, state: tuple[torch.Tensor, torch.Tensor] | None = None
             ) -> tuple[torch.Tensor, tuple[torch.Tensor, torch.Tensor] | None]:
        """Like :meth:`DeblurNet.step <dualpixel.models.unet.DeblurNet.step>`: ``(B, C_in, H,
        W)`` to ``(B, 3, H, W)`` float32 and the next state (None for a single-frame model)."""
        if x.ndim != 4 or x.shape[1] != self.shape.in_channels:
            raise ValueError(
                f"expected input (B, {self.shape.in_channels}, H, W), got {tuple(x.shape)}"
            )
        feeds = {"input": _numpy(x)}
        if not self.temporal:
            (out,) = self.session.run(None, feeds)
            return torch.from_numpy(out), None
        if state is None:
            zeros = torch.zeros(self._state_shape(x.shape[2], x.shape[3], x.shape[0]))
            state = (zeros, zeros)
        feeds.update(hidden=_numpy(state[0]), cell=_numpy(state[1]))
        out, hidden, cell = self.session.run(None, feeds)
        return torch.from_numpy(out), (torch.from_numpy(hidden), torch.from_numpy(cell))


def load_onnx_checkpoint(path: str | Path) -> DeblurNet:
    """The network an exported graph (``dualpixel export``) describes, untrained: what
    :class:`~dualpixel.inference.Deblurrer` needs to run the graph (``graph=path``). A graph
    traced at a fixed size is refused; a recurrent model's single-frame graph deblurs every
    frame on its own (export ``--step`` to carry the state through a sequence)."""
    from dualpixel.errors import InputFileError
    from dualpixel.inference.onnx_export import graph_metadata
    from dualpixel.models import build_model
    from dualpixel.weights import carried_settings

    check_backend("onnxruntime")
    meta = graph_metadata(path)
    if not meta.get("dynamic", True):
        raise InputFileError(path, "was exported at a fixed size; export it again (the default "
                                   "graph runs at any size)")
    try:
        model = build_model(str(meta["model"]), width=float(meta["width"]),
                            residual=bool(meta["residual"]), peepholes=bool(meta["peepholes"]),
                            refiner=tuple(int(c) for c in meta["refiner"]),
                            head_relu=bool(meta.get("head_relu", True)),
                            conv_bottleneck=bool(meta.get("conv_bottleneck", False)))
    except (KeyError, TypeError, ValueError, ParameterError) as error:
        raise InputFileError(path, f"describes no network this version builds ({error})") from None
    model.temporal = bool(meta.get("temporal", False)) and bool(meta.get("step", False))
    model.output_settings = carried_settings(meta.get("output") or {})
    if "output" not in meta:
        warnings.warn(f"{path} carries no output settings (exported by an older version): it "
                      "runs with the network's output as it gives it; export it again to run "
                      "it as its checkpoint does", stacklevel=2)
    return model.eval()


def _numpy(tensor: torch.Tensor) -> np.ndarray:
    return np.ascontiguousarray(tensor.detach().float().cpu().numpy())
