"""The package's face for notebooks: synthesise, load a model, deblur, score.

One array convention at this boundary (:mod:`dualpixel.io.arrays`): images are NumPy ``(H, W, C)``,
``(H, W)`` or ``(N, H, W, C)``, torch ``(C, H, W)`` or ``(N, C, H, W)``, or PIL images; ``C`` is 1,
3 or 4 (grey copied to RGB, alpha dropped); floats in [0, 1] or uint8 / uint16 read by their range.
What comes back has the layout and library of what came in (PIL: NumPy), as float32 in [0, 1]:
RGB, except that :func:`deblur` gives grey views a grey output.
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import torch

from dualpixel.errors import ParameterError, check_seed
from dualpixel.io.arrays import as_image_batch, full_scale, image_channels, restore_layout
from dualpixel.weights import DEFAULT_CHECKPOINT

if TYPE_CHECKING:
    from dualpixel.optics.camera import DPCamera

__all__ = ["check_views", "deblur", "list_models", "load_model", "synthesize"]


def list_models() -> dict[str, dict[str, Any]]:
    """The shipped weights with their metadata (:func:`dualpixel.weights.list_models`)."""
    from dualpixel.weights import list_models as shipped

    return shipped()


def load_model(name_or_path: str | Path = DEFAULT_CHECKPOINT, *, device: str = "auto"):
    """A shipped model by name (see :func:`list_models`) or a checkpoint file, in eval mode, on
    ``device`` (``auto``: the GPU when there is one, as every command)."""
    from dualpixel.inference.pipeline import is_graph, load_network

    if not isinstance(name_or_path, (str, Path)) or is_graph(name_or_path):
        raise ParameterError("load_model takes a model name (list_models()) or a .safetensors "
                             f"checkpoint path, got {name_or_path!r:.80}" + (
                                 "; an exported graph runs as deblur(..., model=PATH)"
                                 if is_graph(name_or_path) else ""))
    return load_network(name_or_path, device=device).net


def check_views(left: Any, right: Any, combined: Any = None) -> list:
    """Likely mistakes in one DP pair (views swapped, at half brightness, from different
    captures, ...) as :class:`~dualpixel.inference.view_checks.ViewFinding` s, most serious
    first; empty when none is seen (:mod:`dualpixel.inference.view_checks`).

    >>> grey = np.full((32, 48, 3), 0.5, np.float32)
    >>> findings = check_views(grey, grey, combined=2 * grey)
    >>> len(findings), findings[0].code
    (1, 'half-bright')
    """
    from dualpixel.inference.view_checks import check_views as check

    images = {}
    for name, image in (("left", left), ("right", right), ("combined", combined)):
        if image is not None:
            batch, _ = as_image_batch(image, name)
            if len(batch) != 1:
                raise ParameterError(f"{name}: check_views takes one pair, got {len(batch)}")
            images[name] = batch[0]
    for name in ("right", "combined"):
        if name in images and images[name].shape != images["left"].shape:
            raise ParameterError(f"{name} {images[name].shape[:2]} and left "
                                 f"{images['left'].shape[:2]} differ in size")
    return check(images["left"], images["right"], combined=images.get("combined"))


def deblur(left: Any, right: Any = None, *, model: Any = DEFAULT_CHECKPOINT, device: str = "auto",
           tile: int | None = None, flips: bool | None = None, multiscale: bool = False,
           precision: str = "auto", views_sum: bool = False,
           backend: str = "torch", encoding: str = "srgb", black_level: float | None = None,
           white_level: float | None = None, right_gain: float | np.ndarray = 1.0,
           auto_exposure: bool = True, brightness: str | None = None,
           overshoot: str | None = None, sequence: bool = False,
           fuse_frames: int | None = None) -> np.ndarray | torch.Tensor:
    """Deblur a DP pair (or a batch of independent pairs; with ``sequence=True``, the batch
    is one sequence's frames in order, and a temporal model carries its state from each frame
    to the next, as ``dualpixel deblur`` on folders of frames): views at the combined image's
    brightness (DPDD), or ``views_sum=True`` for views that sum to it (a raw A/B split; they
    are doubled). :func:`check_views` tells the usual mistakes. ``model``: a name, a checkpoint
    path or a loaded network. ``flips``, ``brightness``, ``overshoot``: None takes the
    model's own setting, which travels with it (a name, its file, or the network
    :func:`load_model` gave: :func:`dualpixel.weights.run_settings`; ``list_models`` shows
    them), else as the network gives it; ``fuse_frames`` likewise. ``flips``:
    average over the flips that keep DP geometry (self-ensemble, 4x the time; ``Deblurrer``).
    ``multiscale``: fuse with a pass at half resolution (at most 1.25x the time;
    :mod:`dualpixel.inference.multiscale`). ``precision``: ``auto`` (bf16 where the device
    computes it natively), ``fp32``, ``bf16`` or ``fp16`` (:mod:`dualpixel.inference.precision`).
    ``backend``: ``torch``, or ``onnxruntime`` (CPU, fp32; :mod:`dualpixel.inference.onnx_runtime`).
    ``brightness``: ``"tied"`` holds the output's low-pass brightness in linear light at the
    input's, ``"model"`` leaves it as the network gives it
    (:mod:`dualpixel.inference.brightness`). ``overshoot``: ``"limited"`` keeps the output
    within the input's local range (no halos), ``"model"`` leaves it
    (:mod:`dualpixel.inference.overshoot`). ``fuse_frames`` (with ``sequence=True``): each
    frame's views averaged with those of up to ``fuse_frames - 1`` earlier frames, registered
    onto it, before the network (:mod:`dualpixel.inference.frame_fusion`; 1: off; the preset
    ``rdpd-light-video``: 6).

    Phone and raw views (:mod:`dualpixel.inference.encoding`): grey views (one channel, such as
    a Pixel's green-only DP data) come back grey, in the layout they came in. ``encoding``:
    ``"srgb"`` (display values, the default) or ``"linear"`` (raw values; then ``black_level``
    and ``white_level`` in the views' own units, e.g. 1024 and 16383 for uint16 arrays of
    14-bit data, and ``right_gain`` for DP shading, a number or a flat-field map): the views are
    encoded as the models were trained and the output decoded back to the views' encoding.
    ``auto_exposure`` (linear views): each pair's light is scaled so that a high percentile of
    the combined image sits where the training frames put it, and the output scaled back
    (:meth:`~dualpixel.inference.encoding.ViewEncoding.exposed`); ``False`` leaves it.
    A pair that looks linear but is declared display-encoded, or the reverse, gives a warning.

    >>> out = deblur(np.full((32, 48, 3), 0.5, np.float32), np.full((32, 48, 3), 0.5, np.float32))
    >>> out.shape, out.dtype
    ((32, 48, 3), dtype('float32'))
    """
    import warnings

    from dualpixel.inference import build_deblurrer, load_network
    from dualpixel.inference.encoding import (
        ViewEncoding,
        deblur_encoded,
        encoding_findings,
        pair_exposed,
    )
    from dualpixel.inference.frame_fusion import check_fuse_frames

    if fuse_frames is not None and check_fuse_frames(fuse_frames) > 1 and not sequence:
        raise ParameterError("fuse_frames averages the frames of a sequence: give "
                             "sequence=True (independent pairs have no earlier frames)")
    view_encoding = ViewEncoding(encoding, black_level, white_level, right_gain,
                                 auto_exposure=auto_exposure)
    channels, scale = min(image_channels(left), 3), full_scale(left)
    lefts, layout = as_image_batch(left, "left")
    rights = None
    if right is not None:
        rights, _ = as_image_batch(right, "right")
        if rights.shape != lefts.shape:
            raise ParameterError(f"left {lefts.shape[:3]} and right {rights.shape[:3]} views "
                                 "differ in size or count")
        if min(image_channels(right), 3) != channels:
            raise ParameterError(f"left has {channels} channel(s) and right "
                                 f"{min(image_channels(right), 3)}: give both views of one "
                                 "capture (grey with grey, colour with colour)")
        if full_scale(right) != scale:
            raise ParameterError("left and right differ in type (bit depth or float): give "
                                 "both views as read from one capture")
    loaded = load_network(model, device=device, backend=backend)
    net = loaded.net
    if right is None and net.spec.views == 2:
        raise ParameterError(f"this model ({net.spec.name}) needs both views; give right")
    if views_sum and rights is None:
        raise ParameterError("views_sum needs both views")
    for finding in encoding_findings(lefts[0], (rights if rights is not None else lefts)[0],
                                     encoding):
        warnings.warn(finding.message, stacklevel=2)
    deblurrer = build_deblurrer(loaded, brightness=brightness, overshoot=overshoot,
                                flips=flips, tile=tile, multiscale=multiscale,
                                precision=precision, fuse_frames=fuse_frames)
    outputs, exposed = [], view_encoding
    for index in range(len(lefts)):
        frame_left = lefts[index][..., :channels]
        frame_right = None if rights is None else rights[index][..., :channels]
        if not sequence or index == 0:  # independent pairs, each of its own exposure; a
            deblurrer.reset()           # sequence keeps its state and its first pair's
            exposed = pair_exposed(view_encoding, frame_left, frame_right, scale=scale,
                                   views_sum=views_sum)
        outputs.append(deblur_encoded(deblurrer, frame_left, frame_right, scale=scale,
                                      views_sum=views_sum, exposed=exposed))
    result = restore_layout(np.stack(outputs), layout, like=left)
    if not type(left).__module__.startswith("PIL.") and np.ndim(left) == 2:  # (H, W) in
        return result[0] if layout == "torch" else result[..., 0]
    return result


#: The lens set :func:`synthesize` blurs one frame with when none is given, per settings: the
#: shipped model's sharper profile, and the paper's set1 (this function's default before
#: ``settings`` existed).
_FRAME_LENS_SET = {"shipped": "dslr-840", "paper": "set1"}


def _old_camera_arguments(lens_set: str, camera: Any, camera_file: Any) -> tuple[str, Any]:
    """``(lens_set, camera)`` with the arguments' old meanings taken, with a warning: before
    release 0.2, ``camera`` named the lens set and ``camera_file`` the calibrated camera."""
    from dualpixel.names import RENAMED_UNTIL, warn_renamed
    from dualpixel.optics.thin_lens import DEFOCUS_PROFILES, PAPER_LENS_SETS

    if isinstance(camera, str) and camera in (*PAPER_LENS_SETS, *DEFOCUS_PROFILES):
        warnings.warn(f"synthesize(camera={camera!r}): a lens set is now lens_set=; camera= is "
                      f"a calibrated camera (the old meaning goes in release {RENAMED_UNTIL})",
                      FutureWarning, stacklevel=3)
        lens_set, camera = camera, None
    if camera_file is not None:
        if camera is not None:
            raise ParameterError("give camera only (camera_file is its old name)")
        warn_renamed("synthesize(camera_file=...)", "camera=...", stacklevel=3)
        camera = camera_file
    return lens_set, camera


def synthesize(rgb: Any, depth: Any, *, lens_set: str | None = None, seed: int = 0,
               settings: str = "shipped", psf_bank: str | None = None, noise: bool = True,
               noise_model: str | None = None, noise_sigmas: tuple[float, ...] | None = None,
               distortion: bool = True,
               camera: str | Path | DPCamera | None = None, psf_shapes: str | None = None,
               light: str | None = None, base_blur: float = 0.0, device: str = "cpu",
               camera_file: str | Path | DPCamera | None = None) -> dict[str, Any]:
    """Synthesise a DP frame from an all-in-focus image and its depth (metres, ``(H, W)``).

    ``settings``: where ``lens_set``, ``psf_bank``, ``noise_model``, ``noise_sigmas`` and
    ``light`` start when not given (:data:`~dualpixel.synthesis.dataset.SYNTH_SETTINGS`):
    ``"shipped"``, the generic DSLR the shipped default model was trained on (lens set
    ``dslr-840``, the broad PSF bank, blur in linear light, a real camera's Poisson-Gaussian
    noise), or ``"paper"`` (``set1``, the paper's PSF bank, blur in the stored values,
    multiplicative noise about six times a real photograph's).
    ``lens_set``: what blurs the frame: one of the paper's camera parameter sets ``set0``..
    ``set4`` or a blur profile such as ``dslr-840`` (focused at the depth map's 30th
    percentile, :func:`~dualpixel.optics.thin_lens.focus_from_depth`).
    ``camera``: a calibrated camera, as ``dualpixel synth --camera`` takes it (a shipped one by
    name, a ``camera.json`` path or a :class:`~dualpixel.optics.camera.DPCamera`): its PSF
    shape replaces ``psf_bank`` (unless ``psf_shapes="bank"``), its per-channel disparity ratio
    forms the views and its light space is where the blur happens (``light`` overrides it:
    "encoded", the paper's, or "linear"); see :func:`~dualpixel.synthesis.frame.camera_settings`.
    ``base_blur``: std (px) of a Gaussian blurring both views, not the target: the in-focus
    optics, which the thin lens leaves perfectly sharp (0: none, the paper's views).
    Until release 0.3, ``camera`` naming a lens set and ``camera_file`` are taken as their old
    meanings, with a warning.
    Returns ``left``, ``right``, ``combined``, ``target`` in the layout of ``rgb`` and
    ``defocus`` (signed CoC radius, px) as ``(H, W)``.

    >>> frame = synthesize(np.full((24, 32, 3), 0.5), np.full((24, 32), 3.0), lens_set="set0")
    >>> sorted(frame), frame["left"].shape
    (['combined', 'defocus', 'left', 'right', 'target'], (24, 32, 3))
    """
    from dualpixel.device import resolve_device
    from dualpixel.io.images import check_depth_map
    from dualpixel.optics.psf_bank import PSF_BANKS
    from dualpixel.optics.thin_lens import DEFOCUS_PROFILES, PAPER_LENS_SETS, focus_from_depth
    from dualpixel.synthesis.dataset import synthesis_settings
    from dualpixel.synthesis.frame import camera_settings, draw_sequence, synthesize_frame

    images, layout = as_image_batch(rgb, "rgb")
    if len(images) != 1:
        raise ParameterError("synthesize takes one frame; call it per frame of a batch")
    depth_map = np.asarray(depth.detach().cpu() if isinstance(depth, torch.Tensor) else depth)
    if depth_map.shape[:2] != images.shape[1:3]:
        raise ParameterError(f"depth {depth_map.shape} must be (H, W) of rgb {images.shape[1:3]}")
    depth_map = check_depth_map(depth_map)
    lens_set, camera = _old_camera_arguments(lens_set, camera, camera_file)
    check_seed("seed", seed)
    defaults = synthesis_settings(settings, camera=camera is not None)
    lens_set = lens_set or _FRAME_LENS_SET[settings]
    psf_bank = psf_bank or defaults["psf_bank"]
    noise_model = noise_model or defaults["noise_model"]
    noise_sigmas = defaults["noise_sigmas"] if noise_sigmas is None else tuple(noise_sigmas)
    light = defaults["light"] if light is None else light
    if psf_bank not in PSF_BANKS:
        raise ParameterError(f"psf_bank must be one of {', '.join(PSF_BANKS)}, got {psf_bank!r}")
    if camera is not None:
        from dualpixel.optics.camera import DPCamera, load_camera

        if isinstance(camera, (str, Path)):
            camera = load_camera(camera)
        elif not isinstance(camera, DPCamera):
            raise ParameterError("camera must be a shipped camera's name, a camera.json path "
                                 f"or a DPCamera, got {type(camera).__name__}")
    settings = camera_settings(camera, PSF_BANKS[psf_bank], psf_shapes=psf_shapes, light=light)
    if lens_set in DEFOCUS_PROFILES:
        focus = focus_from_depth(depth_map)
        lens = DEFOCUS_PROFILES[lens_set].lens(np.random.default_rng(seed), focus,
                                                 depth_map.shape[1])
    elif lens_set in PAPER_LENS_SETS:
        lens = lens_set
    else:
        known = ", ".join([*PAPER_LENS_SETS, *DEFOCUS_PROFILES])
        raise ParameterError(f"lens_set must be one of {known}, got {lens_set!r}")
    draw = draw_sequence(seed, lens, **settings.draw_options(), distortion=distortion,
                         noise=noise, noise_model=noise_model, noise_sigmas=noise_sigmas,
                         base_blur=(base_blur, base_blur))
    frame = synthesize_frame(images[0], depth_map, draw, noise_seed=seed,
                             device=resolve_device(device))
    result: dict[str, Any] = {}
    for key in ("left", "right", "combined", "target"):
        hwc = getattr(frame, key).permute(1, 2, 0).float().cpu().numpy()[None]
        result[key] = restore_layout(hwc, layout, like=rgb)
    defocus = frame.defocus.float().cpu()
    result["defocus"] = defocus.to(rgb.device) if layout.startswith("torch") else defocus.numpy()
    return result
