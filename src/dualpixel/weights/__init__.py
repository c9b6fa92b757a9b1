"""The project's own trained checkpoints, shipped inside the package (see MODEL_CARD.md).

``resolve_checkpoint`` accepts a registry name (``rdpd-light``) or a path to a ``.safetensors`` file
written by ``dualpixel train``.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from dualpixel.errors import InputFileError

__all__ = [
    "CHECKPOINTS", "DEFAULT_CHECKPOINT", "RETIRED_CHECKPOINTS", "model_card", "model_info",
    "register_checkpoint", "resolve_checkpoint",
]

#: name -> (file in this package, description); add entries with :func:`register_checkpoint`.
CHECKPOINTS: dict[str, tuple[str, str]] = {}


def _retired_stage(stage: int, ordinal: str, held_out: float, canon: float, minutes: int) -> str:
    """How to make a retired stage of the default again (its config, trained from the stage
    before); ``held_out`` and ``canon`` are its PSNR (dB), ``minutes`` its training time."""
    return (f"the default's {ordinal} stage ({held_out:.2f} dB held out, {canon:.2f} dB on the "
            f"Canon scenes) no longer ships; scripts/make_mix_data.sh, then "
            f"configs/rdpd-light-stage{stage}-cpu.yaml from a remade rdpd-light-stage{stage - 1} "
            f"(scripts/train_stage{stage}.sh, {minutes} CPU-minutes before the faster loss) make "
            f"it again")


#: Names that shipped once and no longer do (the wheel stays under 100 MB) -> how to get the
#: weights back. Asking for one gives that answer instead of "not found".
RETIRED_CHECKPOINTS: dict[str, str] = {
    "srdpd-light": "the first-generation model (dead-leaves scenes, 24.69 dB on the Canon dev "
                   "scenes, below their input) no longer ships; MODEL_CARD.md says how to make its "
                   "data and train it again with configs/srdpd-light-cpu.yaml (one CPU-hour)",
    "rdpd-light-stage2": "the default's second stage (27.79 dB held out, 26.06 dB on the Canon "
                         "scenes) no longer ships; scripts/make_mix_data.sh and "
                         "scripts/train_finetune.sh (configs/rdpd-light-finetune-cpu.yaml, "
                         "from rdpd-light-photo, 90 CPU-minutes) make it again",
    **{f"rdpd-light-stage{stage}": _retired_stage(stage, ordinal, held_out, canon, minutes)
       for stage, ordinal, held_out, canon, minutes in (
           (3, "third", 28.06, 26.16, 107), (4, "fourth", 28.12, 26.21, 104),
           (5, "fifth", 28.16, 26.25, 86), (6, "sixth", 28.21, 26.30, 105))},
}


def register_checkpoint(name: str, filename: str, description: str) -> None:
    """Add a shipped checkpoint to the registry; a name can be registered once only."""
    from dualpixel.errors import ParameterError

    if name in CHECKPOINTS:
        raise ParameterError(f"checkpoint name {name!r} is already registered "
                             f"({CHECKPOINTS[name][0]})")
    CHECKPOINTS[name] = (filename, description)


register_checkpoint(
    "rdpd-light", "rdpd-light.safetensors",
    "RDPD, width 0.5, residual output, trained on the CPU on photo-like synthetic frames "
    "with DSLR-like blur, in seven stages, plus a refiner trained on top in two (stages 8 and 9), "
    "then both trained together in three (stages 10 to 12; the default; improves real Canon DP "
    "photographs)",
)
register_checkpoint(
    "rdpd-light-stage11", "rdpd-light-stage11.safetensors",
    "the default's eleventh stage (the default before stage 12; the starting point of that run): "
    "stage 10 trained on, both stages together",
)
register_checkpoint(
    "rdpd-light-stage10", "rdpd-light-stage10.safetensors",
    "the default's tenth stage (the default before stage 11; the starting point of that run): "
    "stage 9 with both stages trained together",
)
register_checkpoint(
    "rdpd-light-stage9", "rdpd-light-stage9.safetensors",
    "the default's ninth stage (the default before stage 10; the starting point of that run): "
    "stage 8's refiner trained on, its first stage frozen",
)
register_checkpoint(
    "rdpd-light-stage8", "rdpd-light-stage8.safetensors",
    "the default's eighth stage (the default before stage 9; the starting point of that run): "
    "stage 7, frozen, with a refiner trained on top",
)
register_checkpoint(
    "rdpd-light-stage7", "rdpd-light-stage7.safetensors",
    "the default's seventh stage (the default before stage 8, and its first stage): stage 6 "
    "trained on 256-px crops",
)
register_checkpoint(
    "rdpd-light-photo", "rdpd-light-photo.safetensors",
    "the default's first stage: RDPD, width 0.5, residual output, 12 CPU epochs on 200 photo-like "
    "scenes (the default until it was fine-tuned on 800 more; the starting point of that run)",
)
DEFAULT_CHECKPOINT = "rdpd-light"


def resolve_checkpoint(name_or_path: str | Path) -> Path:
    """The file of a registry name, or the given path; a clear error when neither exists."""
    text = str(name_or_path)
    if text in CHECKPOINTS:
        path = Path(str(resources.files(__name__).joinpath(CHECKPOINTS[text][0])))
        if not path.is_file():
            raise InputFileError(path, f"shipped checkpoint {text!r} is missing from the package")
        return path
    if text in RETIRED_CHECKPOINTS:
        raise InputFileError(text, f"retired checkpoint: {RETIRED_CHECKPOINTS[text]}")
    path = Path(name_or_path)
    if not path.is_file():
        known = ", ".join(CHECKPOINTS)
        raise InputFileError(
            path, f"checkpoint not found (not a file, nor a registry name: {known})"
        )
    return path


def model_info() -> dict[str, dict]:
    """Per shipped checkpoint: description, architecture, parameter count, size, sha256 and the
    training metadata stored in the file (``extra``)."""
    import hashlib

    from dualpixel.models import read_metadata
    from dualpixel.models.checkpoint import build_from_metadata
    from dualpixel.models.registry import count_parameters

    info = {}
    for name, (_, description) in CHECKPOINTS.items():
        path = resolve_checkpoint(name)
        meta = read_metadata(path)
        network = build_from_metadata(meta)
        info[name] = {
            "description": description, "model": meta["model"], "width": meta["width"],
            "residual": meta["residual"], "refiner": list(meta["refiner"]),
            "temporal": meta["temporal"],
            "parameters": count_parameters(network), "bytes": path.stat().st_size,
            "sha256": hashlib.sha256(path.read_bytes()).hexdigest(),
            "training": meta["extra"],
        }
    return info


def model_card() -> str:
    """The model card (Markdown) of the shipped checkpoints."""
    return resources.files(__name__).joinpath("MODEL_CARD.md").read_text(encoding="utf-8")
