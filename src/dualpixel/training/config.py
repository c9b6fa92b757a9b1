"""Training configuration (paper Sec. 5 defaults), read from YAML or JSON with overrides.

Every run saves the resolved configuration as ``config.yaml`` in its output folder. Unknown keys
and values of the wrong type are refused with the key named.
"""

from __future__ import annotations

import dataclasses
import types
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from dualpixel.errors import ParameterError, check_range, check_seed
from dualpixel.io.atomic import atomic_path
from dualpixel.io.paths import check_plain_name
from dualpixel.models.registry import check_conv_bottleneck, check_head_relu, model_spec
from dualpixel.names import RAW_VIEWS, RENDER_ON
from dualpixel.training.losses import LOSS_REDUCTIONS, PIXEL_LOSSES

__all__ = ["LR_SCHEDULES", "TrainConfig", "load_config", "save_config"]

LR_SCHEDULES = ("step", "cosine")


#: Settings that say how a machine runs training, not what it makes (every draw is seeded per
#: item, whatever the loader): a resume may change them, and recipes leave them to the command.
MACHINE_KEYS = ("workers", "threads", "device", "cache", "frame_store", "render_on",
                "checkpoint_minutes")


@dataclass
class TrainConfig:
    """Everything a training run depends on. Defaults are the paper's (Sec. 5)."""

    # Network.
    model: str = "rdpd"
    width: float = 1.0
    peepholes: bool = True
    lstm_dropout: float = 0.4
    residual: bool = False  # ours, not the paper's: output = blurred input + network output
    # Ours: false drops the ReLU after a non-residual head's 3-channel convolution.
    head_relu: bool = True
    # Ours: true gives rdpd / rspd DPDNet's two-convolution bottleneck in place of the ConvLSTM.
    conv_bottleneck: bool = False
    # Dropout after the last encoder level and a convolution bottleneck; null: the network's
    # own (DPDNet's 0.4, the paper's; 0 for the others).
    encoder_dropout: float | None = None
    # Ours: channel widths of a second stage that corrects the output (dualpixel.models.refiner),
    # e.g. [32, 64, 128]; null: none. With init_weights of a network without one, those weights
    # go into the base network and the refiner starts as the identity.
    refiner: list[int] | None = None
    freeze_base: bool = False  # ours: train only the refiner
    # Ours: with a refiner, the base network learns at this multiple of learning_rate (on the same
    # schedule), e.g. 0.25 to fine-tune both stages together with a slower base network.
    base_lr_scale: float = 1.0
    # Data (DPDD layout). Real data: single images; synthetic data: seq_NNN sequences.
    real_data: str | None = None
    real_split: str = "train"
    # One dataset folder, or a list of them (pooled; e.g. the same scenes made with two cameras).
    synthetic_data: str | list[str] | None = None
    synthetic_split: str = "train"
    synthetic_as_frames: bool = False  # sRDPD+: synthetic frames as single images
    # Ours: synthetic folders stored as raw values (synth encoding linear) are trained on as
    # "stored" (their values read as display values) or as "model": through the encoding
    # `deblur --encoding linear` gives raw views (dualpixel.training.raw_views); also validated so.
    raw_views: str = "stored"
    val_data: str | list[str] | None = None
    val_split: str = "test"
    val_limit: int | None = None  # validate on the first N sequences only
    # Real photographs scored every epoch for the log only (DPDD layout or scene folders such as
    # ../shared/data/canon-dp-real); never used to choose a checkpoint.
    real_val_data: str | None = None
    init_weights: str | None = None  # start from these weights (same architecture), not at random
    # Ours: init_weights are of a network this one widens by an integer factor (e.g. rdpd-light's
    # base at width 0.5 into width 1.0); it starts from their function (dualpixel.models.widen).
    widen_init: bool = False
    # Ours: after loading init_weights, fresh weights for the coarsest level, the output unchanged
    # (DeblurNet.reinit_bottleneck; for a model whose bottleneck went dormant).
    reinit_bottleneck: bool = False
    # Ours: the coarsest level's learning rate (DeblurNet.coarsest_level: bottleneck, ConvLSTM,
    # first up-convolution) is this many times learning_rate, on the same schedule (1: the paper).
    coarsest_lr_scale: float = 1.0
    # Ours: a run from nothing scales each up-convolution on its first batch to the skip it joins
    # (DeblurNet.balance_levels; the ConvLSTM's output starts a third of a convolution's).
    balance_levels: bool = False
    patch_size: int = 512
    real_batch: int = 8
    sequence_batch: int = 2
    sequence_frames: int = 4
    min_sharpness: float = 0.0
    flips: bool = True
    cache: bool = False  # keep decoded images in memory (per process)
    # A folder of decoded frames, memory-mapped and shared by all loader processes
    # (dualpixel.data.frame_store; ours): PNGs are decoded once, across epochs and runs.
    frame_store: str | None = None
    # A camera's own DP photographs without targets (the blur-maps file ``dualpixel adapt``
    # writes: dualpixel.adaptation): every iteration also trains ``views_batch`` crops of them
    # on the formation loss (the output re-blurred by the camera's PSFs must give back each
    # view; in-focus blocks must keep the views), weighted by ``formation_weight`` and
    # ``in_focus_weight``, beside the losses on the data above.
    views_data: str | None = None
    views_batch: int = 2
    formation_weight: float = 1.0
    in_focus_weight: float = 1.0
    # Where on-the-fly training frames (dualpixel.synthesis.on_the_fly) are rendered: "loader"
    # (the loader's worker processes, CPU; the faster on a 16-core GPU machine, measured) or
    # "device" (on the training device, many frames at once: dualpixel.synthesis.
    # batched_renderer; by the loader's processes, each its own batches, where ``workers``).
    render_on: str = "loader"
    # Optimisation.
    epochs: int = 140
    iterations_per_epoch: int | None = None  # default: one pass over the larger dataset
    learning_rate: float = 5e-5
    lr_halve_every: int = 40
    # "step": the paper's halving every lr_halve_every epochs; "cosine" (ours): one cosine
    # decay from learning_rate towards 0 over the epochs (better for short fine-tuning runs).
    lr_schedule: str = "step"
    edge_sizes: list[int] = field(default_factory=lambda: [3, 7, 11])
    lambda_x: float = 0.03
    lambda_y: float = 0.02
    # "mean" (the paper) or "log" (ours: each patch's loss in dB, averaged; see DeblurLoss).
    loss_reduction: str = "mean"
    # The pixel term of Eq. 16: "mse" (the paper) or "charbonnier" (a smooth L1; PIXEL_LOSSES).
    pixel_loss: str = "mse"
    # Ours (BasicSR's ``ema_decay``): also keep an exponential moving average of the weights,
    # which validation, best.safetensors and last.safetensors then hold (0: off, the paper).
    ema_decay: float = 0.0
    # Running.
    seed: int = 0
    workers: int = 2
    threads: int | None = None  # torch CPU threads (None: torch's default)
    device: str = "auto"  # auto: cuda when available, else cpu
    amp: bool = True  # bfloat16 autocast on CUDA and on CPUs with native bfloat16
    channels_last: bool = True  # channels-last weights on CUDA and CPUs
    tensorboard: bool = True
    log_images: int = 2
    # Within an epoch, the state is also written (``step_state.pt``) when this many minutes
    # have passed since the last checkpoint, so a run killed mid-epoch (a session or lease that
    # ends) loses at most that much; None: at the end of each epoch only.
    checkpoint_minutes: float | None = 20.0

    def __post_init__(self) -> None:
        model_spec(self.model)
        for key in ("real_split", "synthetic_split", "val_split"):
            check_plain_name(getattr(self, key), key)
        if self.real_data is None and self.synthetic_data is None:
            raise ParameterError("give real_data, synthetic_data or both")
        if self.render_on not in RENDER_ON:
            raise ParameterError(f"render_on must be one of {', '.join(RENDER_ON)}, got "
                                 f"{self.render_on!r}")
        if self.raw_views not in RAW_VIEWS:
            raise ParameterError(f"raw_views must be one of {', '.join(RAW_VIEWS)}, got "
                                 f"{self.raw_views!r}")
        for name, most in _COUNT_LIMITS.items():  # they size work and memory: bounded
            value = getattr(self, name)
            if value is not None and not 1 <= value <= most:
                raise ParameterError(f"{name} must be between 1 and {most}, got {value}")
        # every float finite and in its range: a run must not train to NaN and exit 0
        for name, low, high in (("width", 0.0, 16.0), ("lstm_dropout", 0.0, 1.0),
                                ("learning_rate", 0.0, 1.0), ("lambda_x", 0.0, 1e3),
                                ("lambda_y", 0.0, 1e3), ("min_sharpness", 0.0, 1.0),
                                ("formation_weight", 0.0, 1e3), ("in_focus_weight", 0.0, 1e3)):
            check_range(name, getattr(self, name), low, high)
        if self.encoder_dropout is not None:
            check_range("encoder_dropout", self.encoder_dropout, 0.0, 0.95)
        if self.width <= 0 or self.lstm_dropout >= 1:
            raise ParameterError(f"width must be > 0 and lstm_dropout < 1, got {self.width} and "
                                 f"{self.lstm_dropout}")
        check_seed("seed", self.seed)
        if self.checkpoint_minutes is not None:
            check_range("checkpoint_minutes", self.checkpoint_minutes, 0.0, 1e5)
        for name, most in (("workers", 256), ("log_images", 64)):
            if not 0 <= getattr(self, name) <= most:
                raise ParameterError(f"{name} must be between 0 and {most}, got "
                                     f"{getattr(self, name)}")
        if self.lr_schedule not in LR_SCHEDULES:
            raise ParameterError(f"lr_schedule must be one of {', '.join(LR_SCHEDULES)}, "
                                 f"got {self.lr_schedule!r}")
        if self.loss_reduction not in LOSS_REDUCTIONS:
            raise ParameterError(f"loss_reduction must be one of {', '.join(LOSS_REDUCTIONS)}, "
                                 f"got {self.loss_reduction!r}")
        if self.pixel_loss not in PIXEL_LOSSES:
            raise ParameterError(f"pixel_loss must be one of {', '.join(PIXEL_LOSSES)}, "
                                 f"got {self.pixel_loss!r}")
        if self.widen_init and self.init_weights is None:
            raise ParameterError("widen_init needs init_weights (the network to widen)")
        if self.reinit_bottleneck and self.init_weights is None:
            raise ParameterError("reinit_bottleneck needs init_weights (a new network is fresh "
                                 "everywhere already)")
        if self.balance_levels and self.init_weights is not None:
            raise ParameterError("balance_levels is for a run from nothing (init_weights null): "
                                 "it rescales the up-convolutions, which would change the "
                                 "loaded network's output")
        levels = model_spec(self.model).block
        for option in ("widen_init", "reinit_bottleneck", "balance_levels"):
            if getattr(self, option) and levels != "conv":
                raise ParameterError(f"{option} is for the paper's convolution levels; model "
                                     f"{self.model!r} has {levels} levels")
        check_head_relu(self.model, residual=self.residual, head_relu=self.head_relu)
        check_conv_bottleneck(self.model, self.conv_bottleneck)
        if self.refiner is not None and (not self.refiner or min(self.refiner) < 1):
            raise ParameterError(f"refiner must list channel widths >= 1, got {self.refiner}")
        if self.freeze_base and not self.refiner:
            raise ParameterError("freeze_base needs a refiner (nothing else would train)")
        if self.freeze_base and self.coarsest_lr_scale != 1.0:
            raise ParameterError("coarsest_lr_scale has nothing to scale with freeze_base "
                                 "(the coarsest level is frozen)")
        if self.base_lr_scale <= 0:
            raise ParameterError("base_lr_scale must be > 0 (freeze_base: true "
                                 f"freezes it), got {self.base_lr_scale}")
        if self.base_lr_scale != 1.0 and (self.freeze_base or not self.refiner):
            raise ParameterError("base_lr_scale needs a refiner whose base network trains "
                                 "(refiner set, freeze_base false); without one, set "
                                 "learning_rate")
        if not 0.0 <= self.ema_decay < 1.0:
            raise ParameterError(f"ema_decay must be in [0, 1), got {self.ema_decay}")
        if self.coarsest_lr_scale <= 0:
            raise ParameterError(f"coarsest_lr_scale must be > 0, got {self.coarsest_lr_scale}")
        if self.learning_rate <= 0:
            raise ParameterError(f"learning_rate must be > 0, got {self.learning_rate}")
        if not self.edge_sizes and (self.lambda_x or self.lambda_y):
            raise ParameterError("edge_sizes is empty but lambda_x / lambda_y weigh an edge loss: "
                                 "list its kernel sizes (e.g. [3, 7, 11]) or set both to 0")
        if any(s % 2 == 0 or s < 3 for s in self.edge_sizes):
            raise ParameterError(f"edge_sizes must be odd and >= 3, got {self.edge_sizes}")

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


#: Largest value of each count a config may ask for (work and memory grow with them; an
#: epoch's batch list is built in memory).
_COUNT_LIMITS = {"patch_size": 8192, "real_batch": 4096, "sequence_batch": 4096,
                 "views_batch": 4096,
                 "sequence_frames": 256, "epochs": 100_000, "lr_halve_every": 10_000_000,
                 "iterations_per_epoch": 1_000_000, "val_limit": 10_000_000, "threads": 1024}


def _coerce(name: str, annotation: Any, value: Any) -> Any:
    """Check (and for strings from the command line, parse) one value against its annotation."""
    hint = typing.get_type_hints(TrainConfig)[name]
    options = typing.get_args(hint) if isinstance(hint, types.UnionType) else (hint,)
    if isinstance(value, str) and type(None) in options and value.lower() in ("null", "none"):
        return None  # --set val_data=null: an optional path switched off, not a file "null"
    if isinstance(value, str) and str not in options:
        try:
            value = yaml.safe_load(value)
        except yaml.YAMLError:
            raise ParameterError(f"{name}: {value!r} is not a value (a number, true/false, a "
                                 "name or a [list])") from None
        if isinstance(value, str) and float in options:  # YAML 1.1 reads "5e-4" as a string
            try:
                value = float(value)
            except ValueError:
                pass
    if value is None and type(None) in options:
        return None
    for option in options:
        origin = typing.get_origin(option) or option
        if origin is float and isinstance(value, int | float) and not isinstance(value, bool):
            return float(value)
        if origin is list and isinstance(value, list | tuple):
            (item,) = typing.get_args(option)
            if not all(isinstance(v, item) and not isinstance(v, bool) for v in value):
                raise ParameterError(f"config key {name!r}: {value!r} is not {_described(hint)}")
            return list(value)
        if origin is not type(None) and isinstance(value, origin) and not (
            origin is int and isinstance(value, bool)
        ):
            return value
    raise ParameterError(f"config key {name!r}: {value!r} is not {_described(hint)}")


def _described(hint: Any) -> str:
    """A config type in words: ``int | None`` -> "an integer or null"."""
    words = {int: "an integer", float: "a number", str: "a string", bool: "true or false",
             type(None): "null"}
    plurals = {int: "integers", float: "numbers", str: "strings", bool: "true or false values"}
    options = typing.get_args(hint) if isinstance(hint, types.UnionType) else (hint,)
    parts = []
    for option in options:
        if typing.get_origin(option) is list:
            (item,) = typing.get_args(option)
            parts.append(f"a list of {plurals.get(item, getattr(item, '__name__', item))}")
        else:
            parts.append(words.get(option, getattr(option, "__name__", str(option))))
    return " or ".join(parts)


#: Keys renamed since configs were first written: old name -> new name (the network's parts are
#: the base and the refiner). Old names are read as the new ones.
RENAMED_KEYS = {"freeze_first_stage": "freeze_base", "first_stage_lr_scale": "base_lr_scale"}


def _renamed(values: dict[str, Any], source: str) -> dict[str, Any]:
    both = [old for old, new in RENAMED_KEYS.items() if old in values and new in values]
    if both:
        raise ParameterError(f"config{source}: {both[0]} is the old name of "
                             f"{RENAMED_KEYS[both[0]]}; give only {RENAMED_KEYS[both[0]]}")
    return {RENAMED_KEYS.get(key, key): value for key, value in values.items()}


def load_config(
    path: str | Path | None = None, overrides: dict[str, Any] | None = None
) -> TrainConfig:
    """Read a YAML/JSON config file (optional) and apply ``overrides`` (key -> value or string);
    old key names (:data:`RENAMED_KEYS`) are read as their new ones."""
    values: dict[str, Any] = {}
    if path is not None:
        from dualpixel.examples import example_config
        from dualpixel.io.documents import read_mapping

        if not Path(path).exists() and example_config(str(path)) is not None:
            path = example_config(str(path))  # a shipped example by name: `--config finetune`
        path = Path(path)  # JSON is YAML too
        values.update(_renamed(read_mapping(path, "training config", syntax="yaml"),
                               f" {path}"))
    overrides = _renamed(dict(overrides or {}), " overrides (--set)")
    known = {f.name: f for f in dataclasses.fields(TrainConfig)}
    for source, keys in ((f" in {path}", set(values)), (" in the overrides (--set)",
                                                        set(overrides or {}))):
        unknown = sorted(keys - set(known))
        if unknown:
            raise ParameterError(
                f"unknown config key(s){source}: {', '.join(unknown)}; known: {', '.join(known)}"
            )
    values.update(overrides or {})
    return TrainConfig(**{k: _coerce(k, known[k].type, v) for k, v in values.items()})


def save_config(config: TrainConfig, path: str | Path) -> None:
    """Write the resolved configuration as YAML, atomically."""
    with atomic_path(path) as tmp:
        tmp.write_text(yaml.safe_dump(config.to_dict(), sort_keys=False))
