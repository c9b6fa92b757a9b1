"""Model weights in safetensors, with the architecture in the file's metadata.

A checkpoint holds the state dict and ``{"model", "width", "peepholes", "residual", "refiner",
"head_relu", "conv_bottleneck", "format"}``
(plus free-form ``extra`` JSON), so :func:`load_model` rebuilds the right network without other
files. Weights may be
stored in half precision (``dtype=torch.float16``, for shipped models) and are loaded as float32.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import torch
from safetensors import SafetensorError
from safetensors.torch import load_file, save

from dualpixel.errors import InputFileError, ParameterError, check_range
from dualpixel.io.atomic import atomic_path
from dualpixel.models.registry import build_model, model_spec
from dualpixel.models.unet import DeblurNet

__all__ = ["build_from_metadata", "canonical_safetensors", "load_model", "load_weights",
           "read_metadata", "save_model"]

FORMAT = "dualpixel-model-1"


def _unwrap(model: torch.nn.Module) -> DeblurNet:
    return getattr(model, "module", model)  # DistributedDataParallel


def save_model(
    path: str | Path,
    model: torch.nn.Module,
    *,
    dtype: torch.dtype | None = None,
    extra: dict[str, Any] | None = None,
) -> None:
    """Write ``model``'s weights and architecture atomically to a ``.safetensors`` file."""
    net = _unwrap(model)
    tensors = {
        key: (value.to(dtype) if dtype is not None and value.is_floating_point() else value)
        .detach().cpu().contiguous()
        for key, value in net.state_dict().items()
    }
    metadata = {
        "format": FORMAT,
        "model": net.spec.name,
        "width": repr(float(net.width)),
        "peepholes": json.dumps(net.shape.peepholes),
        "residual": json.dumps(net.shape.residual),
        "refiner": json.dumps(list(net.shape.refiner)),
        "head_relu": json.dumps(net.shape.head_relu),
        "conv_bottleneck": json.dumps(net.conv_bottleneck),
        "temporal": json.dumps(bool(net.temporal)),
        "extra": json.dumps(extra or {}, sort_keys=True),
    }
    data = canonical_safetensors(save(tensors, metadata=metadata))  # in memory, so a full
    with atomic_path(path) as tmp:  # disk is a plain OSError
        tmp.write_bytes(data)


def canonical_safetensors(data: bytes) -> bytes:
    """A safetensors file's bytes with its JSON header in one order (keys sorted, compact): the
    library writes the metadata in a hash map's random order, so equal weights gave files of
    other sha256 from run to run. The tensor data and their offsets are unchanged; the header is
    padded with spaces to 8 bytes, as the format's writer does."""
    import struct

    length = struct.unpack("<Q", data[:8])[0]
    header = json.loads(data[8 : 8 + length])
    text = json.dumps(header, sort_keys=True, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 8)
    return struct.pack("<Q", len(text)) + text + data[8 + length :]


def read_metadata(path: str | Path) -> dict[str, Any]:
    """The architecture and ``extra`` stored in a checkpoint, with clear errors for bad files."""
    path = Path(path)
    if not path.is_file():
        from dualpixel.weights import ALIASES, PRESETS, WEIGHTS

        hint = (f"; {str(path)!r} is a shipped model's name: dualpixel.load_model({str(path)!r}) "
                "loads it" if str(path) in (*ALIASES, *WEIGHTS, *PRESETS) else "")
        raise InputFileError(path, "checkpoint not found" + hint)
    try:
        from safetensors import safe_open

        with safe_open(str(path), framework="pt") as handle:
            metadata = handle.metadata() or {}
    except (SafetensorError, OSError, ValueError) as error:
        raise InputFileError(path, f"not a readable safetensors checkpoint ({error})") from None
    if metadata.get("format") != FORMAT:
        raise InputFileError(path, "not a dualpixel model checkpoint (no architecture metadata)")
    missing = [key for key in ("model", "width", "peepholes") if key not in metadata]
    if missing:
        raise InputFileError(path, f"checkpoint metadata lacks {', '.join(missing)}")
    try:
        meta = _parse_metadata(metadata)
    except (ValueError, TypeError, AttributeError) as error:
        raise InputFileError(path, f"checkpoint metadata is malformed ({error})") from None
    if not (0 < meta["width"] <= MAX_WIDTH and all(1 <= w <= MAX_REFINER_WIDTH
                                                   for w in meta["refiner"])):
        raise InputFileError(path, f"checkpoint metadata asks for a network no checkpoint "
                                   f"holds (width {meta['width']}, refiner {meta['refiner']}; "
                                   f"at most {MAX_WIDTH} and {MAX_REFINER_WIDTH})")
    return meta


#: The largest network a checkpoint may describe (checked before anything is built): the width
#: factor a training config accepts, and refiner channels.
MAX_WIDTH = 16.0
MAX_REFINER_WIDTH = 4096


def _parse_metadata(metadata: dict[str, str]) -> dict[str, Any]:
    refiner = _json_value(metadata, "refiner", "[]", list)
    if not all(isinstance(w, int) and not isinstance(w, bool) for w in refiner):
        raise ValueError(f"refiner must list integer widths, got {refiner!r}")
    return {
        "model": metadata["model"],
        "width": check_range("width", float(metadata["width"])),
        "peepholes": _json_value(metadata, "peepholes", None, bool),
        "residual": _json_value(metadata, "residual", "false", bool),
        "refiner": tuple(refiner),
        "head_relu": _json_value(metadata, "head_relu", "true", bool),
        "conv_bottleneck": _json_value(metadata, "conv_bottleneck", "false", bool),
        "temporal": _temporal(metadata),
        "extra": _json_value(metadata, "extra", "{}", dict),
    }


def _json_value(metadata: dict[str, str], key: str, default: str | None, kind: type) -> Any:
    """Metadata entry ``key`` parsed as JSON and checked to be a ``kind``; a ``ValueError``
    naming the key otherwise (the header's values are strings of JSON)."""
    value = json.loads(metadata[key] if default is None else metadata.get(key, default))
    if not isinstance(value, kind) or (kind is not bool and isinstance(value, bool)):
        raise ValueError(f"{key} must be JSON {kind.__name__}, got {value!r}")
    return value


def _temporal(metadata: dict[str, str]) -> bool:
    """Whether the checkpoint's model carries state between frames (see ``DeblurNet.temporal``);
    for files written before the flag existed, from the training config they store."""
    if "temporal" in metadata:
        return _json_value(metadata, "temporal", None, bool)
    config = _json_value(metadata, "extra", "{}", dict).get("config") or {}
    if isinstance(config, dict) and config:
        return bool(config.get("synthetic_data")) and not config.get("synthetic_as_frames")
    return True


def build_from_metadata(meta: dict[str, Any], *,
                        refiner: tuple[int, ...] | None = None) -> DeblurNet:
    """A fresh network of the architecture that :func:`read_metadata` returned (random weights);
    ``refiner`` replaces the stored refiner widths (``()``: none)."""
    model_spec(meta["model"])
    return build_model(meta["model"], width=meta["width"], peepholes=meta["peepholes"],
                       residual=meta["residual"], head_relu=meta["head_relu"],
                       conv_bottleneck=meta["conv_bottleneck"],
                       refiner=meta["refiner"] if refiner is None else refiner)


def load_weights(model: torch.nn.Module, path: str | Path, *,
                 base_only: bool = False) -> None:
    """Load a checkpoint into an existing model, refusing one written for another architecture.

    ``base_only``: the checkpoint is a network without a refiner, loaded into the base network
    of ``model`` (whose refiner keeps its weights): how a refiner is trained on top of it.
    """
    path = Path(path)
    meta = read_metadata(path)
    net = _unwrap(model)
    mine = {"model": net.spec.name, "width": float(net.width),
            "peepholes": net.shape.peepholes, "residual": net.shape.residual,
            "head_relu": net.shape.head_relu, "conv_bottleneck": net.conv_bottleneck,
            "refiner": () if base_only else net.shape.refiner}
    theirs = {key: meta[key] for key in mine}
    if mine != theirs:
        raise InputFileError(path, f"checkpoint is for {theirs}, but the model is {mine}")
    tensors = load_file(str(path))
    for key, value in tensors.items():
        if value.is_floating_point() and not torch.isfinite(value).all():
            bad = int((~torch.isfinite(value)).sum())
            raise InputFileError(path, f"tensor {key} has {bad} NaN or infinite weights "
                                       "(a diverged or damaged checkpoint)")
    state = net.state_dict()
    for key, value in tensors.items():
        if key in state:
            tensors[key] = value.to(state[key].dtype)
    if base_only:
        tensors.update({k: v for k, v in state.items() if k.startswith("refiner.")})
    try:
        net.load_state_dict(tensors)
    except RuntimeError as error:
        raise InputFileError(path, f"weights do not fit the model: {error}") from None


def load_model(path: str | Path, *, device: str | torch.device = "cpu") -> DeblurNet:
    """Rebuild the network a checkpoint describes, load its weights, and put it in eval mode,
    with the output settings the file carries (``DeblurNet.output_settings``)."""
    from dualpixel.weights import file_output_settings

    if not isinstance(path, (str, Path)):
        raise ParameterError(f"load_model takes a checkpoint path, got {type(path).__name__}")
    meta = read_metadata(path)
    model = build_from_metadata(meta)
    load_weights(model, path)
    model.temporal = model.temporal and meta["temporal"]
    model.output_settings = file_output_settings(path)
    return model.to(device).eval()
