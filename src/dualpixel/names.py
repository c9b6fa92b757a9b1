"""Names of the choices the library offers, in a module that imports nothing heavy, so the
command line can list them without importing torch (``dualpixel --help`` stays fast)."""

from __future__ import annotations

__all__ = ["ALIGN_MODE_NAMES", "BACKENDS", "BRIGHTNESS_MODES", "DEFAULT_BRIGHTNESS",
           "DEFAULT_OVERSHOOT", "ENCODINGS", "LIGHT_SPACES", "MAX_SEQUENCES", "OVERSHOOT_MODES",
           "PRECISIONS", "PSF_BANK_NAMES", "PSF_MODELS", "PSF_SHAPE_SOURCES", "RAW_VIEWS",
           "RENAMED", "RENAMED_UNTIL", "RENDER_ON", "SCENE_LAYOUTS", "SYNTH_SETTINGS_NAMES",
           "SYNTH_SOURCES", "checkpoint_label", "output_modes_suffix", "renamed_attributes",
           "renamed_keys",
           "warn_renamed"]

#: Registrations of an output to its target before scoring
#: (:mod:`dualpixel.evaluation.alignment`; ``dualpixel eval --align``).
ALIGN_MODE_NAMES: tuple[str, ...] = ("translation", "affine")
#: DP PSF models: ours (Eq. 2-4) and the ablation's baselines.
PSF_MODELS: tuple[str, ...] = ("ours", "punnappurath", "disk", "gaussian")
#: Banks of PSF shapes (:data:`dualpixel.optics.psf_bank.PSF_BANKS`).
PSF_BANK_NAMES: tuple[str, ...] = ("paper", "pixel4", "broad")
#: Where a synthesis with a calibrated camera takes its PSF shapes from: the camera's fitted
#: shape, or the PSF bank (the camera's disparity ratios and light kept).
PSF_SHAPE_SOURCES: tuple[str, ...] = ("camera", "bank")
#: Where synthesis blurs (:mod:`dualpixel.optics.tone`): the stored (sRGB-encoded) values, the
#: paper's generator, or linear light with the sRGB curve after, as a lens does.
LIGHT_SPACES: tuple[str, ...] = ("encoded", "linear")
#: Named synthesis settings (:data:`dualpixel.synthesis.dataset.SYNTH_SETTINGS`): what the
#: shipped default model was trained on, or the paper's.
SYNTH_SETTINGS_NAMES: tuple[str, ...] = ("shipped", "paper")
#: Where a synth step's frames come from: written once (``synth``), or rendered as training
#: draws them (:mod:`dualpixel.synthesis.on_the_fly`; validation stays on written frames).
SYNTH_SOURCES: tuple[str, ...] = ("written", "on-the-fly")
#: Where on-the-fly frames are rendered in training: the loader's processes or the device.
RENDER_ON: tuple[str, ...] = ("loader", "device")
#: Layouts of the procedural scenes (:mod:`dualpixel.synthesis.scenes`): "photographic" covers
#: the frame with real photographs (``scenes --photos DIR``).
SCENE_LAYOUTS: tuple[str, ...] = ("leaves", "photo", "photographic")
#: The most sequences one procedural scene folder holds.
MAX_SEQUENCES = 100_000
#: Inference precisions (:mod:`dualpixel.inference.precision`).
PRECISIONS: tuple[str, ...] = ("auto", "fp32", "bf16", "fp16")
#: Inference backends (:mod:`dualpixel.inference.onnx_runtime`): PyTorch (any device and
#: precision) or ONNX Runtime (CPU, float32).
BACKENDS: tuple[str, ...] = ("torch", "onnxruntime")
#: Outputs' brightness (:mod:`dualpixel.inference.brightness`): "tied", the output's low-pass
#: brightness in linear light held at the input's, or "model", as the network gives it.
BRIGHTNESS_MODES: tuple[str, ...] = ("tied", "model")
#: What a network runs with unless told otherwise (a shipped model may say otherwise:
#: :func:`dualpixel.weights.run_settings`).
DEFAULT_BRIGHTNESS = "model"
#: Outputs' range (:mod:`dualpixel.inference.overshoot`): "limited", clipped to the input's
#: local range near every pixel, or "model", as the network gives it.
OVERSHOOT_MODES: tuple[str, ...] = ("limited", "model")
#: What a network runs with unless told otherwise (as for :data:`DEFAULT_BRIGHTNESS`).
DEFAULT_OVERSHOOT = "model"
#: How DP views store light (:mod:`dualpixel.inference.encoding`): display values ("srgb",
#: photographs and the DPDD) or raw sensor values ("linear").
ENCODINGS: tuple[str, ...] = ("srgb", "linear")
#: How training reads synthetic frames stored as raw values (:mod:`dualpixel.training.raw_views`):
#: as stored, or as ``deblur --encoding linear`` feeds raw views to the model.
RAW_VIEWS: tuple[str, ...] = ("stored", "model")


#: File names a training run gives its checkpoints: alone they would not tell runs apart.
RUN_CHECKPOINT_STEMS = ("best", "last", "model", "checkpoint")


def checkpoint_label(checkpoint: str) -> str:
    """The name of a checkpoint in tables: a shipped name as it is, a file by its stem, and a run's
    ``best`` / ``last`` by its folder too.

    >>> checkpoint_label("rdpd-light"), checkpoint_label("runs/x/best.safetensors")
    ('rdpd-light', 'x-best')
    """
    from pathlib import PurePath

    path = PurePath(checkpoint)
    if path.suffix not in (".safetensors", ".onnx") and len(path.parts) == 1:
        return str(checkpoint)
    if path.stem in RUN_CHECKPOINT_STEMS and path.parent.name:
        return f"{path.parent.name}-{path.stem}"
    return path.stem


def output_modes_suffix(brightness: str, overshoot: str, *, flips: bool = False,
                        multiscale: bool = False, fuse_frames: int = 1) -> str:
    """How results name a model run with these settings: ``+fuseN`` for views averaged with
    earlier frames, ``+flips`` and ``+multiscale`` for the network's passes, then ``+limited``
    for a limited overshoot and ``+tied`` for a tied brightness (the order they are applied in).

    >>> output_modes_suffix("tied", "limited"), output_modes_suffix("model", "model", flips=True)
    ('+limited+tied', '+flips')
    >>> output_modes_suffix("tied", "model", fuse_frames=6)
    '+fuse6+tied'
    """
    passes = ((f"+fuse{fuse_frames}" if fuse_frames > 1 else "") + ("+flips" if flips else "")
              + ("+multiscale" if multiscale else ""))
    limited = "+limited" if overshoot == "limited" else ""
    return passes + limited + ("+tied" if brightness == "tied" else "")


#: Settings renamed so that one word keeps one meaning, old -> new. "camera" is a calibrated
#: camera file (:class:`~dualpixel.optics.camera.DPCamera`); a *lens set* is what blurs a
#: frame: one of the paper's five camera parameter sets ``set0``..``set4`` (focal length,
#: aperture, focus distance) or a blur profile relative to the frame (``dslr-840``). The old
#: names are accepted, with a warning, until release :data:`RENAMED_UNTIL`.
RENAMED: dict[str, str] = {"cameras": "lens_sets"}
RENAMED_UNTIL = "0.3"


def warn_renamed(old: str, new: str, where: str | None = None, *, stacklevel: int = 1) -> None:
    """The warning for a setting, option or name given by its old name (``where`` prefixes the
    message; ``stacklevel`` counts from the caller, as ``warnings.warn``'s does)."""
    import warnings

    warnings.warn(f"{where + ': ' if where else ''}{old} is now {new}; the old name goes in "
                  f"release {RENAMED_UNTIL}", FutureWarning, stacklevel=stacklevel + 1)


def renamed_attributes(module: str, renamed: dict[str, str], namespace: dict):
    """A module's ``__getattr__`` that answers each old name of ``renamed`` (old: new) with the
    new name's object from ``namespace`` (the module's ``globals()``) and a warning."""

    def __getattr__(name: str):
        if name in renamed:
            warn_renamed(f"{module}.{name}", renamed[name], stacklevel=2)
            return namespace[renamed[name]]
        raise AttributeError(f"module {module!r} has no attribute {name!r}")

    return __getattr__


def renamed_keys(values: dict, where: str, *, warn: bool = True) -> dict:
    """``values`` with every old key of :data:`RENAMED` under its new name (a warning naming
    ``where`` unless ``warn`` is False, for files this library wrote before the rename).

    >>> renamed_keys({"lens_sets": ["set1"], "seed": 3}, "a recipe")
    {'lens_sets': ['set1'], 'seed': 3}
    """
    from dualpixel.errors import ParameterError

    values = dict(values)
    for old, new in RENAMED.items():
        if old not in values:
            continue
        if new in values:
            raise ParameterError(f"{where}: give {new} only ({old} is its old name)")
        if warn:
            warn_renamed(old, new, where, stacklevel=3)
        values[new] = values.pop(old)
    return values
