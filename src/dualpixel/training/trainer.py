"""The training loop of Sec. 5: alternating real-image and synthetic-sequence iterations.

Iteration ``i`` of an epoch draws from data kind ``i % K`` (K = 1 or 2: real single images with
mini-batch 8, synthetic sequences with 2 sequences of 4 frames; ``synthetic_as_frames`` gives the
sRDPD+ setting). Adam with the learning rate halved every ``lr_halve_every`` epochs
(``lr_schedule: cosine``, ours: one cosine decay over the run instead).

A run folder holds ``config.yaml``, ``last.safetensors`` + ``last_state.pt`` (optimiser, schedule,
RNG states; written atomically after every epoch), ``best.safetensors`` (highest validation PSNR),
``history.jsonl`` (one line per epoch), ``paths.json`` (where its data folders are, seen from
the run folder, so that a run moved together with its data resumes) and ``tensorboard/``. With
``ema_decay`` (ours), an exponential moving average of the weights is kept beside them;
validation, ``best`` and ``last`` then hold the average, and ``last_state.pt`` both.
Within an epoch, ``step_state.pt`` holds the same state with the iterations done so far, written
every ``checkpoint_minutes`` (ours; a CPU epoch of a long run takes most of an hour) and removed
when the epoch's checkpoint is written. ``resume=True`` continues from the latest of the two and
gives the weights an uninterrupted run would have. Batches are drawn from seeds derived from
``(seed, epoch, kind)``, so runs are reproducible whatever the number of workers.

Multi-GPU: launch with ``torchrun --nproc-per-node N -m dualpixel train ...``; each
process takes its share of every global batch and ``DistributedDataParallel`` averages gradients.
"""

from __future__ import annotations

import io
import json
import math
import os
import pickle
import random
import time
import warnings
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import torch
import torch.distributed as dist
from torch.nn.parallel import DistributedDataParallel
from torch.optim.swa_utils import AveragedModel
from torch.utils.data import DataLoader, Dataset
from tqdm import tqdm

from dualpixel.data.dataset import DPPatchDataset, PatchConfig, RenderedOn
from dualpixel.data.layout import DPSequence, discover_dp_dataset
from dualpixel.device import resolve_device
from dualpixel.errors import InputFileError, ParameterError
from dualpixel.evaluation.metrics import psnr
from dualpixel.inference.precision import cpu_has_native_bf16
from dualpixel.io.atomic import atomic_path, remove_partials
from dualpixel.io.documents import read_mapping
from dualpixel.io.run_folder import differing_settings, locate, same_location
from dualpixel.models.checkpoint import load_model, load_weights, read_metadata, save_model
from dualpixel.models.registry import build_model
from dualpixel.models.unet import DeblurNet
from dualpixel.models.widen import widen_network
from dualpixel.progress import progress_bar
from dualpixel.training.config import MACHINE_KEYS, TrainConfig, load_config, save_config
from dualpixel.training.losses import DeblurLoss
from dualpixel.training.raw_views import RawViewsAsModel, raw_views_transform

__all__ = ["DataKind", "TrainResult", "Trainer", "resolve_device", "train", "weight_average"]


@dataclass
class DataKind:
    """One source of training batches."""

    name: str
    dataset: Dataset  # DPPatchDataset, or the views of dualpixel.data.views
    batch: int


@dataclass
class TrainResult:
    """Where a run's files are and how it ended."""

    output: Path
    epochs: int
    step: int
    best_psnr: float | None
    history: list[dict[str, Any]]


def _discover(roots: str | list[str], split: str) -> list[DPSequence]:
    """The sequences of one dataset folder or of several, in order."""
    folders = [roots] if isinstance(roots, str) else roots
    return [s for root in folders for s in discover_dp_dataset(root, split)]


def _data_kinds(config: TrainConfig) -> list[DataKind]:
    kinds = []
    common = dict(patch_size=config.patch_size, flips=config.flips,
                  min_sharpness=config.min_sharpness)
    stored = dict(cache=config.cache, store=config.frame_store)
    if config.real_data is not None:
        sequences = discover_dp_dataset(config.real_data, config.real_split)
        kinds.append(DataKind(
            "real", DPPatchDataset(sequences, PatchConfig(frames=1, **common), **stored),
            config.real_batch,
        ))
    if config.synthetic_data is not None:
        frames = 1 if config.synthetic_as_frames else config.sequence_frames
        as_frames = config.synthetic_as_frames
        batch = config.sequence_batch * (config.sequence_frames if as_frames else 1)
        patches = PatchConfig(frames=frames, **common)
        kinds.append(DataKind("synthetic", _synthetic_dataset(config, patches, stored), batch))
    return kinds


def _synthetic_dataset(config: TrainConfig, patches: PatchConfig, stored: dict[str, Any]):
    """The synthetic data: written datasets read, on-the-fly sources rendered
    (:mod:`dualpixel.synthesis.on_the_fly`), in the order ``synthetic_data`` names them."""
    from dualpixel.data.dataset import ConcatPatches
    from dualpixel.synthesis.on_the_fly import OnTheFlyDataset, SceneCache, is_on_the_fly
    from dualpixel.training.raw_views import StoredRawViews

    folders = ([config.synthetic_data] if isinstance(config.synthetic_data, str)
               else list(config.synthetic_data))
    if not any(is_on_the_fly(folder) for folder in folders):
        sequences = _discover(folders, config.synthetic_split)
        transform = raw_views_transform(folders, config.raw_views)
        return DPPatchDataset(sequences, patches, **stored, transform=transform)
    parts = []
    scenes = (SceneCache(config.frame_store) if config.frame_store is not None  # shared by
              else SceneCache() if config.cache else None)                     # the sources
    for folder in folders:
        if is_on_the_fly(folder):
            part = OnTheFlyDataset(folder, patches, scenes=scenes)
            if config.raw_views == "model" and part.raw_black_level is not None:
                part.transform = StoredRawViews(part.raw_black_level)
        else:
            part = DPPatchDataset(discover_dp_dataset(folder, config.synthetic_split), patches,
                                  **stored, transform=raw_views_transform(folder,
                                                                          config.raw_views))
        parts.append(part)
    return ConcatPatches(parts)


def _rendered_batches(dataset, batches: list[list[tuple[int, int]]], device: torch.device):
    """Batches of ``dataset``'s items for ``batches`` of keys, each batch's on-the-fly frames
    rendered together on ``device`` (:func:`~dualpixel.data.dataset.items_of`)."""
    from torch.utils.data import default_collate

    from dualpixel.data.dataset import items_of

    for keys in batches:
        yield default_collate(items_of(dataset, keys, device))


def _epoch_batches(
    config: TrainConfig, kind_index: int, kind: DataKind, epoch: int, count: int,
    rank: int, world: int,
) -> list[list[tuple[int, int]]]:
    """``count`` batches of ``(index, seed)`` for this process, fixed by (seed, epoch, kind)."""
    rng = np.random.default_rng([config.seed, epoch, kind_index])
    batches = []
    for _ in range(count):
        indices = rng.integers(len(kind.dataset), size=kind.batch)
        seeds = rng.integers(2**62, size=kind.batch)
        pairs = [(int(i), int(s)) for i, s in zip(indices, seeds)]
        batches.append(pairs[rank::world] or pairs[:1])
    return batches


def _joined(frames: torch.Tensor, more: torch.Tensor) -> list[torch.Tensor]:
    """``frames`` and ``more`` ``(B, T, C, h, w)`` as one batch where they differ only in B (one
    forward), else as two (sequences beside single frames: a forward each)."""
    if frames.shape[1:] == more.shape[1:]:
        return [torch.cat([frames, more])]
    return [frames, more]


def _iterations_per_epoch(config: TrainConfig, kinds: list[DataKind]) -> int:
    if config.iterations_per_epoch is not None:
        return config.iterations_per_epoch
    return len(kinds) * max(math.ceil(len(k.dataset) / k.batch) for k in kinds)


def fast_numerics(device: torch.device) -> bool:
    """Whether training on ``device`` uses bfloat16 autocast (config ``amp``): on CUDA, and on
    CPUs that compute bfloat16 natively, where a step takes about half the time and the model
    learns as well (``docs/benchmarks.md``)."""
    return device.type == "cuda" or (device.type == "cpu" and cpu_has_native_bf16())


def channels_last_training(device: torch.device) -> bool:
    """Whether weights and activations are laid out channels-last when config
    ``channels_last`` is on: on CUDA and on every CPU, where convolutions run faster so in
    float32 as well as in bfloat16 (``benchmarks/bench_training.py``, case ``contiguous``)."""
    return device.type in ("cuda", "cpu")


def validate(
    model: DeblurNet, sequences: list[DPSequence], device: torch.device,
    transform: RawViewsAsModel | None = None,
) -> tuple[float, dict[str, torch.Tensor] | None]:
    """Mean PSNR over whole frames of ``sequences`` (state carried through each sequence), in
    float32 whatever the machine, so that selection does not depend on it; each frame through
    ``transform`` first, as training takes it."""
    # Imported here: inference imports the training-free model code only.
    from dualpixel.inference.deblur import deblur_sequence, load_sequence_frames

    was_training = model.training
    memory = _memory_format(model)
    model.eval()
    scores, sample = [], None
    for sequence in sequences:
        frames = load_sequence_frames(sequence)
        if transform is not None:
            frames = [transform(sequence, frame) for frame in frames]
        outputs = deblur_sequence(model, frames, device=device, precision="fp32")
        for frame, output in zip(frames, outputs):
            scores.append(psnr(output, frame["target"]))
        if sample is None:
            sample = {
                "input": torch.from_numpy(frames[0]["left"]).permute(2, 0, 1),
                "output": torch.from_numpy(outputs[0]).permute(2, 0, 1),
                "target": torch.from_numpy(frames[0]["target"]).permute(2, 0, 1),
            }
    model.train(was_training)
    model.to(memory_format=memory)  # as training left it (inference converts it)
    return float(np.mean(scores)), sample


#: A ReLU head's channel positive on fewer training pixels than this is reported as dead.
DEAD_HEAD_SHARE = 0.01


class _HeadWatch:
    """Per channel of a ReLU head's 3-channel convolution (``DeblurNet.head_has_relu``), the
    share of the pixels it passes in training forwards, counted on the device until
    :meth:`close`: a channel that stays negative gets no gradient and never comes back."""

    def __init__(self, net: DeblurNet) -> None:
        self.positive = torch.zeros(3, dtype=torch.float64)
        self.total = 0
        self.handle = net.head[0].register_forward_hook(self._count)

    def _count(self, module: torch.nn.Module, args: tuple, out: torch.Tensor) -> None:
        if module.training:
            counts = (out.detach() > 0).sum(dim=(0, 2, 3), dtype=torch.float64)
            self.positive = self.positive.to(counts.device) + counts
            self.total += out[:, 0].numel()

    def close(self) -> list[float]:
        """Remove the hook; the shares counted (zeros if no training forward ran)."""
        self.handle.remove()
        return [round(float(p) / max(self.total, 1), 4) for p in self.positive.cpu()]


def _memory_format(model: torch.nn.Module) -> torch.memory_format:
    """Channels-last if the model's convolution weights are, else contiguous (judged by the
    first weight whose two layouts differ: a 1x1 kernel can be both)."""
    for weight in model.parameters():
        if weight.ndim == 4 and weight.is_contiguous() != weight.is_contiguous(
                memory_format=torch.channels_last):
            return (torch.contiguous_format if weight.is_contiguous()
                    else torch.channels_last)
    return torch.contiguous_format


def _real_validation(root: str | None) -> list[DPSequence] | None:
    """Real photographs to log: a DPDD-layout folder (its test split) or scene folders."""
    if root is None:
        return None
    from dualpixel.data.layout import discover_any

    return discover_any(root, "test", require_target=True)


def _resolve_weights(name: str) -> Path:
    """A checkpoint path, or the name of a shipped checkpoint."""
    from dualpixel.weights import resolve_checkpoint

    return Path(resolve_checkpoint(name))


def _rng_state() -> dict[str, Any]:
    state = {"torch": torch.get_rng_state(), "python": random.getstate()}
    if torch.cuda.is_available():
        state["cuda"] = torch.cuda.get_rng_state_all()
    return state


def _set_rng_state(state: dict[str, Any]) -> None:
    torch.set_rng_state(state["torch"])
    random.setstate(state["python"])
    if "cuda" in state and torch.cuda.is_available():
        torch.cuda.set_rng_state_all(state["cuda"])


# What a resume may change: the run's length and how it runs (the frame store is a cache keyed
# by its sources' content). The initial weights are read only when a run starts (the state file
# holds them after), so a starting checkpoint renamed since (a default shipped anew) resumes; the
# run folder keeps the name it started from.
_RESUME_MAY_CHANGE = ("epochs", "tensorboard", *MACHINE_KEYS)
# Settings that name data: spelt differently on resume, they must still name the same folders
# (``paths.json`` records where each pointed from the run folder: a recipe's run folder moved or
# copied with its data, or a resume from another working directory).
_PATH_SETTINGS = ("real_data", "synthetic_data", "val_data", "real_val_data")
_PATHS_FILE = "paths.json"


def _data_locations(config: TrainConfig, output: Path) -> dict[str, list[list[str | None]]]:
    """Per path setting that is set, each folder as an absolute path and from ``output``."""
    record = {}
    for key in _PATH_SETTINGS:
        value = getattr(config, key)
        if value is not None:
            folders = [value] if isinstance(value, str) else list(value)
            record[key] = [list(locate(folder, output)) for folder in folders]
    return record


def _moved_data_differs(output: Path, config: TrainConfig, saved: TrainConfig) -> list[str]:
    """The path settings whose folders are not those the run started with."""
    spelt = [k for k in _PATH_SETTINGS if getattr(config, k) != getattr(saved, k)]
    path = output / _PATHS_FILE
    if not spelt or not path.is_file():  # runs from before paths.json: compare as spelt
        return spelt
    recorded = read_mapping(path, "run folder's data paths record")
    mine = _data_locations(config, output)
    return [key for key in spelt
            if len(mine.get(key, [])) != len(recorded.get(key, []))
            or not all(same_location(tuple(a), tuple(b))
                       for a, b in zip(mine[key], recorded[key]))]


def _write_data_locations(config: TrainConfig, output: Path) -> None:
    with atomic_path(output / _PATHS_FILE) as tmp:
        tmp.write_text(json.dumps(_data_locations(config, output), indent=2) + "\n")


def _check_resumable(output: Path, config: TrainConfig) -> TrainConfig:
    """The saved run's config with what this resume may change taken from ``config`` (data
    folders too, where they are the run's own, moved); raises when anything else differs."""
    saved = load_config(output / "config.yaml")
    changed = differing_settings(config.to_dict(), saved.to_dict(),
                                 ignore=(*_RESUME_MAY_CHANGE, *_PATH_SETTINGS, "init_weights"))
    changed = sorted([*changed, *_moved_data_differs(output, config, saved)])
    if changed:
        raise ParameterError(
            f"cannot resume {output}: config differs from the saved run in {', '.join(changed)}"
        )
    return replace(saved, **{k: getattr(config, k) for k in (*_RESUME_MAY_CHANGE,
                                                              *_PATH_SETTINGS)})


def _setup_distributed(config: TrainConfig) -> tuple[int, int, torch.device]:
    """Rank, world size and device; a process group (NCCL on CUDA, else Gloo) whenever torchrun
    launched us (it sets ``WORLD_SIZE``), one process included, so that path runs on one GPU."""
    device = resolve_device(config.device)
    if "WORLD_SIZE" not in os.environ:
        return 0, 1, device
    local_rank = int(os.environ.get("LOCAL_RANK", "0"))
    if device.type == "cuda" and local_rank >= torch.cuda.device_count():
        raise ParameterError(
            f"torchrun started process {local_rank} on this node but it has "
            f"{torch.cuda.device_count()} GPU(s): give --nproc-per-node at most that, or "
            "--set device=cpu")
    if not dist.is_initialized():
        dist.init_process_group("nccl" if device.type == "cuda" else "gloo")
    if device.type == "cuda":
        device = torch.device("cuda", local_rank)
        torch.cuda.set_device(device)
    return dist.get_rank(), dist.get_world_size(), device


def train(
    config: TrainConfig, output: str | Path, *, resume: bool = False, progress: bool = True
) -> TrainResult:
    """Train ``config.model`` and write the run folder ``output`` (see the module docstring)."""
    return Trainer(config, output, resume=resume, progress=progress).run()


class Trainer:
    """One training run in named steps: :meth:`check_folder`, :meth:`build`, :meth:`restore` or
    :meth:`start`, then per epoch :meth:`train_epoch`, :meth:`validate_epoch` and
    :meth:`checkpoint`. :func:`train` runs them all."""

    def __init__(self, config: TrainConfig, output: str | Path, *, resume: bool = False,
                 progress: bool = True) -> None:
        self.config, self.output = config, Path(output)
        self.resume, self.progress = resume, progress
        self.rank, self.world, self.device = _setup_distributed(config)
        self.main = self.rank == 0
        self.start_epoch, self.step, self.best = 0, 0, None
        self.history: list[dict[str, Any]] = []
        self.writer = None
        self.init_record: dict[str, str] | None = None
        # where the epoch in progress stands when resumed from ``step_state.pt``
        self.within: dict[str, Any] | None = None
        self.last_saved = time.monotonic()
        self.from_nothing = False  # a new run without init_weights: set up on its first batch
        self.head_watch: _HeadWatch | None = None  # the epoch's, with the paper's ReLU head

    def run(self) -> TrainResult:
        import contextlib

        from dualpixel.io.lock import folder_lock

        # one writer per run folder (the main process; torchrun's others write nothing)
        threads = torch.get_num_threads()
        try:
            with folder_lock(self.output, "train") if self.main else contextlib.nullcontext():
                return self._run()
        finally:  # ``threads`` sets torch's for the run only, not for the caller afterwards
            torch.set_num_threads(threads)

    def _run(self) -> TrainResult:
        self.check_folder()
        self.build()
        self.restore() if self.resume else self.start()
        if dist.is_initialized():
            # A recurrent model skips its recurrent convolution on a sequence's first frame (zero
            # state), so single-frame batches (real pairs, sRDPD+) leave those weights unused.
            self.model = DistributedDataParallel(
                self.model, device_ids=[self.device.index] if self.device.type == "cuda" else None,
                find_unused_parameters=self.net.recurrent)
        self.writer = _summary_writer(self.output, self.config) if self.main else None
        for epoch in range(self.start_epoch, self.config.epochs):
            record = self.train_epoch(epoch)
            if self.main:
                self.validate_epoch(epoch, record)
                self.checkpoint(epoch, record)
            if dist.is_initialized():
                dist.barrier()
        if self.writer is not None:
            self.writer.close()
        return TrainResult(self.output, self.config.epochs, self.step, self.best, self.history)

    def check_folder(self) -> None:
        """Refuse to overwrite a run, or to resume what is not there or was made otherwise."""
        config, output = self.config, self.output
        if config.threads is not None:
            torch.set_num_threads(config.threads)
        has_run = has_checkpoint(output)
        if has_run and not self.resume:
            raise ParameterError(
                f"{output} already holds a training run; pass --resume to continue it")
        if self.resume and not has_run:
            raise InputFileError(output / "last_state.pt", "nothing to resume (no checkpoint yet); "
                                 "start the run again without --resume")
        if self.resume:
            resumed = _check_resumable(output, config)
            if self.main:
                remove_partials(output)  # what a killed checkpoint write left behind
                save_config(resumed, output / "config.yaml")  # e.g. a run lengthened on resume
                _write_data_locations(resumed, output)

    @property
    def averaged(self) -> DeblurNet:
        """The weights that are validated and saved: the moving average if kept, else the net."""
        return self.net if self.ema is None else self.ema.module

    def build(self) -> None:
        """Data, network, optimiser, schedule, loss and the weight average."""
        config, device = self.config, self.device
        torch.manual_seed(config.seed)
        random.seed(config.seed)
        self.kinds = _data_kinds(config)
        self.val_sequences = None
        if config.val_data is not None:
            from dualpixel.synthesis.on_the_fly import is_on_the_fly

            named = config.val_data
            for folder in [named] if isinstance(named, str) else named:
                if is_on_the_fly(folder):
                    raise ParameterError(f"val_data {folder} is an on-the-fly source; validate "
                                         "on frames written once (a synth folder)")
            self.val_sequences = _discover(config.val_data, config.val_split)[: config.val_limit]
        self.val_transform = raw_views_transform(config.val_data, config.raw_views)
        self.real_val_sequences = _real_validation(config.real_val_data)
        model = build_model(config.model, width=config.width, peepholes=config.peepholes,
                            lstm_dropout=config.lstm_dropout, residual=config.residual,
                            refiner=tuple(config.refiner or ()),
                            head_relu=config.head_relu,
                            conv_bottleneck=config.conv_bottleneck,
                            encoder_dropout=config.encoder_dropout).to(device)
        if config.freeze_base:
            for parameter in model.base_parameters():
                parameter.requires_grad_(False)
        # Single frames only (sRDPD+, real pairs): inference must not carry state between frames.
        model.temporal = model.temporal and bool(config.synthetic_data) and not (
            config.synthetic_as_frames)
        if config.channels_last and channels_last_training(device):
            model = model.to(memory_format=torch.channels_last)
        self.net = self.model = model
        self.optimizer = make_optimizer(model, config, device)
        self.scheduler = _lr_scheduler(self.optimizer, config)
        self.criterion = DeblurLoss(tuple(config.edge_sizes), config.lambda_x, config.lambda_y,
                                    config.loss_reduction, config.pixel_loss).to(device)
        self.iterations = _iterations_per_epoch(config, self.kinds)
        self.views, self.formation = None, None
        if config.views_data is not None:  # a camera's photographs: the formation loss
            from dualpixel.data.views import ViewsDataset, read_blur_maps
            from dualpixel.training.formation import FormationLoss

            maps, camera = read_blur_maps(config.views_data)
            self.views = DataKind("views", ViewsDataset(maps, config.patch_size,
                                                        flips=config.flips), config.views_batch)
            self.formation = FormationLoss(
                camera, formation_weight=config.formation_weight,
                in_focus_weight=config.in_focus_weight,
                reduction=config.loss_reduction).to(device)
        self.ema = None
        if config.ema_decay > 0:  # starts as a copy of the weights at the first update
            self.ema = weight_average(model, config.ema_decay)

    def restore(self) -> None:
        """Continue from ``last_state.pt``, the one atomic unit of a checkpoint (weights,
        optimiser, schedule, RNG): a kill while the derived files were rewritten cannot break it.
        Then from ``step_state.pt`` if it holds the epoch in progress (else, stale, removed)."""
        path, within = self.output / "last_state.pt", self.output / STEP_STATE
        if path.is_file():
            state = self._apply_state(path, self._read_state(path))
            self.start_epoch, self.step = state["epoch"] + 1, state["step"]
            self.best, self.history = state["best_psnr"], state["history"]
            if self.main:
                _write_derived(self.output, self.averaged, state["epoch"], self.step,
                               self.history, self.config, self.init_record)
        if within.is_file():
            state = self._read_state(within, within=True)
            if state["epoch"] == self.start_epoch and state["step"] >= self.step:
                self._apply_state(within, state)
                self.step, self.best = state["step"], state["best_psnr"]
                self.history = state["history"]
                # the RNG again once the epoch's loaders are made (making one draws from it)
                self.within = {**{k: state[k] for k in _WITHIN_SCHEMA}, "rng": state["rng"]}
            elif self.main:  # written in an epoch whose own checkpoint followed it
                within.unlink()
        if not path.is_file() and self.within is None:
            raise InputFileError(path, "nothing to resume (no checkpoint)")

    def _read_state(self, path: Path, *, within: bool = False) -> dict[str, Any]:
        """A state file's content, checked (tensors and plain containers only: it never runs
        code)."""
        try:
            state = torch.load(path, map_location="cpu", weights_only=True)
        except (pickle.UnpicklingError, RuntimeError, EOFError, OSError) as error:
            reason = str(error).splitlines()[0][:200]
            raise InputFileError(path, f"not a training state this version can read safely "
                                       f"({reason}); start anew or remove it") from None
        if isinstance(state, dict) and "epoch" in state and "model" not in state:
            raise InputFileError(path, "written by an older version without the weights; start "
                                       "anew")
        problem = _state_problem(state, within=within)
        if problem:
            raise InputFileError(path, f"is not a training state of this version ({problem}); "
                                       "start anew or remove it")
        return state

    def _apply_state(self, path: Path, state: dict[str, Any]) -> dict[str, Any]:
        """Weights, average, optimiser, schedule and RNG from ``state`` (read from ``path``)."""
        try:  # shapes and entries that do not fit this config's network and optimiser
            self.net.load_state_dict(state["model"])  # copied onto the parameters' device
            if self.ema is not None:
                if state.get("ema") is None:
                    raise ParameterError(f"{path} was written without ema_decay; resume it "
                                         "with ema_decay: 0 or start a new run")
                self.ema.load_state_dict(state["ema"])
            self.optimizer.load_state_dict(state["optimizer"])
            self.scheduler.load_state_dict(state["scheduler"])
            _set_rng_state(state["rng"])
        except (RuntimeError, KeyError, ValueError, TypeError, IndexError) as error:
            reason = str(error).splitlines()[0][:200] if str(error) else type(error).__name__
            raise InputFileError(path, f"does not fit this run's network or optimiser "
                                       f"({reason}); start anew or remove it") from None
        if self.config.lr_schedule == "cosine":  # on the curve of this (maybe longer) run
            factor = _cosine_factor(self.scheduler.last_epoch, self.config.epochs)
            for group in self.optimizer.param_groups:
                group["lr"] = group["initial_lr"] * factor
        if (self.output / "init.json").is_file():
            self.init_record = read_mapping(self.output / "init.json", "starting weights record")
        return state

    def start(self) -> None:
        """A new run: initial weights (``init_weights``) and the saved config."""
        if self.config.init_weights is not None:
            from dualpixel.weights import file_sha256

            path = _resolve_weights(self.config.init_weights)
            # the start, by the name given (a tag or a path, never re-resolved) and its hash
            self.init_record = {"name": self.config.init_weights, "sha256": file_sha256(path)}
            if self.config.widen_init:  # a narrower network's function, widened
                widen_network(load_model(path), self.net, seed=self.config.seed)
            else:  # a network without a refiner goes into the base of one with a refiner
                base_only = bool(self.config.refiner) and not read_metadata(path)["refiner"]
                load_weights(self.net, path, base_only=base_only)
            if self.config.reinit_bottleneck:
                self.net.reinit_bottleneck()
        else:
            self.from_nothing = True
        if self.main:
            self.output.mkdir(parents=True, exist_ok=True)
            save_config(self.config, self.output / "config.yaml")
            _write_data_locations(self.config, self.output)
            if self.init_record is not None:
                with atomic_path(self.output / "init.json") as tmp:
                    tmp.write_text(json.dumps(self.init_record) + "\n")

    def _set_up_from_nothing(self, frames: torch.Tensor) -> None:
        """Before the first step from nothing, on this batch: with ``balance_levels`` each
        up-convolution scaled to its skip (:meth:`DeblurNet.balance_levels`), then a ReLU head
        alive on half of it (:meth:`DeblurNet.centre_head`, on what the levels now give); what
        either changed is averaged over the processes, so all start alike."""
        changed = []
        if self.config.balance_levels:
            self.net.balance_levels(frames)
            changed += [t for up in self.net.upconvs for t in (up.conv.weight, up.conv.bias)]
        if self.net.head_has_relu:
            self.net.centre_head(frames)
            changed.append(self.net.head[0].bias)
        if dist.is_initialized():
            for tensor in changed:
                dist.all_reduce(tensor.data)
                tensor.data /= self.world
        self.from_nothing = False

    def train_epoch(self, epoch: int) -> dict[str, Any]:
        """One epoch of optimisation; returns its record (mean losses, seconds)."""
        config, device, kinds = self.config, self.device, self.kinds
        use_cuda = device.type == "cuda"
        amp = config.amp and fast_numerics(device)
        self.model.train()
        within, self.within = self.within or {"iteration": 0, "totals": {}, "seconds": 0.0}, None
        first = within["iteration"]  # iterations of this epoch done before a resume
        loaders = []
        for index, kind in enumerate(kinds):
            count = len(range(index, self.iterations, len(kinds)))
            batches = _epoch_batches(config, index, kind, epoch, count, self.rank, self.world)
            batches = batches[len(range(index, first, len(kinds))):]  # those not yet trained on
            source, context = kind.dataset, None
            if config.render_on == "device" and kind.name == "synthetic":
                if not config.workers:  # rendered here, all of a batch at once, on the device
                    loaders.append(_rendered_batches(kind.dataset, batches, device))
                    continue
                # each loader process renders its batches on the device (spawned: CUDA cannot
                # start in a forked process)
                source = RenderedOn(kind.dataset, device)
                context = "spawn" if device.type != "cpu" else None
            loaders.append(iter(DataLoader(
                source, batch_sampler=batches, num_workers=config.workers,
                pin_memory=use_cuda, persistent_workers=False, multiprocessing_context=context,
            )))
        views = None
        if self.views is not None:  # one batch of them with every iteration's
            batches = _epoch_batches(config, len(kinds), self.views, epoch, self.iterations,
                                     self.rank, self.world)
            views = iter(DataLoader(self.views.dataset, batch_sampler=batches[first:],
                                    num_workers=config.workers, pin_memory=use_cuda))
        if "rng" in within:
            _set_rng_state(within["rng"])
        totals: dict[str, float] = dict(within["totals"])
        started = time.perf_counter() - within["seconds"]
        if self.head_watch is not None:  # an epoch that raised left its hook
            self.head_watch.close()
        self.head_watch = _HeadWatch(self.net) if self.net.head_has_relu else None
        bar = progress_bar(range(first, self.iterations), desc=f"epoch {epoch + 1}/{config.epochs}",
                           enabled=self.progress and self.main, leave=False, initial=first,
                           total=self.iterations)
        for iteration in bar:
            kind = kinds[iteration % len(kinds)]
            item = {k: v.to(device, non_blocking=True)
                    for k, v in next(loaders[iteration % len(kinds)]).items()}
            frames = self.net.spec.make_input(item["left"], item["right"], item["radial"])
            if self.from_nothing:
                self._set_up_from_nothing(frames[:, 0])
            crops = None
            batches = [frames]
            if views is not None:  # single frames of the crop size: one forward for both
                crops = {k: v.to(device, non_blocking=True) for k, v in next(views).items()}
                batches = _joined(frames, self.net.spec.make_input(
                    crops["left"], crops["right"], crops["radial"]))
            with torch.autocast(device.type, dtype=torch.bfloat16, enabled=amp):
                outputs = [self.model(batch)[0].float() for batch in batches]
            count = item["target"].shape[0]
            loss, parts = self.criterion(outputs[0][:count], item["target"])
            if crops is not None:
                out = outputs[0][count:] if len(outputs) == 1 else outputs[1]
                extra, more = self.formation(out[:, 0], {k: v[:, 0] for k, v in crops.items()})
                loss, parts = loss + extra, {**parts, **more}
            self.optimizer.zero_grad(set_to_none=True)
            loss.backward()
            self.optimizer.step()
            if self.ema is not None:
                self.ema.update_parameters(self.net)
            self.step += 1
            values = {"loss": float(loss.detach()), **{k: float(v) for k, v in parts.items()}}
            for key, value in values.items():
                totals[key] = totals.get(key, 0.0) + value
            bar.set_postfix(loss=_shown_loss(values["loss"], self.config.loss_reduction),
                            kind=kind.name)
            if self.writer is not None:
                for key, value in values.items():
                    self.writer.add_scalar(f"train/{key}", value, self.step)
                self.writer.add_scalar("train/learning_rate",
                                       self.optimizer.param_groups[0]["lr"], self.step)
            if self.main and self._checkpoint_due() and iteration + 1 < self.iterations:
                _save_state(self.output / STEP_STATE, self, epoch, {
                    "iteration": iteration + 1, "totals": totals,
                    "seconds": time.perf_counter() - started})
                self.last_saved = time.monotonic()
        record: dict[str, Any] = {
            "epoch": epoch + 1, "step": self.step,
            "learning_rate": self.optimizer.param_groups[0]["lr"],
            **{k: v / self.iterations for k, v in totals.items()},
            "seconds": round(time.perf_counter() - started, 3),
        }
        if self.head_watch is not None:
            record["head_live"] = self.head_watch.close()
            self.head_watch = None
            dead = [c for c, share in enumerate(record["head_live"]) if share < DEAD_HEAD_SHARE]
            if dead and self.main:
                warnings.warn(
                    f"{self.output}: epoch {epoch + 1}: the head's ReLU passed channel(s) "
                    f"{', '.join(map(str, dead))} on under {DEAD_HEAD_SHARE:.0%} of the training "
                    "pixels: they no longer learn, and the output has lost that colour direction "
                    "(head_relu: false trains the head without that ReLU; docs/guide.md)",
                    stacklevel=2)
        self.scheduler.step()
        return record

    def validate_epoch(self, epoch: int, record: dict[str, Any]) -> None:
        """Synthetic validation (chooses ``best.safetensors``) and the real scenes (logged only,
        never used to choose a checkpoint)."""
        writer, step = self.writer, self.step
        if self.val_sequences:
            record["val_psnr"], sample = validate(self.averaged, self.val_sequences,
                                                  self.device, self.val_transform)
            if writer is not None:
                writer.add_scalar("val/psnr", record["val_psnr"], step)
                if sample is not None and self.config.log_images:
                    for key, image in sample.items():
                        writer.add_image(f"val/{key}", image, step)
        if self.real_val_sequences:
            record["real_val_psnr"], _ = validate(self.averaged, self.real_val_sequences,
                                                  self.device)
            if writer is not None:
                writer.add_scalar("val/real_psnr", record["real_val_psnr"], step)
        if self.val_sequences and (self.best is None or record["val_psnr"] > self.best):
            self.best = record["val_psnr"]
            save_model(self.output / "best.safetensors", self.averaged,
                       extra={"epoch": epoch + 1, "step": step, "val_psnr": self.best})

    def _checkpoint_due(self) -> bool:
        minutes = self.config.checkpoint_minutes
        return minutes is not None and time.monotonic() - self.last_saved >= 60.0 * minutes

    def checkpoint(self, epoch: int, record: dict[str, Any]) -> None:
        """Append the record and write the checkpoint (state file first, then derived files,
        then the epoch's ``step_state.pt`` goes: a kill before that leaves it stale)."""
        self.history.append(record)
        _save_state(self.output / "last_state.pt", self, epoch)
        _write_derived(self.output, self.averaged, epoch, self.step, self.history, self.config,
                       self.init_record)
        (self.output / STEP_STATE).unlink(missing_ok=True)
        self.last_saved = time.monotonic()
        if self.writer is not None:
            self.writer.flush()
        tqdm.write(json.dumps(record))  # one line per epoch, bars or not (logs of long runs)


def _parameter_groups(model: DeblurNet, config: TrainConfig) -> list[dict[str, Any]]:
    """Adam's parameter groups, one per learning rate, the base rate first (the schedule scales
    all alike): with ``base_lr_scale`` the base network of a refined network and with
    ``coarsest_lr_scale`` the coarsest level learn at those multiples of ``learning_rate`` (the
    coarsest level is in the base network: both apply). Frozen parameters
    (``freeze_base``) are left out."""
    first = set()
    if model.refiner is not None:
        first = {id(p) for p in model.base_parameters()}
    coarse = {id(p) for module in model.coarsest_level() for p in module.parameters()}
    by_scale: dict[float, list[torch.nn.Parameter]] = {1.0: []}
    for parameter in model.parameters():
        if not parameter.requires_grad:
            continue
        scale = config.base_lr_scale if id(parameter) in first else 1.0
        if id(parameter) in coarse:
            scale *= config.coarsest_lr_scale
        by_scale.setdefault(scale, []).append(parameter)
    return [{"params": params, "lr": config.learning_rate * scale}
            for scale, params in by_scale.items() if params]


def _cosine_factor(epoch: int, epochs: int) -> float:
    """The cosine schedule's multiplier of the learning rate in ``epoch`` (0-based)."""
    return 0.5 * (1.0 + math.cos(math.pi * epoch / epochs))


def _lr_scheduler(optimizer: torch.optim.Optimizer, config: TrainConfig):
    """Per-epoch schedule: halving every ``lr_halve_every`` epochs (Sec. 5) or one cosine decay."""
    if config.lr_schedule == "cosine":  # closed form in the epoch: a resumed run follows it
        epochs = config.epochs
        return torch.optim.lr_scheduler.LambdaLR(
            optimizer, lambda epoch: _cosine_factor(epoch, epochs))
    return torch.optim.lr_scheduler.StepLR(optimizer, config.lr_halve_every, gamma=0.5)


def make_optimizer(model: torch.nn.Module, config: TrainConfig,
                   device: torch.device) -> torch.optim.Adam:
    """Adam (Sec. 5) over :func:`_parameter_groups`, fused into one kernel per step on the CPU
    and CUDA (the same update; measured on the default model's 7.5 M parameters on 2 busy cores:
    0.2 s a step against 1.5 s for the per-tensor loop)."""
    fused = device.type in ("cpu", "cuda")
    return torch.optim.Adam(_parameter_groups(model, config), lr=config.learning_rate,
                            fused=fused or None)


def weight_average(model: torch.nn.Module, decay: float) -> AveragedModel:
    """An exponential moving average of ``model``'s weights and buffers (``ema_decay``; see
    :func:`_ema_update`): call ``update_parameters(model)`` after each optimiser step and use
    ``.module``. The first update copies the weights."""
    return AveragedModel(model, multi_avg_fn=_ema_update(decay), use_buffers=True)


def _ema_update(decay: float):
    """``multi_avg_fn`` of :class:`AveragedModel`: ``avg <- d * avg + (1 - d) * weights`` with
    ``d = min(decay, (1 + n) / (10 + n))`` after ``n`` updates (TensorFlow's warm-up), so a run
    from random weights does not average them in for thousands of steps."""

    def update(averaged: list[torch.Tensor], current: list[torch.Tensor],
               num_averaged: torch.Tensor) -> None:
        n = float(num_averaged)
        weight = 1.0 - min(decay, (1.0 + n) / (10.0 + n))
        pairs = list(zip(averaged, current, strict=True))
        floating = [pair for pair in pairs if pair[0].is_floating_point()]
        if floating:  # one foreach kernel (AveragedModel passes a device and dtype per call)
            torch._foreach_lerp_([a for a, _ in floating], [c for _, c in floating], weight)
        for avg, value in pairs:
            if not avg.is_floating_point():  # integer buffers follow the weights
                avg.copy_(value)

    return update


def _cpu_state(module: torch.nn.Module) -> dict[str, torch.Tensor]:
    return {k: v.detach().cpu().clone() for k, v in module.state_dict().items()}


def _shown_loss(loss: float, reduction: str) -> str:
    """The loss as the progress bar shows it: with ``loss_reduction: log`` it is the mean of
    ``10 log10`` of each patch's loss, a level in dB (-20.2 dB: a patch error of about 1 %),
    not a negative error."""
    return f"{loss:.2f} dB" if reduction == "log" else f"{loss:.4g}"


#: What ``last_state.pt`` holds: each entry and its type (:func:`_save_state`).
_STATE_SCHEMA: dict[str, type | tuple[type, ...]] = {
    "model": dict, "ema": (dict, type(None)), "optimizer": dict, "scheduler": dict, "epoch": int,
    "step": int, "best_psnr": (float, int, type(None)), "history": list, "rng": dict}


#: What ``step_state.pt`` holds beside :data:`_STATE_SCHEMA` (its ``epoch`` is the one in
#: progress): iterations done, their summed losses and seconds.
_WITHIN_SCHEMA: dict[str, type | tuple[type, ...]] = {
    "iteration": int, "totals": dict, "seconds": (float, int)}

#: The state file of the epoch in progress (see the module docstring).
STEP_STATE = "step_state.pt"


def has_checkpoint(folder: str | Path) -> bool:
    """Whether a run folder holds a state to resume (an epoch's or one within an epoch)."""
    return (Path(folder) / "last_state.pt").is_file() or (Path(folder) / STEP_STATE).is_file()


def _state_problem(state: Any, *, within: bool = False) -> str | None:
    """What makes ``state`` not a training state of :func:`_save_state`, or None."""
    if not isinstance(state, dict):
        return f"a {type(state).__name__}, not a mapping"
    schema = {**_STATE_SCHEMA, **_WITHIN_SCHEMA} if within else _STATE_SCHEMA
    for key, kind in schema.items():
        if key not in state:
            return f"no {key!r} entry"
        if not isinstance(state[key], kind) or isinstance(state[key], bool):
            return f"{key!r} is a {type(state[key]).__name__}"
    if state["epoch"] < 0 or state["step"] < 0:
        return "a negative epoch or step"
    if not all(isinstance(record, dict) for record in state["history"]):
        return "'history' holds an entry that is not a record"
    return None


def _save_state(path: Path, trainer: Trainer, epoch: int,
                within: dict[str, Any] | None = None) -> None:
    """One atomic checkpoint file (weights, their average, optimiser/schedule/RNG state):
    ``last_state.pt`` after epoch ``epoch``, written before the files derived from it
    (:func:`_write_derived`), or ``step_state.pt`` within it (``within``:
    :data:`_WITHIN_SCHEMA`)."""
    ema = trainer.ema
    state = {"model": _cpu_state(trainer.net), "ema": None if ema is None else _cpu_state(ema),
             "optimizer": trainer.optimizer.state_dict(),
             "scheduler": trainer.scheduler.state_dict(), "epoch": epoch, "step": trainer.step,
             "best_psnr": trainer.best, "history": trainer.history, "rng": _rng_state(),
             **(within or {})}
    buffer = io.BytesIO()  # serialised in memory: a full disk is then a plain OSError
    torch.save(state, buffer)
    with atomic_path(path) as tmp:
        tmp.write_bytes(buffer.getbuffer())


def _write_derived(output: Path, net: DeblurNet, epoch: int, step: int,
                   history: list[dict[str, Any]], config: TrainConfig,
                   init: dict[str, str] | None = None) -> None:
    """``last.safetensors`` and ``history.jsonl`` from the checkpoint's content; rewritten on
    resume, so a kill between the state file and these cannot leave them stale. ``init``: the
    starting weights' name and sha256."""
    save_model(output / "last.safetensors", net,
               extra={"epoch": epoch + 1, "step": step, "config": config.to_dict(),
                      "init": init})
    with atomic_path(output / "history.jsonl") as tmp:
        tmp.write_text("".join(json.dumps(r) + "\n" for r in history))


def _summary_writer(output: Path, config: TrainConfig):
    if not config.tensorboard:
        return None
    try:
        from torch.utils.tensorboard import SummaryWriter
    except ImportError:  # tensorboard is an optional extra
        tqdm.write("tensorboard is not installed; pip install 'dualpixel[train]' for logs")
        return None
    return SummaryWriter(str(output / "tensorboard"))
