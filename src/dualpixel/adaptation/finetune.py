"""``dualpixel adapt``: a shipped model fine-tuned to one camera from a folder of its DP
photographs, no sharp targets (issue on cameras without targets).

The run folder holds, each step resuming or reused on a rerun:

- ``camera.json``: the camera (``--camera``, or measured from the views alone:
  :func:`~dualpixel.calibration.target_free.calibrate_camera_from_views`);
- ``views.json``: each pair's blur per block at that camera
  (:mod:`dualpixel.adaptation.blur_maps`);
- ``data/``: photographic scenes, an on-the-fly source formed like the camera, one formed like
  the shipped family's nearest camera (the model's own losses, so it cannot drift), and a
  held-out set of the camera written once;
- ``train/``: the training run (:mod:`dualpixel.training.trainer`: synthetic losses plus the
  formation loss on the photographs, :mod:`dualpixel.training.formation`);
- ``adapted.safetensors``: the adapted model (float16, the start's output settings, its
  provenance), which ``deblur --model``, ``export`` and ``check-model`` take as a shipped one;
- ``report.md`` / ``report.json``: the held-out PSNR and the target-free checks and formation
  residuals on the photographs, before and after.
"""

from __future__ import annotations

import dataclasses
import json
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from dualpixel.errors import InputFileError, ParameterError
from dualpixel.optics.camera import DPCamera

__all__ = ["AdaptSettings", "adapt", "read_views"]

SETTINGS_FILE = "adapt.json"
#: Fewest pairs an adaptation takes, and fewest blurred, informative blocks over them.
MIN_PAIRS = 2
MIN_BLURRED_BLOCKS = 20


@dataclass(frozen=True)
class AdaptSettings:
    """What an adaptation makes (a rerun with other settings is refused). ``model``: the start
    (a registry name or ``.safetensors``); ``camera``: a camera file or shipped name (None:
    measured from the views); ``photos``: a folder of photographs for the synthetic scenes
    (None: the package's own). Training: ``epochs`` x ``iterations`` steps of ``batch``
    synthetic crops and ``views_batch`` crops of the photographs, ``patch_size`` px."""

    model: str = "rdpd-light"
    select: tuple[str, ...] = ()  # name patterns of the pairs to take (none: every pair)
    camera: str | None = None
    photos: str | None = None
    scenes: int = 40
    epochs: int = 3
    iterations: int = 200
    batch: int = 4
    views_batch: int = 2
    patch_size: int = 192
    learning_rate: float = 5e-5
    # the formation loss on the pairs (off by default: on the synthetic proof it cost 1.5 dB
    # against synthetic data alone, docs/guide.md)
    formation_weight: float = 0.0
    in_focus_weight: float = 0.0
    seed: int = 0
    scene_size: tuple[int, int] = (840, 560)  # (width, height) px of the synthetic scenes
    # the synthetic training pairs' lossy coding, ``CODEC[:SHARE]`` or None (ViewCoding.parse)
    view_coding: str | None = None

    def __post_init__(self) -> None:
        from dualpixel.errors import check_range

        for name, low, high in (("scenes", 2, 100_000), ("epochs", 1, 10_000),
                                ("iterations", 1, 1_000_000), ("batch", 1, 4096),
                                ("views_batch", 1, 4096), ("patch_size", 64, 8192)):
            value = getattr(self, name)
            if not isinstance(value, int) or not low <= value <= high:
                raise ParameterError(f"{name} must be an integer in [{low}, {high}], got "
                                     f"{value!r}")
        for key in ("scene_size", "select"):  # lists from JSON
            if isinstance(getattr(self, key), list):
                object.__setattr__(self, key, tuple(getattr(self, key)))
        if (len(self.scene_size) != 2 or not all(isinstance(v, int) and 64 <= v <= 16384
                                                 for v in self.scene_size)):
            raise ParameterError(f"scene_size must be (width, height) in [64, 16384] px, got "
                                 f"{self.scene_size!r}")
        for name in ("learning_rate", "formation_weight", "in_focus_weight"):
            check_range(name, getattr(self, name), 0.0, 1e3)
        if self.learning_rate <= 0:
            raise ParameterError(f"learning_rate must be > 0, got {self.learning_rate}")
        if self.view_coding is not None:
            self.coding().require()  # checked now, not when the first crop is rendered

    def coding(self):
        """The training pairs' :class:`~dualpixel.synthesis.view_coding.ViewCoding`, or None."""
        from dualpixel.synthesis.view_coding import ViewCoding

        return None if self.view_coding is None else ViewCoding.parse(self.view_coding)


@dataclass
class AdaptResult:
    """Where the adapted model and its report are, and the report's figures."""

    model: Path
    report: Path
    figures: dict[str, Any]


def read_views(roots: str | Path | Sequence[str | Path], select: tuple[str, ...] = ()
               ) -> list[tuple[str, str, np.ndarray, np.ndarray]]:
    """``(left path, right path, left, right)`` of every pair under ``roots`` (folders of
    ``left``/``right`` or ``view0``/``view1``, or the DPDD layout; the first frame of a
    sequence) whose name matches one of the ``select`` patterns (``fnmatch``; none: all), views
    float32 ``(H, W, 3)`` in [0, 1] (grey copied to three channels, as the model sees it).
    Targets are never read."""
    from fnmatch import fnmatch

    from dualpixel.data.layout import discover_any
    from dualpixel.io.images import read_rgb

    roots = [roots] if isinstance(roots, (str, Path)) else list(roots)
    pairs = []
    sequences = [s for root in roots for s in discover_any(root, None, require_target=False)]
    for sequence in sequences:
        if select and not any(fnmatch(sequence.name, pattern) for pattern in select):
            continue
        frame = sequence.frames[0]
        left, right = read_rgb(frame.left), read_rgb(frame.right)
        if left.shape != right.shape:
            raise InputFileError(frame.right, f"is {right.shape[1]}x{right.shape[0]}, its left "
                                              f"view {left.shape[1]}x{left.shape[0]}")
        pairs.append((str(frame.left), str(frame.right), left, right))
    if len(pairs) < MIN_PAIRS:
        chosen = f" matching {', '.join(select)}" if select else ""
        named = ", ".join(str(r) for r in roots)
        raise InputFileError(named, f"holds {len(pairs)} DP pair(s){chosen}; adapt needs at "
                                    f"least {MIN_PAIRS}")
    return pairs


def _is_grey(pairs) -> bool:
    return all(np.array_equal(v[..., 0], v[..., 1]) and np.array_equal(v[..., 0], v[..., 2])
               for _, _, left, right in pairs for v in (left, right))


def _claim(output: Path, settings: AdaptSettings, roots: list[Path]) -> None:
    """Record the settings in a new folder; refuse a folder adapted otherwise."""
    from dualpixel.io.atomic import atomic_path

    record = json.loads(json.dumps({"pairs": [str(r.resolve()) for r in roots],
                                    **dataclasses.asdict(settings)}))  # as stored
    path = output / SETTINGS_FILE
    if path.is_file():
        from dualpixel.io.documents import read_mapping

        saved = read_mapping(path, "adaptation settings")
        changed = sorted(k for k in record if saved.get(k) != record[k])
        if changed:
            raise ParameterError(f"{output} was adapted with other settings ({', '.join(changed)}"
                                 "); choose another --output")
        return
    output.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(record, indent=2) + "\n")


def _camera(output: Path, settings: AdaptSettings, pairs, grey: bool, progress: bool, log):
    """The camera, and the blur maps where measuring it made them (else None)."""
    from dualpixel.optics.camera import load_camera

    path = output / "camera.json"
    if path.is_file():
        return load_camera(path), None
    maps = None
    if settings.camera is not None:
        camera = load_camera(settings.camera)
    else:
        from dualpixel.adaptation.blur_maps import maps_from_fit
        from dualpixel.calibration.target_free import calibrate_camera_from_views

        log(f"measuring the camera from {len(pairs)} pairs' views")
        views = [(name, *_as_calibrated(left, right, grey)) for name, _, left, right in pairs]
        with warnings.catch_warnings():  # the ends of the search are refused below
            warnings.filterwarnings("ignore", message="the disparity ratio of")
            measured = calibrate_camera_from_views(views, name="adapted", progress=progress)
        if measured.unmeasured:
            raise ParameterError(
                f"the views do not measure this camera: the disparity ratio of "
                f"{', '.join(measured.unmeasured)} ran to the end of the search (ratios "
                f"{', '.join(f'{a:g}' for a in measured.camera.disparity_ratio)}; the blur and "
                "the disparity trade against each other where the PSF shape is unlike ours); "
                "give --camera: a camera file measured with targets or PSF patterns "
                "(calibrate camera, calibrate fit-psf --camera), or the nearest shipped camera")
        camera = measured.camera
        maps = maps_from_fit(pairs, measured.fit, measured.centres, patch=48)
    camera.save(path)
    return camera, maps


def _as_calibrated(left: np.ndarray, right: np.ndarray, grey: bool):
    return (left[..., :1], right[..., :1]) if grey else (left, right)


def _blur_maps(output: Path, pairs, camera: DPCamera, measured, progress: bool):
    from dualpixel.adaptation.blur_maps import blur_maps
    from dualpixel.data.views import read_blur_maps, write_blur_maps

    path = output / "views.json"
    if not path.is_file():
        maps = measured if measured is not None else blur_maps(pairs, camera, progress=progress)
        counts = [int((m.informative & (m.radius > 1.0)).sum()) for m in maps]
        if sum(counts) < MIN_BLURRED_BLOCKS:
            listed = ", ".join(f"{Path(m.left).parent.name} {c}" for m, c in zip(maps, counts))
            raise ParameterError(f"too few blurred blocks the views can measure: {sum(counts)} "
                                 f"(need {MIN_BLURRED_BLOCKS}; per pair: {listed}); give pairs "
                                 "with textured, defocused regions")
        write_blur_maps(maps, camera, path)
    return read_blur_maps(path)[0], path


def _synth_config(camera: DPCamera | str, grey: bool, seed: int, split: str,
                  coding: dict | None = None):
    """The family recipe's synthesis settings for a colour or a grey (phone) camera, the views
    coded by ``coding`` (a ViewCoding's mapping; None: clean)."""
    from dualpixel.optics.camera import load_camera
    from dualpixel.synthesis.dataset import SynthConfig

    camera = load_camera(camera) if isinstance(camera, str) else camera
    common = dict(camera=camera.to_dict(), psf_bank="pixel4", noise_model="poisson-gaussian",
                  bit_depth=8, seed=seed, split=split, view_coding=coding)
    if grey:
        return SynthConfig(lens_sets=("phone-2016-crop", "phone-2016-close"), grey=True,
                           noise_sigmas=(0.008, 0.012, 0.018, 0.025, 0.035), **common)
    return SynthConfig(lens_sets=("dslr-840", "dslr-840-mild"),
                       noise_sigmas=(0.006, 0.009, 0.013, 0.018, 0.025), **common)


def _data(output: Path, settings: AdaptSettings, camera: DPCamera, grey: bool,
          progress: bool) -> tuple[list[str], str]:
    """Scenes, the two on-the-fly sources and the held-out set: ``(train folders, val)``."""
    from dualpixel.synthesis.dataset import synthesize_dataset
    from dualpixel.synthesis.on_the_fly import write_on_the_fly
    from dualpixel.synthesis.scenes import SceneConfig, photo_library, write_scene_folder

    data = output / "data"
    width, height = settings.scene_size
    config = SceneConfig(width=width, height=height, frames=1, layout="photographic")
    photos = photo_library(config, settings.photos)
    write_scene_folder(data / "scenes", settings.scenes, config, seed=settings.seed,
                       progress=progress, photos=photos)
    write_scene_folder(data / "val-scenes", 4, config, seed=settings.seed + 1,
                       progress=progress, photos=photos)
    family = "pixel4" if grey else "canon-840-linear"  # the shipped family's nearest camera
    coding = settings.coding()
    coding = None if coding is None else coding.as_dict()
    sources = []
    for name, source_camera, offset in (("camera-train", camera, 2), ("family-train", family, 3)):
        folder = data / name
        write_on_the_fly(folder, data / "scenes", "rgbd",
                         _synth_config(source_camera, grey, settings.seed + offset, "train",
                                       coding))
        sources.append(str(folder))
    val = data / "camera-test"
    summary = synthesize_dataset(data / "val-scenes", "rgbd", val,
                                 _synth_config(camera, grey, settings.seed + 4, "test"),
                                 workers=1, progress=progress)
    if summary["status"] != "complete":
        raise InputFileError(val, "synthesis did not finish; rerun adapt")
    return sources, str(val)


def _train_config(settings: AdaptSettings, sources: list[str], val: str, views: Path,
                  start: Path):
    from dualpixel.models.checkpoint import read_metadata
    from dualpixel.training.config import load_config

    meta = read_metadata(start)
    return load_config(None, {
        "model": meta["model"], "width": meta["width"], "peepholes": meta["peepholes"],
        "residual": meta["residual"], "head_relu": meta["head_relu"],
        "conv_bottleneck": meta["conv_bottleneck"],
        "refiner": list(meta["refiner"]) or None,
        "lstm_dropout": 0.0, "init_weights": str(start), "synthetic_data": sources,
        "synthetic_as_frames": True, "val_data": [val], "val_split": "test",
        # the pairs' crops only where a loss reads them
        "views_data": str(views) if settings.formation_weight or settings.in_focus_weight
        else None, "views_batch": settings.views_batch,
        "formation_weight": settings.formation_weight,
        "in_focus_weight": settings.in_focus_weight, "patch_size": settings.patch_size,
        "sequence_batch": settings.batch, "sequence_frames": 1, "epochs": settings.epochs,
        "iterations_per_epoch": settings.iterations, "learning_rate": settings.learning_rate,
        "lr_schedule": "cosine", "loss_reduction": "log", "ema_decay": 0.999,
        "seed": settings.seed, "workers": 0, "tensorboard": False})


def _export(run: Path, target: Path, start: Path, start_name: str, camera: DPCamera,
            settings: AdaptSettings, val_psnr: float | None) -> Path:
    """The run's best weights in float16 with the start's output settings and provenance."""
    import torch

    from dualpixel.models.checkpoint import load_model, read_metadata, save_model
    from dualpixel.models.registry import count_parameters
    from dualpixel.weights import file_sha256, output_settings

    model = load_model(run / "best.safetensors")
    started = read_metadata(start)["extra"]
    extra = {"name": f"{started.get('name', start.stem)}-adapted",
             "doc": f"{start_name} adapted to camera {camera.name!r} from its DP photographs "
                    "(dualpixel adapt)",
             "adapted_from": {"name": start_name, "sha256": file_sha256(start)},
             "camera": camera.to_dict(), "settings": dataclasses.asdict(settings),
             "num_params": count_parameters(model), "output": output_settings(start_name),
             "metrics": {} if val_psnr is None else {"camera_val_psnr": round(val_psnr, 3)}}
    save_model(target, model, dtype=torch.float16, extra=extra)
    return target


def adapt(pairs_roots: str | Path | Sequence[str | Path], output: str | Path,
          settings: AdaptSettings = AdaptSettings(), *, device: str = "auto",
          threads: int | None = None, progress: bool = True,
          log: Callable[[str], None] = print) -> AdaptResult:
    """Adapt ``settings.model`` to the camera of the DP pairs under ``pairs_roots`` (see the
    module docstring); resumes ``output``. Returns the adapted model's path and the report."""
    from dualpixel.io.lock import folder_lock
    from dualpixel.training.trainer import has_checkpoint, train
    from dualpixel.weights import resolve_checkpoint

    roots = ([Path(pairs_roots)] if isinstance(pairs_roots, (str, Path))
             else [Path(r) for r in pairs_roots])
    output = Path(output)
    start = Path(resolve_checkpoint(settings.model))
    pairs = read_views(roots, settings.select)
    _claim(output, settings, roots)
    with folder_lock(output, "adapt"):
        grey = _is_grey(pairs)
        camera, measured = _camera(output, settings, pairs, grey, progress, log)
        maps, views = _blur_maps(output, pairs, camera, measured, progress)
        log(f"camera {camera.name}: ratios {', '.join(f'{a:g}' for a in camera.disparity_ratio)}"
            f", {camera.light} light; {sum(int(m.informative.sum()) for m in maps)} measured "
            f"blocks in {len(maps)} pairs")
        sources, val = _data(output, settings, camera, grey, progress)
        config = _train_config(settings, sources, val, views, start)
        if threads is not None or device != "auto":
            config = dataclasses.replace(config, **({"threads": threads} if threads else {}),
                                         device=device)
        run = output / "train"
        result = train(config, run, resume=has_checkpoint(run), progress=progress)
        target = _export(run, output / "adapted.safetensors", start, settings.model, camera,
                         settings, result.best_psnr)
        from dualpixel.adaptation.report import write_report

        figures = write_report(output, pairs, start, target, maps, camera, val,
                               device=device, progress=progress)
    log(f"adapted model: {target}")
    return AdaptResult(target, output / "report.md", figures)
