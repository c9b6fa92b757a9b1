"""Writing synthetic DP datasets in the DPDD layout the authors used, resumable and reproducible.

Layout under the output folder, for each split (train / test) and output sequence ``seq_NNN``::

    {split}_c/source/seq_NNN/NAME.png    combined blurred image (left + right) / 2
    {split}_l/source/seq_NNN/NAME.png    left view  (at the combined image's brightness, x2)
    {split}_r/source/seq_NNN/NAME.png    right view (likewise)
    {split}_c/target/seq_NNN/NAME.png    sharp all-in-focus target
    {split}_c/defocus/seq_NNN/NAME.npy   signed CoC radius in pixels, float32
    manifest.jsonl                       one JSON line per finished frame
    dataset.json                         configuration, input, version, status

Each input sequence gives one output sequence per lens set (the paper's five camera parameter
sets), numbered as the authors did: ``seq = set_index * n_inputs + input_index + 1``. With noise
off, ``combined == (left + right) / 2`` on disk up to integer rounding (the combined value is
``ceil((left + right) / 2)`` of the stored integers).

Robustness: every file is written atomically; a frame counts as done only once its manifest line
is written after its files; a rerun skips done frames and finishes the rest; ``dataset.json`` says
``"status": "complete"`` only when every frame is done. An output folder made with another
configuration or from another input is refused; one moved or copied together with its input
(a whole run folder) is the same dataset and resumes.
"""

from __future__ import annotations

import concurrent.futures
import functools
import json
import os
from collections.abc import Iterator
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path

import numpy as np
import torch

from dualpixel import __version__
from dualpixel.device import resolve_device
from dualpixel.errors import (
    InputFileError,
    OutputFileError,
    ParameterError,
    check_range,
    check_seed,
    is_integer,
)
from dualpixel.io.atomic import atomic_path, open_for_append, remove_partials
from dualpixel.io.documents import read_mapping
from dualpixel.io.dpdd import frame_paths, read_manifest
from dualpixel.io.images import check_png_compression, quantise, save_npy, write_png
from dualpixel.io.lock import folder_lock
from dualpixel.io.paths import check_plain_name, contained
from dualpixel.io.run_folder import differing_settings, locate, same_location
from dualpixel.names import renamed_keys
from dualpixel.optics.noise import PAPER_NOISE_SIGMAS, NoiseModel, check_noise_sigmas
from dualpixel.optics.psf import PSFModel, check_psf_model
from dualpixel.optics.psf_bank import PSF_BANKS
from dualpixel.optics.thin_lens import (
    DEFOCUS_PROFILES,
    PAPER_LENS_SETS,
    DefocusProfile,
    ThinLens,
    focus_from_depth,
)
from dualpixel.optics.tone import check_encoding, check_raw_storage
from dualpixel.parallel import completed
from dualpixel.progress import progress_bar
from dualpixel.synthesis.frame import (
    CameraSettings,
    SequenceDraw,
    camera_settings,
    check_base_blur_range,
    draw_sequence,
    synthesize_frame,
)
from dualpixel.synthesis.inputs import (
    InputFormat,
    InputFrame,
    InputSequence,
    discover_sequences,
    load_depth,
    load_frame,
)
from dualpixel.synthesis.layers import check_render_mode
from dualpixel.synthesis.view_coding import ViewCoding, code_views

__all__ = ["SYNTH_SETTINGS", "SynthConfig", "merge_shards", "plan_jobs", "read_manifest",
           "render_job", "render_jobs", "render_target", "synthesis_settings",
           "synthesize_dataset"]

@dataclass(frozen=True)
class SynthConfig:
    """Everything that determines a synthetic dataset's content (saved in ``dataset.json``)."""

    # What blurs each output sequence (one per input and lens set): the paper's camera
    # parameter sets setK, or blur profiles relative to the frame (dslr-840, ...).
    lens_sets: tuple[str, ...] = tuple(PAPER_LENS_SETS)
    psf_model: PSFModel = "ours"
    psf_bank: str = "paper"
    max_layers: int = 500
    render_mode: str = "fast"  # "exact": the reference renderer (slow)
    bit_depth: int = 16
    noise: bool = True
    noise_model: NoiseModel = "multiplicative"
    noise_sigmas: tuple[float, ...] = PAPER_NOISE_SIGMAS
    distortion: bool = True
    seed: int = 0
    max_depth: float = 250.0
    depth_scale: float = 0.001
    split: str = "train"
    # Ours: a calibrated camera (dualpixel.calibration.camera.DPCamera.to_dict(); ``synth
    # --camera camera.json``): its PSF shape replaces the bank (see psf_shapes) and its
    # per-channel disparity ratio is applied to every frame. None: the paper's model.
    camera: dict | None = field(default=None, hash=False)
    # Ours: with a camera, draw PSF shapes from the camera's fit ("camera") or from psf_bank
    # ("bank", the camera's ratios and light kept); None: "camera".
    psf_shapes: str | None = None
    # Ours: where the blur happens (dualpixel.optics.tone): "encoded" (the paper's) or
    # "linear"; None: the camera's, else "encoded".
    light: str | None = None
    # Ours: store every image as its green channel alone (grey PNGs), as a phone's DP data are
    # (the Google Pixel's DP views are one green channel of the raw frame).
    grey: bool = False
    # Ours: how the images store light: "srgb" (display values, as photographs and the DPDD) or
    # "linear" (raw values, as a phone's DP data: ``black_level`` plus the light times an
    # exposure gain drawn per sequence from ``raw_gains``; dualpixel.optics.tone.linear_to_raw).
    # "linear" needs light "linear".
    encoding: str = "srgb"
    black_level: float = 0.0
    raw_gains: tuple[float, float] = (1.0, 1.0)
    # Ours: a share of the stored frames have their two views lossily coded (H.264 as one
    # animation, or JPEG): dualpixel.synthesis.view_coding.ViewCoding's fields; 8-bit
    # display-encoded views only. None: no coding.
    view_coding: dict | None = field(default=None, hash=False)
    # Ours: the in-focus optics, a Gaussian std (px of the frame) drawn per sequence uniformly
    # from (low, high) and applied to both views, not the target (SequenceDraw.base_blur).
    base_blur: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        for key in ("lens_sets", "noise_sigmas", "raw_gains", "base_blur"):  # JSON or YAML lists
            if isinstance(getattr(self, key), list):
                object.__setattr__(self, key, tuple(getattr(self, key)))
        known = (*PAPER_LENS_SETS, *DEFOCUS_PROFILES)
        unknown = [c for c in self.lens_sets if c not in known]
        if unknown or not self.lens_sets:
            raise ParameterError(
                f"lens_sets must be a non-empty subset of {', '.join(known)}, got "
                f"{', '.join(self.lens_sets) or 'none'}"
            )
        if self.psf_bank not in PSF_BANKS:
            raise ParameterError(
                f"psf_bank must be one of {', '.join(PSF_BANKS)}, got {self.psf_bank!r}"
            )
        check_psf_model(self.psf_model)
        check_render_mode(self.render_mode)
        if self.bit_depth not in (8, 16):
            raise ParameterError(f"bit_depth must be 8 or 16, got {self.bit_depth}")
        check_noise_sigmas(self.noise_sigmas)
        check_range("max_depth", self.max_depth, 0.0, low_inclusive=False)
        check_range("depth_scale", self.depth_scale, 0.0, low_inclusive=False)
        check_plain_name(self.split, "split")
        check_seed("seed", self.seed)
        object.__setattr__(self, "base_blur", check_base_blur_range(self.base_blur))
        if not 1 <= self.max_layers <= 100000:
            raise ParameterError(f"max_layers must be in [1, 100000], got {self.max_layers}")
        light = self.draw_settings().light  # refuses a bad camera, light or psf_shapes now
        if check_encoding(self.encoding) == "linear":
            check_raw_storage(self.black_level, self.raw_gains)
            if light != "linear":
                raise ParameterError("encoding 'linear' (raw values) needs light 'linear': a "
                                     "sensor's values are linear in light")
        elif (self.black_level, self.raw_gains) != (0.0, (1.0, 1.0)):
            raise ParameterError("black_level and raw_gains are for encoding 'linear' (raw "
                                 "values); sRGB-encoded images have neither")
        coding = ViewCoding.from_value(self.view_coding)
        if coding is not None:
            if self.bit_depth != 8 or self.encoding != "srgb":
                raise ParameterError("view_coding codes 8-bit display-encoded views (bit_depth "
                                     "8, encoding 'srgb'); raw views are never coded")
            object.__setattr__(self, "view_coding", coding.as_dict())

    def coding(self) -> ViewCoding | None:
        """The views' lossy coding (:mod:`dualpixel.synthesis.view_coding`), or None."""
        return ViewCoding.from_value(self.view_coding)

    def draw_settings(self) -> CameraSettings:
        """The camera's settings of every sequence: :func:`camera_settings`."""
        return camera_settings(self.dp_camera(), PSF_BANKS[self.psf_bank],
                               psf_shapes=self.psf_shapes, light=self.light)

    def dp_camera(self):
        """The calibrated camera (:class:`~dualpixel.calibration.camera.DPCamera`), or None."""
        if self.camera is None:
            return None
        from dualpixel.optics.camera import DPCamera

        return DPCamera.from_dict(self.camera, "camera")

    @classmethod
    def from_dict(cls, values: dict, where: str = "dataset.json", *, warn: bool = False
                  ) -> SynthConfig:
        """The config of :meth:`as_dict` (or of a recipe's synth step), old key names taken
        (:func:`~dualpixel.names.renamed_keys`; silently for files written before a rename);
        unknown keys are a :class:`ParameterError` naming ``where``."""
        values = renamed_keys(values, where, warn=warn)
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(values) - known)
        if unknown:
            raise ParameterError(f"unknown synthesis setting(s) {', '.join(unknown)} in {where}; "
                                 f"known: {', '.join(sorted(known))}")
        return cls(**values)

    def as_dict(self) -> dict:
        data = asdict(self)
        data["lens_sets"] = list(self.lens_sets)
        data["noise_sigmas"] = list(self.noise_sigmas)
        for key in ("light", "psf_shapes"):  # as recorded before the settings existed
            if data[key] is None:
                del data[key]
        if not data["grey"]:
            del data["grey"]
        if data["view_coding"] is None:  # as recorded before view coding existed
            del data["view_coding"]
        if self.base_blur == (0.0, 0.0):  # as recorded before the in-focus blur existed
            del data["base_blur"]
        else:
            data["base_blur"] = list(self.base_blur)
        if data["encoding"] == "srgb":  # as recorded before raw storage existed
            for key in ("encoding", "black_level", "raw_gains"):
                del data[key]
        else:
            data["raw_gains"] = list(self.raw_gains)
        return data


#: Named synthesis settings, each a set of :class:`SynthConfig` values. ``"paper"``: Sec. 3's
#: (the five camera parameter sets, the 48 PSF shapes, its multiplicative noise of strength
#: 0.05-0.5: about six times a real Canon photograph's, blur in the stored values).
#: ``"shipped"``: the generic DSLR among the cameras the shipped default model was trained on
#: (``recipes/rdpd-light-cameras.yaml``, step ``dslr-train``: blur profiles dslr-840 and
#: dslr-840-mild, the broad PSF bank, blur in linear light, Poisson-Gaussian noise of a real
#: camera; a test holds them equal). ``synth`` and :func:`dualpixel.synthesize` start from
#: "shipped" (a camera file given brings its own light space); :class:`SynthConfig`'s own
#: defaults, which recipes start from, are the paper's.
SYNTH_SETTINGS: dict[str, dict] = {
    "shipped": {"lens_sets": ("dslr-840", "dslr-840-mild"), "psf_bank": "broad",
                "noise_model": "poisson-gaussian",
                "noise_sigmas": (0.006, 0.009, 0.013, 0.018, 0.025), "light": "linear"},
}
#: "paper": SynthConfig's own defaults of the same settings (the paper's, as recipes start).
SYNTH_SETTINGS["paper"] = {setting.name: setting.default for setting in fields(SynthConfig)
                           if setting.name in SYNTH_SETTINGS["shipped"]}


def synthesis_settings(name: str, *, camera: bool = False) -> dict:
    """The :data:`SYNTH_SETTINGS` of ``name``, or a :class:`ParameterError` naming the choices;
    with ``camera`` (a camera file given) the light space is left to the camera (``None``)."""
    if name not in SYNTH_SETTINGS:
        raise ParameterError(f"settings must be one of {', '.join(SYNTH_SETTINGS)}, got {name!r}")
    return {**SYNTH_SETTINGS[name], **({"light": None} if camera else {})}


@dataclass(frozen=True)
class FrameJob:
    """One output frame: inputs, draw and where it goes."""

    frame: InputFrame
    split: str
    sequence: int  # output sequence number (seq_NNN)
    index: int  # frame index within the sequence
    draw: SequenceDraw = field(compare=False)
    noise_seed: int = 0

    @property
    def key(self) -> str:
        return f"{self.split}/seq_{self.sequence:03d}/{self.frame.name}"

    def paths(self, root: Path) -> dict[str, Path]:
        paths = frame_paths(root, self.split, f"seq_{self.sequence:03d}", self.frame.name)
        return {role: paths[role] for role in ("combined", "left", "right", "target", "defocus")}


def _profile_lens(
    profile: DefocusProfile, sequence: InputSequence, fmt: InputFormat, config: SynthConfig,
    seed: tuple[int, ...],
) -> ThinLens:
    """A defocus profile's lens for a sequence: focused at the distance its ``scene.json``
    gives (procedural "photo" scenes), else at a depth percentile (10..50, drawn) of its first
    frame; the frame width scales the blur."""
    rng = np.random.default_rng((*seed, 1))
    first = sequence.frames[0]
    depth = load_depth(first, fmt, max_depth=config.max_depth, depth_scale=config.depth_scale)
    scene_file = first.rgb.parent.parent / "scene.json"
    focus = None
    if scene_file.is_file():
        description = read_mapping(scene_file, "scene description")
        if "focus_distance" not in description:
            raise InputFileError(scene_file, "expected JSON with a number 'focus_distance'")
        try:
            focus = check_range("focus_distance", description["focus_distance"], 0.0,
                                low_inclusive=False)
        except ParameterError as error:
            raise InputFileError(scene_file, str(error)) from None
    if focus is None:
        focus = focus_from_depth(depth, rng.uniform(10, 50))
    return profile.lens(rng, focus, depth.shape[1])


def plan_jobs(
    sequences: list[InputSequence], config: SynthConfig, fmt: InputFormat = "rgbd"
) -> list[FrameJob]:
    """Every output frame, with the draw of its sequence drawn from the seed."""
    jobs = []
    settings = config.draw_settings()
    for set_index, lens_set in enumerate(config.lens_sets):
        for seq_index, sequence in enumerate(sequences):
            number = set_index * len(sequences) + seq_index + 1
            seed = (config.seed, seq_index, set_index)
            distortion = config.distortion
            # a defocus profile draws a lens per sequence (its focus and blur scale)
            lens: str | ThinLens = lens_set
            if lens_set in DEFOCUS_PROFILES:
                lens = _profile_lens(DEFOCUS_PROFILES[lens_set], sequence, fmt, config, seed)
            draw = draw_sequence(
                seed, lens, psf_model=config.psf_model, **settings.draw_options(),
                distortion=distortion, noise=config.noise,
                noise_model=config.noise_model, noise_sigmas=config.noise_sigmas,
                max_layers=config.max_layers, render_mode=config.render_mode,
                raw_black_level=config.black_level if config.encoding == "linear" else None,
                raw_gains=config.raw_gains, base_blur=config.base_blur,
            )
            for index, frame in enumerate(sequence.frames):
                noise_seed = int(np.random.SeedSequence((config.seed, number, index))
                                 .generate_state(1)[0])
                jobs.append(FrameJob(frame, sequence.split, number, index, draw, noise_seed))
    return jobs


@functools.cache
def _writer_pool_of(pid: int) -> concurrent.futures.ThreadPoolExecutor:
    return concurrent.futures.ThreadPoolExecutor(max_workers=4, thread_name_prefix="png")


def _writer_pool() -> concurrent.futures.ThreadPoolExecutor:
    """This process's image writer threads (a forked worker makes its own)."""
    return _writer_pool_of(os.getpid())


def _quantise(image: torch.Tensor, bit_depth: int) -> np.ndarray:
    return quantise(image.permute(1, 2, 0).cpu().numpy(), bit_depth)


def render_job(job: FrameJob, fmt: InputFormat, config: SynthConfig, device: str = "cpu",
               window: tuple[int, int, int, int] | None = None,
               scene: tuple[np.ndarray, np.ndarray] | None = None) -> dict[str, np.ndarray]:
    """One frame as a dataset stores it: ``left``, ``right``, ``combined``, ``target`` as
    ``config.bit_depth`` integers ``(H, W, 3)`` (``(H, W)`` grey) and ``defocus`` float32
    ``(H, W)`` px: what ``synth`` writes, and what on-the-fly training crops are cut from.
    ``window`` ``(top, left, height, width)``: only that window, rendered with its blur margin
    (:func:`~dualpixel.synthesis.frame.synthesize_frame`); ``scene``: the job's RGB and depth
    (:func:`~dualpixel.synthesis.inputs.load_frame`) if already read."""
    rgb, depth = scene or load_frame(job.frame, fmt, max_depth=config.max_depth,
                                     depth_scale=config.depth_scale)
    result = synthesize_frame(rgb, depth, job.draw, noise_seed=job.noise_seed, device=device,
                              window=window)
    return _stored(result, job, config)


def render_target(job: FrameJob, config: SynthConfig, scene: tuple[np.ndarray, np.ndarray]
                  ) -> np.ndarray:
    """The stored ``target`` of :func:`render_job` of ``scene`` (the job's RGB and depth), alone:
    no views rendered."""
    from dualpixel.synthesis.frame import sharp_target

    target = _quantise(sharp_target(*scene, job.draw), config.bit_depth)
    return target[..., 1] if config.grey else target


def render_jobs(jobs: list[FrameJob], fmt: InputFormat, config: SynthConfig,
                device: str = "cpu", *,
                windows: list[tuple[int, int, int, int] | None] | None = None,
                scenes: list[tuple[np.ndarray, np.ndarray] | None] | None = None
                ) -> list[dict[str, np.ndarray]]:
    """:func:`render_job` for many frames at once, rendered together on ``device``
    (:func:`~dualpixel.synthesis.frame.synthesize_frames`: for accelerators); ``windows`` and
    ``scenes`` per job as :func:`render_job` takes them."""
    from dualpixel.synthesis.frame import synthesize_frames

    scenes = [None] * len(jobs) if scenes is None else scenes
    frames = [scene or load_frame(job.frame, fmt, max_depth=config.max_depth,
                                  depth_scale=config.depth_scale)
              for job, scene in zip(jobs, scenes)]
    results = synthesize_frames(frames, [job.draw for job in jobs],
                                [job.noise_seed for job in jobs], device=device, windows=windows)
    return [_stored(result, job, config) for result, job in zip(results, jobs)]


def _stored(result, job: FrameJob, config: SynthConfig) -> dict[str, np.ndarray]:
    """A rendered frame (:class:`~dualpixel.synthesis.frame.DPFrame`) as the dataset stores it."""
    left = _quantise(result.left, config.bit_depth)
    right = _quantise(result.right, config.bit_depth)
    if job.draw.light == "linear":  # the views' light summed, then encoded
        combined = _quantise(result.combined, config.bit_depth)
    else:  # (left + right) / 2 of the stored integers, rounded up
        combined = ((left.astype(np.uint32) + right + 1) >> 1).astype(left.dtype)
    target = _quantise(result.target, config.bit_depth)
    if config.grey:  # the green channel alone
        left, right, combined, target = (image[..., 1] for image in (left, right, combined,
                                                                     target))
    coding = config.coding()
    if coding is not None:
        coded = code_views(left, right, coding, job.noise_seed)
        if coded[0] is not left:  # the combined image of the coded views
            left, right = coded
            combined = ((left.astype(np.uint32) + right + 1) >> 1).astype(left.dtype)
    return {"left": left, "right": right, "combined": combined, "target": target,
            "defocus": result.defocus.cpu().numpy().astype(np.float32)}


def run_job(job: FrameJob, root: Path, fmt: InputFormat, config: SynthConfig,
            device: str = "cpu", png_compression: int | None = None) -> dict:
    """Synthesise and write one frame; return its manifest record."""
    return _finish_job(*_start_job(job, root, fmt, config, device, png_compression))


def _start_job(job: FrameJob, root: Path, fmt: InputFormat, config: SynthConfig,
               device: str, png_compression: int | None
               ) -> tuple[dict, list[concurrent.futures.Future]]:
    """Render one frame and hand its files to the writer threads: (its record, the writes)."""
    stored = render_job(job, fmt, config, device)
    left, right, combined, target = (stored[k] for k in ("left", "right", "combined", "target"))
    paths = job.paths(root)
    # The encoders release the GIL: the frame's files are written side by side, and all of them
    # are in place before its manifest line (the frame's commit) is returned.
    # The views are written fast (stored, level 0); the target, read again at every epoch's
    # scoring and kept longest, compressed. ``png_compression`` sets all four.
    view_level = 0 if png_compression is None else png_compression
    writes = [_writer_pool().submit(write_png, paths[name], data, bit_depth=config.bit_depth,
                                    compression=level)
              for name, data, level in (("left", left, view_level), ("right", right, view_level),
                                        ("combined", combined, view_level),
                                        ("target", target, png_compression))]
    save_npy(paths["defocus"], stored["defocus"])
    record = {
        "key": job.key,
        "input": {"rgb": str(job.frame.rgb), "depth": str(job.frame.depth)},
        "outputs": {name: str(path.relative_to(root)) for name, path in paths.items()},
        "split": job.split,
        "sequence": job.sequence,
        "frame": job.index,
        "noise_seed": job.noise_seed,
        "seed": config.seed,
        **job.draw.describe(),
        "version": __version__,
    }
    return record, writes


def _finish_job(record: dict, writes: list[concurrent.futures.Future]) -> dict:
    """Wait for a frame's files: all are in place before its record (the frame's commit)."""
    for write in writes:
        write.result()  # re-raises a failed write here
    return record


def _pipelined(jobs_args: list[tuple]) -> Iterator[dict]:
    """The jobs in order in this process, each frame's files encoded while the next renders."""
    previous = None
    for args in jobs_args:
        started = _start_job(*args)
        if previous is not None:
            yield _finish_job(*previous)
        previous = started
    if previous is not None:
        yield _finish_job(*previous)


def _check_shard(shard: tuple[int, int]) -> tuple[int, int]:
    index, count = (int(v) for v in shard)
    if count < 1 or not 0 <= index < count:
        raise ParameterError(f"shard must be K/N with 0 <= K < N, got {index}/{count}")
    return index, count


def _description(config: SynthConfig, input_dir: str | Path, fmt: InputFormat,
                 frames: int, root: Path) -> dict:
    """What ``dataset.json`` records; the input both as an absolute path and as seen from the
    dataset folder, so that a folder moved together with its input (a whole run folder moved
    or copied) is still recognised as the same dataset."""
    resolved, relative = locate(input_dir, root)
    return {
        "config": config.as_dict(),
        "input": resolved,
        "input_from_output": relative,
        "format": fmt,
        "version": __version__,
        "frames_total": frames,
        "status": "incomplete",
    }


def _shard_description(path: Path) -> dict:
    """The ``dataset.json`` of a finished ``synth --shard K/N`` folder, its keys checked:
    ``shard`` two integers 0 <= K < N, ``config`` a mapping, ``input``, ``format`` and
    ``version`` strings (anything else is an :class:`InputFileError` naming the file)."""
    description = read_mapping(path, "dataset description of `synth --shard`")
    if "shard" not in description:
        raise InputFileError(path, "is not a shard (made without --shard)")
    shard = description["shard"]
    if not (isinstance(shard, list) and len(shard) == 2
            and all(is_integer(v) for v in shard)
            and 0 <= shard[0] < shard[1]):
        raise InputFileError(path, f"shard must be [K, N] with 0 <= K < N, got {shard!r}")
    for key, kind in (("config", dict), ("input", str), ("format", str), ("version", str)):
        if not isinstance(description.get(key), kind):
            raise InputFileError(path, f"{key} must be a {'mapping' if kind is dict else 'string'}"
                                       f", got {description.get(key)!r}; not made by `synth`")
    if description.get("status") != "complete":
        raise InputFileError(path, "shard is unfinished; rerun its `synth --shard` first")
    return description


def merge_shards(shards: list[str | Path], output_dir: str | Path, *,
                 progress: bool = True) -> dict:
    """Join the folders of ``synth --shard K/N`` (all N, each complete) into ``output_dir``:
    files, manifest and ``dataset.json`` byte-identical to a single run's. The input folder the
    shards were made from must be readable here (the frame plan is rebuilt from it). A merge
    into the folder of the same merge cut short finishes it."""

    roots = [Path(s) for s in shards]
    if not roots:
        raise ParameterError("no shard folders given")
    descriptions = [_shard_description(root / "dataset.json") for root in roots]
    first = descriptions[0]
    for root, description in zip(roots, descriptions):
        for key in ("config", "input", "format", "version"):
            if description[key] != first[key]:
                raise InputFileError(root / "dataset.json", f"{key} differs from {roots[0]}'s")
    count = first["shard"][1]
    indices = sorted(d["shard"][0] for d in descriptions)
    if len(indices) != count or indices != list(range(count)) \
            or any(d["shard"][1] != count for d in descriptions):
        raise ParameterError(f"need each of the shards 0..{count - 1} of {count} exactly once, "
                             f"got {', '.join(f'{i}/{count}' for i in indices)}")
    try:
        config = SynthConfig.from_dict(dict(first["config"]), "its config")
    except ParameterError as error:
        raise InputFileError(roots[0] / "dataset.json", str(error)) from None
    sequences = discover_sequences(first["input"], first["format"], split=config.split)
    jobs = plan_jobs(sequences, config, first["format"])
    by_index = {d["shard"][0]: root for root, d in zip(roots, descriptions)}
    owner = {job.key: by_index[i % count] for i, job in enumerate(jobs)}
    records = {}
    for root in roots:
        records.update(read_manifest(root / "manifest.jsonl"))
    missing = [job.key for job in jobs if job.key not in records]
    if missing:
        raise InputFileError(owner[missing[0]] / "manifest.jsonl",
                             f"lacks {len(missing)} frame(s), e.g. {missing[0]}")
    out = Path(output_dir)
    description = _description(config, first["input"], first["format"], len(jobs), out)
    if out.exists() and any(out.iterdir()) and not _unfinished_merge(out, description):
        raise OutputFileError(out, "is not empty; merge into a new folder")
    with folder_lock(out, "merge-shards"):
        return _merge_locked(out, jobs, records, owner, description, progress)


def _unfinished_merge(out: Path, description: dict) -> bool:
    """Whether ``out`` is this merge cut short (a rerun finishes it): its ``dataset.json`` is
    the one the merge writes first, and no manifest (written last) is there."""
    path = out / "dataset.json"
    if not path.is_file() or (out / "manifest.jsonl").exists():
        return False
    return read_mapping(path, "dataset description (remove the folder and rerun)") == description


def _merge_locked(out: Path, jobs: list, records: dict, owner: dict, description: dict,
                  progress: bool) -> dict:
    """:func:`merge_shards` once it holds the output's lock: ``dataset.json`` says
    "incomplete" before the first file is copied and "complete" after the last, so a merge cut
    short never reads as a finished dataset; a rerun copies every file again."""
    import shutil

    for job in jobs:  # every path a manifest names stays inside its folders, checked first
        manifest = owner[job.key] / "manifest.jsonl"
        for relative in records[job.key]["outputs"].values():
            contained(owner[job.key], relative, manifest)
            contained(out, relative, manifest)
    remove_partials(out)  # copies a kill cut short
    _write_json(out / "dataset.json", description)  # "incomplete" until the end
    for job in progress_bar(jobs, desc="merging shards", unit="frame", enabled=progress):
        for relative in records[job.key]["outputs"].values():
            with atomic_path(out / relative) as tmp:
                shutil.copyfile(owner[job.key] / relative, tmp)
    _write_manifest(out / "manifest.jsonl", [records[job.key] for job in jobs])
    description.update(frames_done=len(jobs), status="complete")
    _write_json(out / "dataset.json", description)
    return description


def _write_manifest(path: Path, records: list[dict]) -> None:
    with atomic_path(path) as tmp:
        tmp.write_text("".join(json.dumps(r, sort_keys=True) + "\n" for r in records))


def _check_or_write_description(root: Path, description: dict) -> None:
    path = root / "dataset.json"
    if path.is_file():
        existing = read_mapping(path, "dataset description (remove the folder and rerun)")
        if isinstance(existing.get("config"), dict):  # written before a setting was renamed
            existing["config"] = renamed_keys(existing["config"], str(path), warn=False)
        mine = {k: description.get(k) for k in ("config", "format", "shard")}
        differ = differing_settings(mine, {k: existing.get(k) for k in mine})
        if not _same_input(description, existing):
            differ = sorted([*differ, "input"])
        # A run that finished no frame holds nothing to protect: new settings may take over.
        if differ and read_manifest(root / "manifest.jsonl"):
            raise InputFileError(
                root, "holds a dataset made with a different configuration (differs in "
                f"{', '.join(differ)}); choose another output folder"
            )
    _write_json(path, description)


def _same_input(mine: dict, existing: dict) -> bool:
    """Whether a dataset was made from this input: the same absolute path, or the same path
    relative to the dataset folder (both moved together)."""
    return same_location((mine["input"], mine["input_from_output"]),
                         (existing.get("input"), existing.get("input_from_output")))


def _write_json(path: Path, data: dict) -> None:
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(data, indent=2) + "\n")


def synthesize_dataset(
    input_dir: str | Path,
    fmt: InputFormat,
    output_dir: str | Path,
    config: SynthConfig | None = None,
    *,
    workers: int = 1,
    device: str = "cpu",
    progress: bool = True,
    limit: int | None = None,
    shard: tuple[int, int] | None = None,
    png_compression: int | None = None,
) -> dict:
    """Synthesise a whole dataset (see the module docstring); resumes an interrupted run.

    Args:
        input_dir: SYNTHIA-SF root or RGB-D folder.
        fmt: "synthia" or "rgbd".
        output_dir: dataset root.
        config: content settings; defaults to the paper's five lens sets, noise and distortion on.
        workers: frames rendered in parallel processes.
        device: torch device for rendering ("cpu", "cuda").
        progress: show a progress bar.
        limit: stop after this many new frames (leaves the dataset incomplete; for tests).
        shard: ``(k, n)``: render only frames ``k, k + n, k + 2n, ...`` of the plan (0 <= k < n),
            e.g. one task of a scheduler's array job; :func:`merge_shards` joins the n folders
            into the dataset a single run writes, byte for byte.
        png_compression: zlib level 0-9 of the PNGs (:func:`~dualpixel.io.images.write_png`);
            None: the views stored (level 0, fastest) and the target with OpenCV's fast
            default. Not part of the content: a run may resume with another.

    Returns:
        The ``dataset.json`` description (with ``status`` and frame counts).
    """
    config = config or SynthConfig()
    check_png_compression(png_compression)
    device = str(resolve_device(device))  # refuse an unknown or absent device before any work
    if device.startswith("cuda") and workers > 1:
        raise ParameterError("workers must be 1 on CUDA (one process drives the GPU); "
                             f"got --workers {workers}")
    root = Path(output_dir)
    sequences = discover_sequences(input_dir, fmt, split=config.split)
    jobs = plan_jobs(sequences, config, fmt)
    if shard is not None:
        shard = _check_shard(shard)
        jobs = jobs[shard[0]::shard[1]]
    with folder_lock(root, "synth"):
        return _synthesize_locked(root, jobs, input_dir, fmt, config, shard, workers, device,
                                  progress, limit, png_compression)


def _synthesize_locked(root: Path, jobs: list, input_dir, fmt, config: SynthConfig, shard,
                       workers: int, device: str, progress: bool, limit: int | None,
                       png_compression: int | None) -> dict:
    """:func:`synthesize_dataset` once it holds the folder's lock."""
    description = _description(config, input_dir, fmt, len(jobs), root)
    if shard is not None:
        description["shard"] = list(shard)
    _check_or_write_description(root, description)
    remove_partials(root)  # temporary files of writes a kill interrupted
    manifest_path = root / "manifest.jsonl"
    done = read_manifest(manifest_path)
    pending = [job for job in jobs if job.key not in done]
    if limit is not None:
        pending = pending[:limit]
    already = sum(job.key in done for job in jobs)
    bar = progress_bar(total=len(jobs), initial=already, desc="synthesising frames", unit="frame",
                       enabled=progress)
    with open_for_append(manifest_path) as manifest:
        jobs_args = [(job, root, fmt, config, device, png_compression) for job in pending]
        records = (completed(run_job, jobs_args, workers) if workers > 1
                   else _pipelined(jobs_args))
        for record in records:
            manifest.write(json.dumps(record, sort_keys=True) + "\n")
            manifest.flush()
            os.fsync(manifest.fileno())
            done[record["key"]] = record
            bar.update(1)
    bar.close()
    # The manifest is appended in completion order (a journal); rewrite it in plan order so the
    # same seed gives the same bytes whatever the number of workers or interruptions.
    _write_manifest(manifest_path, [done[job.key] for job in jobs if job.key in done])
    finished = sum(job.key in done for job in jobs)
    description.update(frames_done=finished,
                       status="complete" if finished == len(jobs) else "incomplete")
    _write_json(root / "dataset.json", description)
    return description
