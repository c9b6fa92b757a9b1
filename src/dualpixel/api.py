"""The package's face for notebooks: synthesise, load a model, deblur, score.

One array convention at this boundary: images are NumPy ``(H, W, 3)`` or torch ``(3, H, W)`` /
``(B, 3, H, W)``, float in [0, 1] or integers read by their dtype's range (uint8 / 255, uint16 /
65535); what comes back has the layout and library of what came in, as float32 in [0, 1].
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import torch

from dualpixel.errors import ParameterError
from dualpixel.io.arrays import to_unit_float

__all__ = ["deblur", "list_models", "load_model", "synthesize"]


def _to_hwc(image: Any, name: str) -> tuple[np.ndarray, str]:
    """``image`` as float32 ``(N, H, W, 3)`` and the layout it came in."""
    if isinstance(image, torch.Tensor):
        array = image.detach().cpu()
        if array.ndim == 3 and array.shape[0] == 3:
            layout, array = "torch-chw", array[None]
        elif array.ndim == 4 and array.shape[1] == 3:
            layout = "torch-bchw"
        else:
            raise ParameterError(f"{name}: expected a torch (3, H, W) or (B, 3, H, W) image, "
                                 f"got {tuple(array.shape)}")
        array = array.permute(0, 2, 3, 1).numpy()
    else:
        array = np.asarray(image)
        if array.ndim != 3 or array.shape[2] != 3:
            raise ParameterError(f"{name}: expected a NumPy (H, W, 3) image, got {array.shape}")
        layout, array = "numpy-hwc", array[None]
    return to_unit_float(array, name, np.float32), layout


def _from_hwc(images: np.ndarray, layout: str) -> np.ndarray | torch.Tensor:
    if layout == "numpy-hwc":
        return images[0]
    tensor = torch.from_numpy(np.ascontiguousarray(images)).permute(0, 3, 1, 2)
    return tensor[0] if layout == "torch-chw" else tensor


def list_models() -> dict[str, dict[str, Any]]:
    """The shipped weights with their metadata (:func:`dualpixel.weights.list_models`)."""
    from dualpixel.weights import list_models as shipped

    return shipped()


def load_model(name_or_path: str | Path = "rdpd-light", *, device: str = "cpu"):
    """A shipped model by name (see :func:`list_models`) or a checkpoint file, in eval mode."""
    from dualpixel.device import resolve_device
    from dualpixel.models import load_model as load_checkpoint
    from dualpixel.weights import resolve_checkpoint

    return load_checkpoint(resolve_checkpoint(name_or_path), device=resolve_device(device))


def deblur(left: Any, right: Any = None, *, model: Any = "rdpd-light", device: str = "auto",
           tile: int | None = None, flips: bool = False,
           multiscale: bool = False) -> np.ndarray | torch.Tensor:
    """Deblur a DP pair (or a batch of independent pairs): views at the combined image's
    brightness (DPDD). ``model``: a name, a checkpoint path or a loaded network. ``flips``:
    average over the flips that keep DP geometry (self-ensemble, 4x the time; ``Deblurrer``).
    ``multiscale``: fuse with a pass at half resolution (at most 1.25x the time;
    :mod:`dualpixel.inference.multiscale`).

    >>> out = deblur(np.full((32, 48, 3), 0.5, np.float32), np.full((32, 48, 3), 0.5, np.float32))
    >>> out.shape, out.dtype
    ((32, 48, 3), dtype('float32'))
    """
    from dualpixel.device import resolve_device
    from dualpixel.inference import Deblurrer

    lefts, layout = _to_hwc(left, "left")
    rights = None
    if right is not None:
        rights, _ = _to_hwc(right, "right")
        if rights.shape != lefts.shape:
            raise ParameterError(f"left {lefts.shape[1:3]} and right {rights.shape[1:3]} views "
                                 "differ in size")
    resolved = resolve_device(device)
    net = load_model(model, device=str(resolved)) if isinstance(model, (str, Path)) else model
    if right is None and net.spec.views == 2:
        raise ParameterError(f"this model ({net.spec.name}) needs both views; give right")
    deblurrer = Deblurrer(net, device=resolved, tile=tile, flips=flips,
                          multiscale=multiscale)
    outputs = []
    for index in range(len(lefts)):
        deblurrer.reset()  # a batch holds independent pairs
        outputs.append(deblurrer(lefts[index], None if rights is None else rights[index]))
    return _from_hwc(np.stack(outputs), layout)


def synthesize(rgb: Any, depth: Any, *, camera: str = "set1", seed: int = 0,
               psf_bank: str = "paper", noise: bool = True, noise_model: str = "multiplicative",
               noise_sigmas: tuple[float, ...] | None = None, distortion: bool = True,
               device: str = "cpu") -> dict[str, Any]:
    """Synthesise a DP frame from an all-in-focus image and its depth (metres, ``(H, W)``).

    ``camera``: a preset ``set0``..``set4`` or a defocus profile such as ``dslr-840`` (focused at
    the depth map's 30th percentile, :func:`~dualpixel.optics.thin_lens.focus_from_depth`).
    Returns ``left``, ``right``, ``combined``, ``target`` in the layout of ``rgb`` and
    ``defocus`` (signed CoC radius, px) as ``(H, W)``.

    >>> frame = synthesize(np.full((24, 32, 3), 0.5), np.full((24, 32), 3.0), camera="set0")
    >>> sorted(frame), frame["left"].shape
    (['combined', 'defocus', 'left', 'right', 'target'], (24, 32, 3))
    """
    from dualpixel.device import resolve_device
    from dualpixel.optics.noise import PAPER_NOISE_SIGMAS
    from dualpixel.optics.psf_bank import PSF_BANKS
    from dualpixel.optics.thin_lens import CAMERA_PRESETS, DEFOCUS_PROFILES, focus_from_depth
    from dualpixel.synthesis.frame import draw_recipe, synthesize_frame

    images, layout = _to_hwc(rgb, "rgb")
    if len(images) != 1:
        raise ParameterError("synthesize takes one frame; call it per frame of a batch")
    depth_map = np.asarray(depth.detach().cpu() if isinstance(depth, torch.Tensor) else depth,
                           dtype=np.float32)
    if depth_map.shape != images.shape[1:3]:
        raise ParameterError(f"depth {depth_map.shape} must be (H, W) of rgb {images.shape[1:3]}")
    if not np.isfinite(depth_map).all() or (depth_map <= 0).any():
        raise ParameterError("depth must be finite and > 0 (metres)")
    if psf_bank not in PSF_BANKS:
        raise ParameterError(f"psf_bank must be one of {', '.join(PSF_BANKS)}, got {psf_bank!r}")
    if camera in DEFOCUS_PROFILES:
        focus = focus_from_depth(depth_map)
        lens = DEFOCUS_PROFILES[camera].camera(np.random.default_rng(seed), focus,
                                               depth_map.shape[1])
    elif camera in CAMERA_PRESETS:
        lens = camera
    else:
        known = ", ".join([*CAMERA_PRESETS, *DEFOCUS_PROFILES])
        raise ParameterError(f"camera must be one of {known}, got {camera!r}")
    recipe = draw_recipe(seed, lens, bank=PSF_BANKS[psf_bank], distortion=distortion,
                         noise=noise, noise_model=noise_model,
                         noise_sigmas=tuple(noise_sigmas or PAPER_NOISE_SIGMAS))
    frame = synthesize_frame(images[0], depth_map, recipe, noise_seed=seed,
                             device=resolve_device(device))
    result: dict[str, Any] = {}
    for key in ("left", "right", "combined", "target"):
        hwc = getattr(frame, key).permute(1, 2, 0).float().cpu().numpy()[None]
        result[key] = _from_hwc(hwc, layout)
    defocus = frame.defocus.float().cpu()
    result["defocus"] = defocus.numpy() if layout == "numpy-hwc" else defocus
    return result
