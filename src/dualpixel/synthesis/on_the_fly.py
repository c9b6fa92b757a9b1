"""Training crops rendered on the fly from RGB-D scenes, instead of read from a written dataset.

A written dataset (``dualpixel synth``) fixes each frame's camera, PSF shape, noise and
exposure once, when it is written. An on-the-fly source keeps only the recipe: its folder holds
:data:`ON_THE_FLY_FILE` (the scenes folder, its format and the :class:`~dualpixel.synthesis.
dataset.SynthConfig`), and every training sample draws its own lens set, focus, PSF shape,
distortion, noise and raw exposure from that config, with the seed the sampler hands it, as
``synth`` draws them per sequence (:func:`~dualpixel.synthesis.dataset.plan_jobs`), renders the
frame exactly as ``synth`` stores it (:func:`~dualpixel.synthesis.dataset.render_job`: the same
quantisation, grey channel and combined image) and cuts the crop from it as
:class:`~dualpixel.data.dataset.DPPatchDataset` cuts crops from files. So a crop equals the
same region of a written frame with the same draw, and the samples follow the written
dataset's distributions; only the files are gone.

Only the crop is rendered: the crop's place is chosen on the frame's sharp target (as from
files), then its views are rendered with the whole frame's layers over the crop and its blur
margin (:func:`~dualpixel.synthesis.frame.synthesize_frame`'s ``window``), equal to the crop of
the whole frame's render to a level of rounding where the distortion moves it, exactly where
none does.

Training names such a folder wherever it names a dataset (``synthetic_data``; a recipe's synth
step with ``source: on-the-fly``); validation stays on datasets written once. Sources given
one :class:`SceneCache` (training's ``cache``, ``reproduce --cache``) decode each scene's RGB
and depth once per process and share them: about 3.3 MB a 840x560 scene; with training's
``frame_store`` (``reproduce --frame-store``) once for all processes, mapped from that folder.
"""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from dualpixel.data.dataset import DPPatchDataset, PatchConfig
from dualpixel.errors import InputFileError, ParameterError
from dualpixel.io.atomic import atomic_path

__all__ = ["ON_THE_FLY_FILE", "OnTheFlyDataset", "SceneCache", "is_on_the_fly",
           "write_on_the_fly", "write_samples"]

#: The file that makes a folder an on-the-fly source.
ON_THE_FLY_FILE = "on-the-fly.json"


def is_on_the_fly(folder: str | Path) -> bool:
    """Whether ``folder`` is an on-the-fly source (holds :data:`ON_THE_FLY_FILE`)."""
    return (Path(folder) / ON_THE_FLY_FILE).is_file()


def write_on_the_fly(folder: str | Path, input_dir: str | Path, fmt: str, config) -> Path:
    """Make ``folder`` an on-the-fly source of ``input_dir`` (RGB-D scenes in ``fmt``) under
    ``config`` (:class:`~dualpixel.synthesis.dataset.SynthConfig`): every scene is checked
    first (depth present, finite and positive; sizes), so a bad one is named before any
    training. Written atomically; returns the descriptor's path."""
    source = _Source(str(Path(input_dir).resolve()), fmt, config)
    source.check()
    root = Path(folder)
    root.mkdir(parents=True, exist_ok=True)
    path = root / ON_THE_FLY_FILE
    record = {"input": source.input, "format": fmt, "config": config.as_dict()}
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(record, indent=2, sort_keys=True) + "\n")
    return path


@dataclass(frozen=True)
class _Source:
    input: str
    fmt: str
    config: object  # SynthConfig

    @classmethod
    def read(cls, folder: str | Path) -> _Source:
        from dualpixel.io.documents import read_mapping
        from dualpixel.synthesis.dataset import SynthConfig

        path = Path(folder) / ON_THE_FLY_FILE
        record = read_mapping(path, "on-the-fly source", syntax="json")
        try:
            return cls(str(record["input"]), str(record["format"]),
                       SynthConfig(**record["config"]))
        except (KeyError, TypeError, ParameterError) as error:
            raise InputFileError(path, f"not an on-the-fly source description ({error})") from None

    def sequences(self):
        from dualpixel.synthesis.inputs import discover_sequences

        return discover_sequences(self.input, self.fmt, split=self.config.split)

    def check(self) -> None:
        """Every scene's depth read (:func:`~dualpixel.synthesis.inputs.load_depth` refuses
        NaN, infinite and non-positive depth, naming the file) and its size matched to its
        RGB's header."""
        from dualpixel.io.images import image_size
        from dualpixel.synthesis.inputs import load_depth

        for sequence in self.sequences():
            for frame in sequence.frames:
                depth = load_depth(frame, self.fmt, max_depth=self.config.max_depth,
                                   depth_scale=self.config.depth_scale)
                if image_size(frame.rgb) != depth.shape:
                    raise InputFileError(frame.depth, f"depth is {depth.shape[1]}x"
                                                      f"{depth.shape[0]}, unlike {frame.rgb}")


@dataclass(frozen=True)
class _Sequence:
    """What :class:`DPPatchDataset` needs of a sequence, for one scene and lens set."""

    name: str
    height: int
    width: int
    frames: tuple
    scene: int
    lens_set: int


class OnTheFlyDataset(DPPatchDataset):
    """Crops of frames rendered on the fly (see the module's text): ``(index, seed)`` items as
    :class:`DPPatchDataset` gives, one index per scene and lens set, the draw from the seed.
    ``transform`` as for :class:`DPPatchDataset`; ``scenes``: where decoded scenes are kept
    (None: each item reads its scene's files).

    Rendering runs where the item is made: in the DataLoader's worker processes (CPU).
    """

    def __init__(self, folder: str | Path, config: PatchConfig, *,
                 scenes: SceneCache | None = None, transform=None):
        from dualpixel.io.images import image_size

        self.source = _Source.read(folder)
        self.scenes = self.source.sequences()
        lens_sets = self.source.config.lens_sets
        sequences = []
        for s, scene in enumerate(self.scenes):
            height, width = image_size(scene.frames[0].rgb)
            for c, lens_set in enumerate(lens_sets):
                sequences.append(_Sequence(f"{scene.name}/{lens_set}", height, width,
                                           scene.frames, s, c))
        super().__init__(sequences, config, transform=transform)
        self.scene_cache = scenes

    @property
    def raw_black_level(self) -> float | None:
        """The black level (of full scale) its frames are stored above, None for display
        values (see :mod:`dualpixel.training.raw_views`)."""
        config = self.source.config
        return float(config.black_level) if config.encoding == "linear" else None

    def job(self, index: int, seed: int, frame: int):
        """The frame job of sequence ``index``'s frame ``frame`` under the draw of ``seed``:
        ``synth``'s own plan for that scene and lens set, with ``seed`` as its seed."""
        from dualpixel.synthesis.dataset import plan_jobs

        sequence = self.sequences[index]
        config = dataclasses.replace(self.source.config, seed=int(seed) % 2**31,
                                     lens_sets=(self.source.config.lens_sets[sequence.lens_set],))
        return plan_jobs([self.scenes[sequence.scene]], config, self.source.fmt)[frame]

    def _frames(self, index: int, start: int, rng: np.random.Generator) -> list:
        """The frames' draws, each with its whole sharp target (what the crop's place is chosen
        on): the views are rendered for the crop alone (:meth:`_cut`)."""
        seed = int(rng.integers(2**62))
        frames = range(start, start + self.config.frames)
        if self._batch is not None:  # render_items: each frame's target made once for its passes
            return [self._batch.frame(self, (index, seed, k)) for k in frames]
        return [self._pending(self.job(index, seed, k)) for k in frames]

    def _pending(self, job) -> _Pending:
        from dualpixel.synthesis.dataset import render_target
        from dualpixel.synthesis.inputs import load_frame

        config = self.source.config
        read = dict(max_depth=config.max_depth, depth_scale=config.depth_scale)
        scene = (load_frame(job.frame, self.source.fmt, **read) if self.scene_cache is None
                 else self.scene_cache.load(job.frame, self.source.fmt, **read))
        target = _as_read(render_target(job, config, scene), config.bit_depth)
        return _Pending(job, scene, target)

    def _cut(self, frame, top: int, left: int, height: int, width: int
             ) -> dict[str, np.ndarray]:
        """The crop's views rendered with their blur margin alone (the same region of the whole
        frame's render to float rounding), the target cut from the frame's."""
        if not isinstance(frame, _Pending):
            return super()._cut(frame, top, left, height, width)
        if self._batch is not None:  # rendered beforehand, all at once (render_items)
            return self._batch.rendered[id(frame), (top, left, height, width)]
        from dualpixel.synthesis.dataset import render_job

        whole = (top, left, height, width) == (0, 0, *frame.target.shape[:2])
        stored = render_job(frame.job, self.source.fmt, self.source.config, scene=frame.scene,
                            window=None if whole else (top, left, height, width))
        return self._as_crop(frame, stored, (top, left, height, width))

    def _as_crop(self, frame: _Pending, stored: dict[str, np.ndarray],
                 window: tuple[int, int, int, int]) -> dict[str, np.ndarray]:
        """A crop's rendered views (stored integers) as read from files, with the target cut
        from the frame's."""
        top, left, height, width = window
        bits = self.source.config.bit_depth
        return {"left": _as_read(stored["left"], bits), "right": _as_read(stored["right"], bits),
                "target": frame.target[top : top + height, left : left + width]}

    _batch: _Batch | None = None

    def render_items(self, keys: list[tuple[int, int]], device) -> list[dict[str, torch.Tensor]]:
        """The items of ``keys`` (``(index, seed)``), as ``dataset[key]`` gives them, their crops
        rendered together on ``device`` (:func:`~dualpixel.synthesis.dataset.render_jobs` with
        windows): training renders on its GPU so. The same draws, crops and flips as in the
        loader, each crop with its blur margin alone; the noise is drawn by ``device``'s
        generator."""
        from dualpixel.synthesis.dataset import render_jobs

        self._batch = batch = _Batch()
        try:
            wanted = {}  # (frame, window) of every crop, in the order the items cut them
            for key in keys:
                placement = self.placed(key)
                for frame in placement.frames:
                    wanted[id(frame), placement.window] = (frame, placement.window)
            stored = render_jobs([frame.job for frame, _ in wanted.values()], self.source.fmt,
                                 self.source.config, device,
                                 windows=[window for _, window in wanted.values()],
                                 scenes=[frame.scene for frame, _ in wanted.values()])
            for (name, (frame, window)), views in zip(wanted.items(), stored):
                batch.rendered[name] = self._as_crop(frame, views, window)
            return [self[key] for key in keys]
        finally:
            self._batch = None

    def _frames_of_job(self, job) -> dict[str, np.ndarray]:
        """One job's frame as :func:`~dualpixel.data.layout.read_frame` reads it from the files
        ``synth`` would write: ``left``, ``right``, ``target`` float32 ``(H, W, 3)``."""
        from dualpixel.synthesis.dataset import render_job

        stored = render_job(job, self.source.fmt, self.source.config)
        return {key: _as_read(stored[key], self.source.config.bit_depth)
                for key in ("left", "right", "target")}


@dataclass(frozen=True)
class _Pending:
    """A frame whose views are not rendered yet: its job, RGB and depth, and its whole sharp
    target (as read) for the choice of the crop."""

    job: object  # FrameJob
    scene: tuple[np.ndarray, np.ndarray]
    target: np.ndarray

    def __getitem__(self, key: str) -> np.ndarray:
        if key != "target":
            raise KeyError(key)
        return self.target


class _Batch:
    """What :meth:`OnTheFlyDataset.render_items` keeps between its passes over the items: each
    frame made once (its draw, scene and target), and the crops rendered for them."""

    def __init__(self) -> None:
        self.frames: dict[tuple[int, int, int], _Pending] = {}
        self.rendered: dict[tuple[int, tuple[int, int, int, int]], dict[str, np.ndarray]] = {}

    def frame(self, dataset: OnTheFlyDataset, key: tuple[int, int, int]) -> _Pending:
        """Frame ``key`` ``(sequence index, seed, frame)`` of ``dataset``, made on first use."""
        if key not in self.frames:
            self.frames[key] = dataset._pending(dataset.job(*key))
        return self.frames[key]


class SceneCache:
    """Scene frames decoded once and kept in memory (RGB as 8-bit where that is lossless),
    for the on-the-fly sources of one process that read the same scenes; or, given ``store``
    (a :class:`~dualpixel.data.frame_store.FrameStore` folder), decoded once for every process
    and mapped from there (loader processes, which end every epoch, and runs after)."""

    def __init__(self, store: str | Path | None = None) -> None:
        from dualpixel.data.frame_store import FrameStore

        self._scenes: dict[tuple, tuple[np.ndarray, np.ndarray]] = {}
        self._store = None if store is None else FrameStore(store)

    def __len__(self) -> int:
        return len(self._scenes)

    def load(self, frame, fmt: str, *, max_depth: float, depth_scale: float
             ) -> tuple[np.ndarray, np.ndarray]:
        """A frame's RGB ``(H, W, 3)`` float32 in [0, 1] and depth ``(H, W)`` as
        :func:`~dualpixel.synthesis.inputs.load_frame` reads them, the files read on the first
        call only; each call gets its own copies."""
        from dualpixel.data.frame_store import compact_frame, expand
        from dualpixel.synthesis.inputs import load_frame

        read = dict(max_depth=max_depth, depth_scale=depth_scale)
        if self._store is not None:
            rgb, depth = self._store.load_scene(frame.rgb, frame.depth,
                                                f"{fmt}\0{max_depth!r}\0{depth_scale!r}",
                                                lambda: load_frame(frame, fmt, **read))
        else:
            key = (str(frame.rgb), str(frame.depth), fmt, max_depth, depth_scale)
            if key not in self._scenes:
                rgb, depth = load_frame(frame, fmt, **read)
                self._scenes[key] = (compact_frame({"rgb": rgb})["rgb"], depth)
            rgb, depth = self._scenes[key]
        image = expand(rgb)
        return (np.array(image) if image is rgb else image), np.array(depth)


def _as_read(image: np.ndarray, bit_depth: int) -> np.ndarray:
    """Stored integers as :func:`~dualpixel.io.images.read_rgb` returns the file written from
    them: float32 ``(H, W, 3)`` in [0, 1], grey copied to the three channels."""
    from dualpixel.io.images import max_level

    values = image.astype(np.float32) / max_level(bit_depth)
    if values.ndim == 2:
        values = np.repeat(values[:, :, None], 3, axis=2)
    return values


def write_samples(dataset: OnTheFlyDataset, output: str | Path, count: int, *,
                  seed: int = 0) -> Path:
    """``count`` whole frames of ``dataset``, each with its own draw, written in the DPDD layout
    (split ``train``) for ``dualpixel stats``: what the source trains on, made visible."""
    from dualpixel.io.dpdd import frame_paths
    from dualpixel.io.images import write_png
    from dualpixel.synthesis.dataset import render_job

    root = Path(output)
    rng = np.random.default_rng(seed)
    bits = dataset.source.config.bit_depth
    for n in range(count):
        index = int(rng.integers(len(dataset)))
        job = dataset.job(index, int(rng.integers(2**62)), 0)
        stored = render_job(job, dataset.source.fmt, dataset.source.config)
        paths = frame_paths(root, "train", f"seq_{n:03d}", "frame_0000")
        for role in ("left", "right", "combined", "target"):
            write_png(paths[role], stored[role], bit_depth=bits)
    return root
