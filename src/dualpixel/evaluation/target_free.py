"""Target-free checks of a deblurred real DP photograph: what a model must not do, what it should.

A real DP photograph has no all-in-focus target, but the physics of defocus still says a lot
about a correct output:

- **Brightness is kept.** Blur moves light, it neither adds nor removes it (the PSFs of paper
  Eq. 2-4 sum to one), so in linear light the output's mean over the frame, and over any region
  much larger than the blur, equals the input's (the views' mean, the combined image).
- **No halos.** The sharp image lies within the range the blurred one spans around an edge, once
  the window is wider than the blur; a rim beyond that range is overshoot.
- **In-focus regions are kept.** Where the two views agree (zero disparity, so zero CoC: the
  left and right PSFs coincide, Eq. 4) there is nothing to deblur.
- **Nothing is invented.** A flat input region (no structure at any scale the blur leaves) has
  no detail to restore; texture appearing there is made up.
- **Defocused regions get sharper.** Where the views disagree, the output's gradients should
  grow.

:func:`check_deblurred` measures each on one pair and its output, on blocks of 32 px (64 px from
1280 px wide; the grid of :func:`~dualpixel.data.statistics.block_disparity_map`).
Brightness is measured in linear light; halos, in-focus change and invented texture in the
stored (display) values, as a person sees them, in levels of 255. :func:`check_model` runs a
model over pairs and returns a row per pair.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from dualpixel.data.statistics import block_disparity_map, block_sums
from dualpixel.errors import InputFileError, ParameterError
from dualpixel.filters import gradient_magnitude
from dualpixel.inference.brightness import is_palette_image, smooth
from dualpixel.inference.encoding import ViewEncoding
from dualpixel.names import output_modes_suffix
from dualpixel.optics.tone import (
    check_encoding,
    combined_light,
    linear_to_srgb_array,
    srgb_to_linear_array,
)

__all__ = [
    "TargetFreeReport", "check_deblurred", "check_folder", "check_model",
    "compare_to_reference", "flat_detail_error", "local_brightness_error", "markdown_table",
    "method_settings", "model_methods", "read_pairs", "reference_method", "summarise_reports",
    "write_target_free_report",
]

#: |disparity| (px) at or below which a textured block counts as in focus.
IN_FOCUS_SHIFT = 0.3
#: |disparity| (px) from which a textured block counts as defocused.
DEFOCUSED_SHIFT = 0.75
#: A block is flat when the input's mean gradient (Sobel of the grey image after a Gaussian of
#: 2 px, units of [0, 1] per px) stays below this: no structure the blur could have left.
FLAT_GRADIENT = 0.012
#: Gaussian (px) applied to every image before measuring, so noise removal is not change.
NOISE_SIGMA = 1.0
#: Excursion beyond the input's local range (levels of 255) that counts as a visible halo.
HALO_LEVELS = 4.0


#: ``(name, left, right)``: one DP pair.
Pair = tuple[str, np.ndarray, np.ndarray]
#: A deblurring method: ``method(left, right)`` -> output of the views' shape and encoding.
Method = Callable[[np.ndarray, np.ndarray], np.ndarray]


@dataclass(frozen=True)
class TargetFreeReport:
    """What one output did to its input; brightness as fractions, the rest in levels of 255.

    ``brightness_change``: mean(output) / mean(input) - 1 in linear light (signed).
    ``local_brightness``: mean over blocks of |low-pass(output) - low-pass(input)| in linear
    light (Gaussian, sigma of half a block), as a fraction of the input's mean;
    ``local_brightness_p95``: its 95th percentile over blocks.
    ``overshoot``: mean excursion beyond the input's local range (a window of half a block)
    around strong edges; ``halo_share``: share of those pixels beyond it by over
    :data:`HALO_LEVELS`.
    ``in_focus_change``: RMS change in in-focus blocks (NaN when none).
    ``invented_texture``: mean over flat blocks of the fine-detail std the output adds
    (NaN when none).
    ``sharpness_gain``: median over defocused blocks of the output's mean gradient over the
    input's (1: unchanged; NaN when none).
    """

    brightness_change: float
    local_brightness: float
    local_brightness_p95: float
    overshoot: float
    halo_share: float
    in_focus_change: float
    invented_texture: float
    sharpness_gain: float
    blocks: int
    in_focus_blocks: int
    defocused_blocks: int
    flat_blocks: int

    def as_dict(self) -> dict[str, float | int]:
        return asdict(self)


def _check_images(images: dict[str, np.ndarray], *, finite: bool = True) -> None:
    """Refuse images that are not ``(H, W, 1)`` or ``(H, W, 3)``, hold NaN or infinite values
    (``finite``) or do not share one shape; the message names the image."""
    for name, image in images.items():
        if image.ndim != 3 or image.shape[2] not in (1, 3):
            raise ParameterError(f"{name} must be (H, W, 1) or (H, W, 3), got {image.shape}")
        if finite and not np.isfinite(image).all():
            raise ParameterError(f"{name} holds NaN or infinite values")
    if len({image.shape for image in images.values()}) > 1:
        names = [f"{name} {image.shape}" for name, image in images.items()]
        raise ParameterError(f"{', '.join(names[:-1])} and {names[-1]} must share one shape")


def _to_linear(encoding: str):
    """The function that takes images stored in ``encoding`` to linear light."""
    return srgb_to_linear_array if check_encoding(encoding) == "srgb" else np.asarray


def block_size(width: int) -> int:
    """Block side (px) of the checks: 32 below 1280 px wide, 64 from there."""
    return 64 if width >= 1280 else 32


def _local_shift_blocks(grey: np.ndarray, reference: np.ndarray, patch: int,
                        mean: float) -> np.ndarray:
    """Per block, the mean |low-pass(grey) - low-pass(reference)| (Gaussian of half a block;
    ``(H, W)`` linear light) as a fraction of ``mean``."""
    sigma = patch / 2
    local = np.abs(cv2.GaussianBlur(grey, (0, 0), sigma, borderType=cv2.BORDER_REFLECT)
                   - cv2.GaussianBlur(reference, (0, 0), sigma, borderType=cv2.BORDER_REFLECT))
    return block_sums(local, patch) / patch**2 / mean


def local_brightness_error(output: np.ndarray, target: np.ndarray, *,
                           encoding: str = "srgb") -> float:
    """The checks' local brightness measure taken against the sharp target instead of the
    input, where a target is known (held-out synthetic frames): the mean over blocks of
    |low-pass(output) - low-pass(target)| in linear light (Gaussian of half a block), as a
    fraction of the target's mean. 0 for a perfect deblur, which the target-free
    ``local_brightness`` is not (a sharp image's low-pass differs from a blurred one's near
    edges). ``output``, ``target``: float ``(H, W, C)`` in [0, 1], one shape and encoding.

    >>> image = np.full((64, 128, 1), 0.5, np.float32)
    >>> round(local_brightness_error(image * 0.98, image, encoding="linear"), 4)
    0.02
    """
    to_linear = _to_linear(encoding)
    _check_images({"output": output, "target": target}, finite=False)
    grey_out, grey_target = (np.asarray(to_linear(x), np.float32).mean(axis=2)
                             for x in (output, target))
    mean = max(float(grey_target.mean()), 1e-6)
    return float(_local_shift_blocks(grey_out, grey_target, block_size(output.shape[1]),
                                     mean).mean())


def _check_frame(images: dict[str, np.ndarray], noise_sigma: float) -> int:
    """Refuse what :func:`_check_images` refuses, a ``noise_sigma`` outside [0, 8] px and
    images too small for two rows of four blocks; the block side (px)."""
    if not (math.isfinite(noise_sigma) and 0 <= noise_sigma <= 8):
        raise ParameterError(f"noise_sigma must be in [0, 8] px, got {noise_sigma}")
    _check_images(images)
    height, width = next(iter(images.values())).shape[:2]
    return _checked_size(width, height)


def _checked_size(width: int, height: int) -> int:
    """The block side (px) for images ``width`` x ``height``; a :class:`ParameterError` when
    they are too small for two rows of four blocks."""
    patch = block_size(width)
    if height < 2 * patch or width < 4 * patch:
        raise ParameterError(f"images must be at least {4 * patch}x{2 * patch} px for the "
                             f"target-free checks, got {width}x{height}")
    return patch


def _combined(left: np.ndarray, right: np.ndarray,
              encoding: str) -> tuple[np.ndarray, np.ndarray]:
    """The combined image (the views' mean in linear light): in linear light, and stored in
    ``encoding`` as the views are."""
    linear = combined_light(left, right, encoding)
    return linear, linear if encoding == "linear" else linear_to_srgb_array(linear)


def _shown(pictures: list[np.ndarray], encoding: str, noise_sigma: float) -> list[np.ndarray]:
    """``pictures`` (stored in ``encoding``) as display values, after a Gaussian of
    ``noise_sigma`` px in their own encoding, as the checks see them."""
    if noise_sigma > 0:  # noise and dither that the model removes are no change to judge
        pictures = [smooth(v, noise_sigma) for v in pictures]
    if encoding == "srgb":
        return pictures
    return [linear_to_srgb_array(v) for v in pictures]


def _block_grid(shown_left: np.ndarray, shown_right: np.ndarray,
                patch: int) -> tuple[np.ndarray, np.ndarray, tuple[slice, slice]]:
    """The views' disparity per block, which blocks are textured, and the pixels the grid
    covers (:func:`~dualpixel.data.statistics.block_disparity_map`)."""
    views = [np.repeat(v, 3, axis=2) if v.shape[2] == 1 else v for v in (shown_left, shown_right)]
    shifts, textured, start = block_disparity_map(*views, patch=patch,
                                                  max_shift=min(12, patch // 4))
    rows, cols = shifts.shape
    return shifts, textured, (slice(0, rows * patch), slice(start, start + cols * patch))


def _flat_blocks(grey_shown_in: np.ndarray, core: tuple[slice, slice], patch: int) -> np.ndarray:
    """Blocks of the grid with no structure the blur could have left: the input's mean
    gradient after a Gaussian of 2 px below :data:`FLAT_GRADIENT`."""
    smooth_in = cv2.GaussianBlur(grey_shown_in, (0, 0), 2.0, borderType=cv2.BORDER_REFLECT)
    structure = block_sums(gradient_magnitude(smooth_in[..., None])[core], patch) / patch**2
    return structure < FLAT_GRADIENT


def _fine_detail(grey: np.ndarray) -> np.ndarray:
    """What a Gaussian of 2 px removes from ``grey``."""
    return grey - cv2.GaussianBlur(grey, (0, 0), 2.0, borderType=cv2.BORDER_REFLECT)


def flat_detail_error(left: np.ndarray, right: np.ndarray, output: np.ndarray,
                      target: np.ndarray, *, encoding: str = "srgb",
                      noise_sigma: float = NOISE_SIGMA) -> float:
    """The checks' invented-texture measure taken against the sharp target, where one is known
    (held-out synthetic frames): over the blocks :func:`check_deblurred` calls flat, the RMS
    difference between the output's fine detail and the target's, in levels of 255 of the
    display values, after the checks' smoothing. 0 for a perfect deblur, whose invented texture
    is not 0 (a blur can leave a block flat whose target has texture); NaN when no block is
    flat. All four images float ``(H, W, C)`` in [0, 1], one shape and ``encoding``.

    >>> image = np.full((64, 128, 1), 0.5, np.float32)
    >>> flat_detail_error(image, image, image, image)
    0.0
    """
    patch = _check_frame({"left": left, "right": right, "output": output, "target": target},
                         noise_sigma)
    _, combined = _combined(left, right, encoding)
    shown_left, shown_right, shown_in, shown_out, shown_target = _shown(
        [left, right, combined, output, target], encoding, noise_sigma)
    _, _, core = _block_grid(shown_left, shown_right, patch)
    flat = _flat_blocks(shown_in.mean(axis=2), core, patch)
    if not flat.any():
        return math.nan
    difference = (_fine_detail(shown_out.mean(axis=2))
                  - _fine_detail(shown_target.mean(axis=2)))[core]
    return 255.0 * math.sqrt(float(block_sums(difference**2, patch)[flat].sum())
                             / (flat.sum() * patch**2))


def check_deblurred(left: np.ndarray, right: np.ndarray, output: np.ndarray, *,
                    encoding: str = "srgb", noise_sigma: float = NOISE_SIGMA,
                    palette: bool | None = None) -> TargetFreeReport:
    """Measure what ``output`` did to the DP pair ``left``/``right`` (float ``(H, W, C)`` in
    [0, 1], ``C`` 1 or 3, views at the combined image's brightness), with no target.

    ``encoding``: how all three store light (:data:`~dualpixel.inference.encoding.ENCODINGS`;
    linear values with the black level taken off). The input is the views' mean
    in linear light (each view is light collected by half of every pixel). Every measure is
    taken after a Gaussian of ``noise_sigma`` px on all three images, so that removing noise,
    dither or coding artefacts does not count as a change: in linear light for the brightness
    measures (camera noise is added there, and smoothing there keeps every mean), except for
    ``palette`` images (at most 256 colours, as GIF frames; detected when None), whose dither
    was added to the stored values and is smoothed there before they are linearised.
    """
    to_linear = _to_linear(encoding)
    patch = _check_frame({"left": left, "right": right, "output": output}, noise_sigma)
    lin_in, stored_in = _combined(left, right, encoding)
    shown_left, shown_right, shown_in, shown_out = _shown(
        [left, right, stored_in, output], encoding, noise_sigma)
    if palette is None:
        palette = is_palette_image(left)
    if palette:  # dither added to the stored values: smoothed there, then linearised
        lin_in = combined_light(shown_left, shown_right)
        lin_out = srgb_to_linear_array(shown_out)
    else:  # camera noise is added in linear light: smoothing there keeps every mean
        lin_out = to_linear(output)
        if noise_sigma > 0:
            lin_in, lin_out = smooth(lin_in, noise_sigma), smooth(lin_out, noise_sigma)

    # brightness: over the frame, and locally (Gaussian of half a block), in linear light
    mean_in = max(float(lin_in.mean()), 1e-6)
    brightness = float(lin_out.mean()) / mean_in - 1.0
    grey_in, grey_out = lin_in.mean(axis=2), lin_out.mean(axis=2)
    local_blocks = _local_shift_blocks(grey_out, grey_in, patch, mean_in)

    # halos: excursion beyond the input's range over a window of half a block, near strong edges
    reach = patch // 4
    window = np.ones((2 * reach + 1, 2 * reach + 1), np.uint8)
    gradient = gradient_magnitude(shown_in)
    strong = gradient >= max(float(np.percentile(gradient, 90)), 0.05)
    near_edges = cv2.dilate(strong.astype(np.uint8), window).astype(bool)
    low = cv2.erode(np.ascontiguousarray(shown_in), window, borderType=cv2.BORDER_REFLECT)
    high = cv2.dilate(np.ascontiguousarray(shown_in), window, borderType=cv2.BORDER_REFLECT)
    low, high = (a.reshape(shown_in.shape) for a in (low, high))
    excursion = 255.0 * np.maximum(shown_out - high, low - shown_out).clip(min=0).max(axis=2)
    if near_edges.any():
        overshoot = float(excursion[near_edges].mean())
        halo = float((excursion[near_edges] > HALO_LEVELS).mean())
    else:
        overshoot = halo = 0.0

    # block classes on the disparity grid
    shifts, textured, core = _block_grid(shown_left, shown_right, patch)
    in_focus = textured & (np.abs(shifts) <= IN_FOCUS_SHIFT)
    defocused = textured & (np.abs(shifts) >= DEFOCUSED_SHIFT)

    change = 255.0 * (shown_out - shown_in)[core].mean(axis=2)
    squared = block_sums(change**2, patch)
    focus_change = (math.sqrt(float(squared[in_focus].sum()) / (in_focus.sum() * patch**2))
                    if in_focus.any() else math.nan)

    grey_shown_in, grey_shown_out = shown_in.mean(axis=2), shown_out.mean(axis=2)
    flat = _flat_blocks(grey_shown_in, core, patch)
    fine_in, fine_out = _fine_detail(grey_shown_in), _fine_detail(grey_shown_out)
    added = (block_sums(fine_out[core] ** 2, patch) - block_sums(fine_in[core] ** 2, patch))
    invented_blocks = 255.0 * np.sqrt(np.clip(added / patch**2, 0.0, None))
    invented = float(invented_blocks[flat].mean()) if flat.any() else math.nan

    detail_in = block_sums(gradient[core], patch)
    detail_out = block_sums(gradient_magnitude(shown_out)[core], patch)
    gains = detail_out[defocused] / np.maximum(detail_in[defocused], 1e-9)
    sharpness = float(np.median(gains)) if gains.size else math.nan

    return TargetFreeReport(
        brightness_change=brightness,
        local_brightness=float(local_blocks.mean()),
        local_brightness_p95=float(np.percentile(local_blocks, 95)),
        overshoot=overshoot, halo_share=halo, in_focus_change=focus_change,
        invented_texture=invented, sharpness_gain=sharpness,
        blocks=int(local_blocks.size), in_focus_blocks=int(in_focus.sum()),
        defocused_blocks=int(defocused.sum()), flat_blocks=int(flat.sum()),
    )


def check_model(pairs: Iterable[Pair], deblur: Method, *,
                encoding: str = "srgb") -> list[tuple[str, TargetFreeReport]]:
    """:func:`check_deblurred` for every ``(name, left, right)`` with ``deblur(left, right)``
    as the output (same shape and encoding as the views)."""
    return [(name, check_deblurred(left, right, deblur(left, right), encoding=encoding))
            for name, left, right in pairs]


def summarise_reports(reports: Iterable[TargetFreeReport]) -> dict[str, float]:
    """Means over pairs (NaN entries skipped), plus the largest |brightness change|."""
    rows = [r.as_dict() for r in reports]
    if not rows:
        raise ParameterError("no reports to summarise")
    summary = {}
    for key in rows[0]:
        values = [float(r[key]) for r in rows if not math.isnan(float(r[key]))]
        summary[key] = float(np.mean(values)) if values else math.nan
    summary["worst_brightness_change"] = max((float(r["brightness_change"]) for r in rows), key=abs)
    return summary


def read_pairs(root: str | Path, split: str | None = None,
               encoding: ViewEncoding | None = None) -> list[Pair]:
    """``(name, left, right)`` of every pair in a folder of scene folders (``NAME/left.png``,
    ``NAME/right.png`` or ``view0``/``view1``; no target needed) or a DPDD-layout folder; the
    first frame of a sequence. Views come as float32 ``(H, W, C)`` in [0, 1] with the file's
    channels: 1 for a grey view, 3 for colour; linear views (``encoding``, levels in the files'
    units) as light, the black level taken off (:func:`~dualpixel.inference.encoding.
    linear_light`), as :func:`check_deblurred` and methods made with
    :data:`~dualpixel.inference.encoding.LINEAR_LIGHT` take them."""
    from dualpixel.data.layout import discover_any
    from dualpixel.inference.encoding import linear_light
    from dualpixel.io.images import max_level, read_views

    pairs = []
    for sequence in discover_any(root, split, require_target=False):
        frame = sequence.frames[0]
        left, right, (bits, _) = read_views(frame.left, frame.right)
        try:
            _checked_size(left.shape[1], left.shape[0])
            if encoding is not None and encoding.linear:  # levels that must fit this file
                encoding.check_levels(left, right, scale=max_level(bits))
        except ParameterError as error:
            raise InputFileError(frame.left, str(error)) from None
        if encoding is not None and encoding.linear:
            left, right = linear_light(left, right, encoding, scale=max_level(bits))
        pairs.append((sequence.name, left, right))
    return pairs


class _LastOutput:
    """The network's output for the last pair it was given, so that the output modes of one
    checkpoint share one pass of the network."""

    def __init__(self, deblurrer) -> None:
        self.deblurrer = deblurrer
        self.views: tuple[np.ndarray, np.ndarray] | None = None
        self.output: np.ndarray | None = None

    def __call__(self, left: np.ndarray, right: np.ndarray) -> np.ndarray:
        if self.views is None or not all(np.array_equal(a, b)
                                         for a, b in zip(self.views, (left, right))):
            self.deblurrer.reset()
            self.views, self.output = (left, right), self.deblurrer.network_output(left, right)
        return self.output


def method_settings(checkpoints: Iterable[str], *, brightness: Iterable[str] | None = None,
                    overshoot: Iterable[str] | None = None, flips: Iterable[bool] | None = None
                    ) -> dict[str, tuple[str, dict[str, Any]]]:
    """``{name: (checkpoint, settings)}`` for every checkpoint and combination of the given
    settings; a setting not given (None) is each checkpoint's own
    (:func:`~dualpixel.weights.run_settings`). Names are ``CHECKPOINT`` plus
    :func:`~dualpixel.names.output_modes_suffix` (``+flips``, ``+limited``, ``+tied``)."""
    from dualpixel.weights import run_settings

    named = {}
    for checkpoint in checkpoints:
        own = run_settings(checkpoint)
        for flip in (own["flips"],) if flips is None else flips:
            for limit in (own["overshoot"],) if overshoot is None else overshoot:
                for tie in (own["brightness"],) if brightness is None else brightness:
                    name = str(checkpoint) + output_modes_suffix(tie, limit, flips=flip)
                    named[name] = (str(checkpoint), {"brightness": tie, "overshoot": limit,
                                                     "flips": flip})
    return named


def reference_method(named: dict[str, tuple[str, dict[str, Any]]], reference: str) -> str:
    """The method of :func:`method_settings`' ``named`` that ``reference`` stands for: a method
    name, or a checkpoint checked with one combination of settings (``rdpd-light`` for
    ``rdpd-light+tied``)."""
    if reference in named:
        return reference
    matches = [name for name, (checkpoint, _) in named.items() if checkpoint == reference]
    if len(matches) == 1:
        return matches[0]
    what = f"checked with several settings ({', '.join(matches)}); name one" if matches else \
        f"not one of the checked models ({', '.join(named)})"
    raise ParameterError(f"{reference!r} is {what}")


def model_methods(checkpoints: Iterable[str], *, device: str = "auto",
                  encoding: ViewEncoding | None = None, tile: int | None = None,
                  precision: str = "auto", brightness: Iterable[str] | None = None,
                  overshoot: Iterable[str] | None = None,
                  flips: Iterable[bool] | None = None) -> dict[str, Method]:
    """A :data:`Method` per checkpoint (a registry name or a ``.safetensors`` path) and
    combination of settings (:func:`method_settings`; not given: the model's own): flips (the
    self-ensemble, :class:`~dualpixel.inference.Deblurrer`), overshoot mode
    (:mod:`dualpixel.inference.overshoot`) and brightness mode
    (:mod:`dualpixel.inference.brightness`). Each pair is deblurred afresh, in the views' own
    encoding and channels (:func:`~dualpixel.inference.encoding.deblur_encoded`); the output
    modes of one checkpoint and flips setting share its network's output."""
    from dualpixel.inference import build_deblurrer, load_network
    from dualpixel.inference.encoding import deblur_encoded

    models: dict[str, Any] = {}
    passes: dict[tuple[str, bool], _LastOutput] = {}
    methods: dict[str, Method] = {}
    for name, (checkpoint, settings) in method_settings(
            checkpoints, brightness=brightness, overshoot=overshoot, flips=flips).items():
        if checkpoint not in models:
            models[checkpoint] = load_network(checkpoint, device=device)
        key = (checkpoint, settings["flips"])
        if key not in passes:
            passes[key] = _LastOutput(build_deblurrer(models[checkpoint], tile=tile,
                                                      precision=precision,
                                                      flips=settings["flips"]))
        last = passes[key]

        def finished(left: np.ndarray, right: np.ndarray, last=last,
                     settings=settings) -> np.ndarray:
            return last.deblurrer.finish(last(left, right), left, right,
                                         brightness=settings["brightness"],
                                         overshoot=settings["overshoot"])

        def method(left: np.ndarray, right: np.ndarray, finished=finished) -> np.ndarray:
            return deblur_encoded(finished, left, right, encoding)

        methods[name] = method
    return methods


def check_folder(root: str | Path, methods: dict[str, Method],
                 *, split: str | None = None, encoding: ViewEncoding | str | None = None,
                 progress: bool = False, prefix: str = "") -> list[dict[str, Any]]:
    """One row per pair and method: ``{"pair", "method", **TargetFreeReport}``, pairs from
    :func:`read_pairs` (named ``prefix`` + their name; linear ones as light, so the methods
    take them with :data:`~dualpixel.inference.encoding.LINEAR_LIGHT`), each method called as
    ``method(left, right)``. ``encoding`` "linear" (a name, no levels): files whose values
    already are light."""
    from dualpixel.inference.encoding import LINEAR_LIGHT
    from dualpixel.progress import progress_bar

    if isinstance(encoding, str):  # a name: checked, and linear values taken as they are
        _to_linear(encoding)
        encoding = LINEAR_LIGHT if encoding == "linear" else None
    pairs = read_pairs(root, split, encoding)
    light = "linear" if encoding is not None and encoding.linear else "srgb"
    rows = []
    steps = progress_bar(total=len(pairs) * len(methods), desc="target-free checks", unit="output",
                         enabled=progress)
    with steps:
        for name, left, right in pairs:
            for method, deblur in methods.items():
                report = check_deblurred(left, right, deblur(left, right), encoding=light)
                rows.append({"pair": prefix + name, "method": method, **report.as_dict()})
                steps.update()
    return rows


#: Tolerances of :func:`compare_to_reference`: a model may exceed the reference's local
#: brightness shift and overshoot by this much before it counts as worse (measurement noise).
COMPARE_TOLERANCE = {"local_brightness": 0.0005, "overshoot": 0.05}
#: Largest |brightness change| over the frame (fraction, linear light) a model may make.
MAX_BRIGHTNESS_CHANGE = 0.01


def compare_to_reference(rows: list[dict[str, Any]], reference: str) -> list[str]:
    """What each method does worse than ``reference`` on the same pair (more local brightness
    shift or overshoot, beyond :data:`COMPARE_TOLERANCE`), and every output whose brightness
    over the frame changes by more than :data:`MAX_BRIGHTNESS_CHANGE`; empty when none."""
    by_pair = {(r["pair"], r["method"]): r for r in rows}
    if not any(method == reference for _, method in by_pair):
        raise ParameterError(f"reference {reference!r} is not among the checked methods")
    findings = []
    for row in rows:
        change = row["brightness_change"]
        if abs(change) > MAX_BRIGHTNESS_CHANGE:
            findings.append(f"{row['pair']}: {row['method']} changes the brightness by "
                            f"{100 * change:+.2f} % (limit {100 * MAX_BRIGHTNESS_CHANGE:.0f} %)")
        base = by_pair.get((row["pair"], reference))
        if row["method"] == reference or base is None:
            continue
        for key, slack in COMPARE_TOLERANCE.items():
            if row[key] > base[key] + slack:
                findings.append(f"{row['pair']}: {row['method']} {key} {row[key]:.4g} > "
                                f"{reference} {base[key]:.4g}")
    return findings


#: Columns of the Markdown table, with their headings.
TABLE_COLUMNS = {
    "brightness_change": "brightness %", "local_brightness": "local shift %",
    "overshoot": "overshoot", "halo_share": "halo %", "in_focus_change": "in-focus change",
    "invented_texture": "invented", "sharpness_gain": "sharpness x",
}


def _cell(key: str, value: float) -> str:
    if isinstance(value, float) and math.isnan(value):
        return "–"
    if key == "brightness_change":
        return f"{100 * value:+.2f}"
    if key in ("local_brightness", "halo_share"):
        return f"{100 * value:.2f}"
    return f"{value:.2f}"


def markdown_table(rows: list[dict[str, Any]]) -> str:
    """The rows as a Markdown table: one line per pair and method, then the means per method.
    Brightness and local shift in % of the input's mean (linear light), overshoot, in-focus
    change and invented texture in levels of 255, sharpness as a ratio."""
    lines = ["| pair | method | " + " | ".join(TABLE_COLUMNS.values()) + " |",
             "|---|---|" + "---|" * len(TABLE_COLUMNS)]
    for row in rows:
        cells = " | ".join(_cell(k, row[k]) for k in TABLE_COLUMNS)
        lines.append(f"| {row['pair']} | {row['method']} | {cells} |")
    methods = list(dict.fromkeys(r["method"] for r in rows))
    for method in methods:
        mine = [r for r in rows if r["method"] == method]
        means = {k: float(np.nanmean([r[k] for r in mine])) if not all(
            math.isnan(r[k]) for r in mine) else math.nan for k in TABLE_COLUMNS}
        worst = max((r["brightness_change"] for r in mine), key=abs)
        cells = " | ".join(_cell(k, means[k]) for k in TABLE_COLUMNS)
        lines.append(f"| **mean of {len(mine)}** | {method} (largest brightness change "
                     f"{100 * worst:+.2f} %) | {cells} |")
    return "\n".join(lines) + "\n"


def write_target_free_report(rows: list[dict[str, Any]], output: str | Path, *,
                             reference: str | None = None) -> list[str]:
    """Write ``target_free.csv`` (a row per pair and method) and ``target_free.md`` (the
    table, then what each method does worse than ``reference``) atomically into ``output``;
    return those findings (:func:`compare_to_reference`)."""
    import csv
    import io

    from dualpixel.io.atomic import atomic_path

    if not rows:
        raise ParameterError("no pairs were checked")
    findings = compare_to_reference(rows, reference) if reference else []
    output = Path(output)
    output.mkdir(parents=True, exist_ok=True)
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=list(rows[0]), lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    text = markdown_table(rows)
    if reference:
        text += (f"\nAgainst {reference}: " + ("nothing worse.\n" if not findings else
                 "\n\n" + "\n".join(f"- {f}" for f in findings) + "\n"))
    for name, content in (("target_free.csv", buffer.getvalue()), ("target_free.md", text)):
        with atomic_path(output / name) as tmp:
            tmp.write_text(content)
    return findings
