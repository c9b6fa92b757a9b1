"""The project's trained weights, shipped inside the package, as data (``registry.json``).

After torchvision's ``Weights`` and timm's ``arch.tag`` names: every shipped file has an
immutable *tag* (``rdpd-light.v12``) with its sha256, the recipe and phase that made it
(``dualpixel reproduce recipes/RECIPE --until PHASE``) and where that phase started (a phase of
the same recipe or a shipped tag, with the sha256 of those weights), its parameter count,
metrics, a one-line doc and the output settings it runs with by default; an *alias*
(``rdpd-light``, the default) names the tag it stands for today. A *preset*
(``rdpd-light-video``) is shipped weights run with other output settings (frame fusion for
video): no file of its own. Names that shipped once are in the deprecation map, which says
which recipe phase remakes them. ``dualpixel release``
(:mod:`dualpixel.training.release`) writes the files and the rows.

``resolve_checkpoint`` takes an alias, a tag, a preset or a path to a ``.safetensors`` file
written by ``dualpixel train`` / ``reproduce``.
"""

from __future__ import annotations

import copy
import functools
import hashlib
import json
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

from dualpixel.errors import InputFileError, ParameterError

__all__ = [
    "ALIASES", "DEFAULT_CHECKPOINT", "DEPRECATED", "OUTPUT_KEY", "PRESETS", "WEIGHTS",
    "Preset", "Weights",
    "carried_settings", "deprecation", "file_output_settings", "file_sha256", "list_models",
    "model_card", "model_info", "output_settings", "phase_weights", "resolve_checkpoint",
    "resolve_tag", "run_settings", "weights_folder",
]


@dataclass(frozen=True)
class Weights:
    """One shipped weight file (a row of ``registry.json``)."""

    tag: str
    file: str
    architecture: str  # a name of dualpixel.models.spec.ARCHITECTURES
    sha256: str
    recipe: str
    phase: str
    num_params: int
    doc: str
    metrics: dict[str, Any] = field(default_factory=dict)
    start: dict[str, str] | None = None  # {"phase" or "tag": NAME, "sha256": ...}; None: nothing
    output: dict[str, Any] = field(default_factory=dict)  # deblur's settings by default

    @property
    def path(self) -> Path:
        return weights_folder() / self.file


@dataclass(frozen=True)
class Preset:
    """Shipped weights run with other output settings (a row of ``registry.json``'s
    ``presets``): ``output`` over the weights' own, e.g. ``{"fuse_frames": 6}``."""

    name: str
    weights: str  # a tag of WEIGHTS
    output: dict[str, Any]
    doc: str
    metrics: dict[str, Any] = field(default_factory=dict)


def weights_folder() -> Path:
    """The package folder that holds the shipped files and ``registry.json``."""
    return Path(str(resources.files(__name__)))


def _registry() -> dict[str, Any]:
    return json.loads((weights_folder() / "registry.json").read_text("utf-8"))


_REGISTRY = _registry()
#: Shipped files by tag.
WEIGHTS: dict[str, Weights] = {tag: Weights(tag=tag, **row)
                               for tag, row in _REGISTRY["weights"].items()}
#: Alias -> the tag it stands for.
ALIASES: dict[str, str] = dict(_REGISTRY["aliases"])
#: Presets by name: shipped weights with output settings of their own.
PRESETS: dict[str, Preset] = {name: Preset(name=name, **row)
                              for name, row in _REGISTRY.get("presets", {}).items()}
#: Names that no longer ship -> {"recipe", "phase", "note"}: how to make them again.
DEPRECATED: dict[str, dict[str, str]] = dict(_REGISTRY["deprecated"])
DEFAULT_CHECKPOINT: str = _REGISTRY["default"]


def deprecation(name: str) -> str:
    """Why ``name`` no longer ships and what makes it again (its recipe and phase)."""
    entry = DEPRECATED[name]
    parts = [f"{name} no longer ships ({entry.get('note', 'retired')})"]
    if entry.get("use"):
        parts.append(f"use {entry['use']} instead")
    if entry.get("phase"):
        parts.append(f"`dualpixel reproduce recipes/{entry['recipe']} --output DIR --until "
                     f"{entry['phase']}` makes it again")
    return "; ".join(parts)


def resolve_checkpoint(name_or_path: str | Path) -> Path:
    """The file of an alias, tag or preset, or the given path; a clear error when neither
    exists."""
    text = str(name_or_path)
    tag = PRESETS[text].weights if text in PRESETS else ALIASES.get(text, text)
    if tag in WEIGHTS:
        path = WEIGHTS[tag].path
        if not path.is_file():
            raise InputFileError(path, f"shipped weights {tag!r} are missing from the package")
        return path
    if text in DEPRECATED:
        raise InputFileError(text, f"retired checkpoint: {deprecation(text)}")
    path = Path(name_or_path)
    if not path.is_file():
        known = ", ".join([*ALIASES, *WEIGHTS, *PRESETS])
        raise InputFileError(
            path, f"checkpoint not found (not a file, nor a shipped name: {known})")
    return path


def file_sha256(path: str | Path) -> str:
    """The sha256 of a file, read in blocks."""
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def resolve_tag(tag: str) -> Path:
    """The file of a shipped *tag* (not an alias: a recipe names what it starts from for good),
    checked against its sha256."""
    if tag in ALIASES:
        raise ParameterError(f"{tag!r} is an alias (of {ALIASES[tag]}); name the tag, which "
                             "never changes")
    if tag not in WEIGHTS:
        raise ParameterError(f"no shipped weights tagged {tag!r} (tags: {', '.join(WEIGHTS)})")
    path = resolve_checkpoint(tag)
    if file_sha256(path) != WEIGHTS[tag].sha256:
        raise InputFileError(path, f"sha256 differs from the registry's for {tag}")
    return path


#: The metadata key (in a checkpoint's ``extra``, and in an exported graph's description) of
#: the output settings the weights run with.
OUTPUT_KEY = "output"


def output_settings(source: Any) -> dict[str, Any]:
    """The output settings (``brightness``, ``overshoot``, ``flips``, ``fuse_frames``) a model
    runs with by default, from wherever it came: a shipped name (a preset's over its weights');
    a checkpoint file (those it carries in its
    metadata, else a shipped file's by its sha256, so a copy of one runs as it does); a loaded
    network (what it was loaded with, ``DeblurNet.output_settings``: also an exported graph's).
    Empty: the network's output as it gives it."""
    if hasattr(source, "output_settings") and not isinstance(source, (str, Path)):
        return dict(source.output_settings)
    if source is None:
        return {}
    if str(source) in PRESETS:
        preset = PRESETS[str(source)]
        return {**WEIGHTS[preset.weights].output, **preset.output}
    tag = ALIASES.get(str(source), str(source))
    if tag in WEIGHTS:
        return dict(WEIGHTS[tag].output)
    return file_output_settings(source) if Path(source).is_file() else {}


def file_output_settings(path: str | Path) -> dict[str, Any]:
    """The output settings a checkpoint file carries (see :func:`output_settings`); unreadable
    files give none (their loader names the problem). An exported graph's come with the network
    :func:`~dualpixel.inference.onnx_runtime.load_onnx_checkpoint` describes."""
    from safetensors import SafetensorError, safe_open

    path = Path(path)
    if path.suffix.lower() == ".onnx":  # read by its loader (the inference layer)
        return {}
    try:
        with safe_open(str(path), framework="numpy") as handle:
            extra = json.loads((handle.metadata() or {}).get("extra", "{}"))
        carried = extra.get(OUTPUT_KEY) if isinstance(extra, dict) else None
    except (OSError, ValueError, SafetensorError):
        return {}
    if isinstance(carried, dict):
        return carried_settings(carried)
    digest = file_sha256(path)
    shipped = [w for w in WEIGHTS.values() if w.sha256 == digest]
    return dict(shipped[0].output) if shipped else {}


def carried_settings(values: dict[str, Any]) -> dict[str, Any]:
    """The output settings among ``values`` (other keys, from a newer version, left out)."""
    return {key: values[key] for key in ("brightness", "overshoot", "flips", "fuse_frames")
            if key in values}


def run_settings(source: Any, *, brightness: str | None = None,
                 overshoot: str | None = None, flips: bool | None = None,
                 fuse_frames: int | None = None) -> dict[str, Any]:
    """The output settings a model runs with: each one given, else the model's own
    (:func:`output_settings`: a name, a file or a loaded network), else as the network gives it
    (``fuse_frames`` 1: each frame alone).

    >>> run_settings("some/file.safetensors", overshoot="limited")
    {'brightness': 'model', 'overshoot': 'limited', 'flips': False, 'fuse_frames': 1}
    """
    from dualpixel.names import DEFAULT_BRIGHTNESS, DEFAULT_OVERSHOOT

    own = output_settings(source)
    return {"brightness": brightness or own.get("brightness", DEFAULT_BRIGHTNESS),
            "overshoot": overshoot or own.get("overshoot", DEFAULT_OVERSHOOT),
            "flips": bool(own.get("flips", False)) if flips is None else bool(flips),
            "fuse_frames": own.get("fuse_frames", 1) if fuse_frames is None
            else fuse_frames}


def phase_weights(recipe: str, phase: str) -> str | None:
    """The tag of the shipped weights a recipe's phase made, if any ships."""
    for tag, weights in WEIGHTS.items():
        if weights.recipe == recipe and weights.phase == phase:
            return tag
    return None


def model_info() -> dict[str, dict]:
    """Per shipped tag and preset, what :func:`list_models` gives (a copy of its own for each
    caller)."""
    return copy.deepcopy(_model_info())


@functools.lru_cache(maxsize=1)
def _model_info() -> dict[str, dict]:
    """Per shipped tag: doc, aliases, recipe and phase, architecture (the file's header only: no
    network is built and torch is not imported), parameter count, size, sha256, metrics and the
    output settings it runs with by default; per preset, its weights' with its own doc, metrics
    and settings (``preset_of``: the tag). ``temporal``: a frame's output depends on earlier
    frames (a recurrent state carried, or frames fused)."""
    from safetensors import safe_open

    info = {}
    for tag, weights in WEIGHTS.items():
        with safe_open(str(resolve_checkpoint(tag)), framework="numpy") as handle:
            meta = handle.metadata()
        info[tag] = {
            "description": weights.doc, "aliases": [a for a, t in ALIASES.items() if t == tag],
            "recipe": weights.recipe, "phase": weights.phase,
            "architecture": weights.architecture, "model": meta["model"],
            "width": float(meta["width"]), "residual": json.loads(meta["residual"]),
            "refiner": json.loads(meta.get("refiner", "[]")),
            "temporal": json.loads(meta.get("temporal", "true")),
            "parameters": weights.num_params, "bytes": weights.path.stat().st_size,
            "sha256": weights.sha256, "metrics": weights.metrics,
            "output": run_settings(tag),
        }
        info[tag]["temporal"] = info[tag]["temporal"] or info[tag]["output"]["fuse_frames"] > 1
    for name, preset in PRESETS.items():
        output = run_settings(name)
        info[name] = {**info[preset.weights], "description": preset.doc, "aliases": [],
                      "preset_of": preset.weights, "metrics": preset.metrics, "output": output,
                      "temporal": info[preset.weights]["temporal"] or output["fuse_frames"] > 1}
    return info


def list_models() -> dict[str, dict]:
    """The shipped weights and presets with their metadata (``dualpixel models`` prints the
    same); reads file headers only, without importing torch."""
    return model_info()


def model_card() -> str:
    """The model card (Markdown) of the shipped weights."""
    return resources.files(__name__).joinpath("MODEL_CARD.md").read_text(encoding="utf-8")
