"""One synthetic DP frame: CoC -> layered DP views -> in-focus blur (ours) -> radial distortion ->
noise (paper Sec. 3).

A :class:`SequenceDraw` fixes what the paper keeps constant over a sequence (lens, PSF shape,
distortion set, noise strength); :func:`draw_sequence` draws it reproducibly from a seed.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
import torch

from dualpixel.errors import ParameterError, check_range
from dualpixel.filters import gaussian_blur, gaussian_reach
from dualpixel.names import PSF_SHAPE_SOURCES
from dualpixel.optics.crosstalk import (
    apply_crosstalk,
    check_disparity_falloff,
    check_disparity_ratio,
)
from dualpixel.optics.distortion import (
    DISTORTION_PRESETS,
    DivisionDistortion,
    distort_image,
    distort_window,
    window_sources,
)
from dualpixel.optics.noise import (
    PAPER_NOISE_SIGMAS,
    NoiseModel,
    add_noise,
    check_noise_sigmas,
    sample_noise_sigma,
    tiled_normals,
)
from dualpixel.optics.psf import PSFModel, PSFParams, check_psf_model
from dualpixel.optics.psf_bank import PAPER_PSF_BANK, PSFBank
from dualpixel.optics.thin_lens import PAPER_LENS_SETS, ThinLens, coc_radius
from dualpixel.optics.tone import (
    Light,
    check_light,
    check_raw_storage,
    linear_to_raw,
    linear_to_srgb,
    srgb_to_linear,
)
from dualpixel.synthesis.fast_renderer import (
    MAX_DOWNSAMPLE,
    crop_margin,
    downsample_factor,
    render_fast,
)
from dualpixel.synthesis.layers import check_render_mode, quantise_layers
from dualpixel.synthesis.renderer import render_dp_views

if TYPE_CHECKING:
    from dualpixel.optics.camera import DPCamera

__all__ = ["MAX_BASE_BLUR", "CameraSettings", "DPFrame", "SequenceDraw", "camera_settings",
           "check_base_blur", "check_base_blur_range", "common_regions", "draw_sequence",
           "render_region",
           "sharp_target", "synthesize_frame", "synthesize_frames"]


@dataclass(frozen=True)
class SequenceDraw:
    """Everything that stays fixed over one synthetic sequence; ``lens`` is the lens set's
    thin lens (manifests record it under ``camera``, as they always have)."""

    lens: ThinLens
    psf: PSFParams
    distortion: DivisionDistortion | None
    noise_sigma: float | None
    psf_model: PSFModel = "ours"
    noise_model: NoiseModel = "multiplicative"
    max_layers: int = 500
    render_mode: str = "fast"
    # Ours: per channel, the fraction of the model's disparity the camera's views keep
    # (dualpixel.optics.crosstalk; a calibrated camera); None: the paper's model (1, 1, 1).
    disparity_ratio: tuple[float, ...] | None = None
    # Ours: how that ratio falls towards the frame's left and right sides (a calibrated camera).
    disparity_falloff: float = 0.0
    # Ours: "linear" blurs in linear light and encodes the views and target as sRGB after
    # (dualpixel.optics.tone; a calibrated camera); "encoded": the paper's, the stored values.
    light: Light = "encoded"
    # Ours: ``(black_level, gain)``: the views and target stored as linear raw values
    # (dualpixel.optics.tone.linear_to_raw, as a phone's DP data), noise added to them;
    # None: sRGB-encoded values. Needs ``light`` "linear".
    raw: tuple[float, float] | None = None
    # Ours: std (px of the frame) of a Gaussian blurring both views after the layered render,
    # not the target: the in-focus optics, which the thin lens leaves perfectly sharp
    # (docs/formation.md, "In focus, the real views are softer"). 0: the paper's views.
    base_blur: float = 0.0

    def __post_init__(self) -> None:
        check_base_blur(self.base_blur)
        if self.disparity_ratio is not None:
            check_disparity_ratio(self.disparity_ratio)
        if check_disparity_falloff(self.disparity_falloff) and self.disparity_ratio is None:
            raise ParameterError("a disparity falloff needs a disparity ratio (a camera)")
        check_light(self.light)
        if self.raw is not None:
            check_raw_storage(self.raw[0], (self.raw[1], self.raw[1]))
            if self.light != "linear":
                raise ParameterError("raw storage needs light 'linear' (a sensor's values are "
                                     "linear in light, so the lens blurs them as stored)")

    @property
    def camera(self) -> ThinLens:
        """Old name of :attr:`lens` (until release 0.3)."""
        from dualpixel.names import warn_renamed

        warn_renamed("SequenceDraw.camera", "SequenceDraw.lens", stacklevel=2)
        return self.lens

    def describe(self) -> dict:
        """A JSON-ready description for manifests."""
        lens = self.lens
        return {
            "camera": {
                "name": lens.name, "focal_length": lens.focal_length,
                "f_number": lens.f_number, "focus_distance": lens.focus_distance,
                "pixel_pitch": lens.pixel_pitch, "max_coc_radius": lens.max_coc_radius,
            },
            "psf_model": self.psf_model,
            "psf": self.psf.as_dict(),
            "distortion": None if self.distortion is None else {
                "name": self.distortion.name, "coefficients": list(self.distortion.coefficients)
            },
            "noise_model": self.noise_model,
            "noise_sigma": self.noise_sigma,
            "max_layers": self.max_layers,
            "render_mode": self.render_mode,
            **({} if self.disparity_ratio is None
               else {"disparity_ratio": list(self.disparity_ratio)}),
            **({} if not self.disparity_falloff
               else {"disparity_falloff": self.disparity_falloff}),
            **({} if self.light == "encoded" else {"light": self.light}),
            **({} if self.raw is None
               else {"raw": {"black_level": self.raw[0], "gain": self.raw[1]}}),
            **({} if not self.base_blur else {"base_blur": self.base_blur}),
        }


#: The largest in-focus blur (Gaussian std, px) a draw takes.
MAX_BASE_BLUR = 3.0


def check_base_blur(sigma: float, name: str = "base_blur") -> float:
    """A Gaussian std of the in-focus optics in [0, :data:`MAX_BASE_BLUR`] px."""
    return check_range(name, sigma, 0.0, MAX_BASE_BLUR, high_inclusive=True)


def check_base_blur_range(values, name: str = "base_blur") -> tuple[float, float]:
    """A range ``(low, high)`` of in-focus blurs to draw from, each :func:`check_base_blur`."""
    values = tuple(values)
    if len(values) != 2:
        raise ParameterError(f"{name} must be two stds LOW,HIGH in px, got {list(values)}")
    low, high = (check_base_blur(v, name) for v in values)
    if low > high:
        raise ParameterError(f"{name} must have LOW <= HIGH, got {low:g},{high:g}")
    return float(low), float(high)


def _init_with_old_names(init):
    """``SequenceDraw(camera=...)``, the old name of ``lens=``, taken with a warning (until
    release 0.3)."""

    @functools.wraps(init)
    def __init__(self, *args, camera: ThinLens | None = None, **kwargs) -> None:
        if camera is not None:
            from dualpixel.names import warn_renamed

            if "lens" in kwargs:
                raise ParameterError("give lens only (camera is its old name)")
            warn_renamed("SequenceDraw(camera=...)", "SequenceDraw(lens=...)", stacklevel=2)
            kwargs["lens"] = camera
        init(self, *args, **kwargs)

    return __init__


SequenceDraw.__init__ = _init_with_old_names(SequenceDraw.__init__)  # type: ignore[method-assign]


class CameraSettings(NamedTuple):
    """What a calibrated camera sets for :func:`draw_sequence` (:func:`camera_settings`)."""

    bank: PSFBank
    disparity_ratio: tuple[float, ...] | None  # per channel; None: the paper's views
    disparity_falloff: float  # across the frame (:func:`~dualpixel.optics.crosstalk.field_ratio`)
    light: Light

    def draw_options(self) -> dict[str, Any]:
        """The keywords of :func:`draw_sequence` these settings fill."""
        return self._asdict()


def camera_settings(
    camera: DPCamera | None,
    bank: PSFBank = PAPER_PSF_BANK,
    *,
    psf_shapes: str | None = None,
    light: str | None = None,
) -> CameraSettings:
    """What a calibrated camera (``dualpixel calibrate camera``) sets for :func:`draw_sequence`.

    The camera's fitted PSF shape replaces ``bank`` unless ``psf_shapes`` is "bank"; its
    per-channel disparity ratio and its falloff across the frame are applied; ``light``
    overrides the camera's light space. Without a camera: ``bank``, the paper's views and
    ``light`` or "encoded".
    """
    if psf_shapes is not None:
        if psf_shapes not in PSF_SHAPE_SOURCES:
            raise ParameterError(f"psf_shapes must be one of {', '.join(PSF_SHAPE_SOURCES)}, "
                                 f"got {psf_shapes!r}")
        if camera is None:
            raise ParameterError("psf_shapes chooses between a camera's PSF shape and the "
                                 "bank; it needs a camera")
    if light is not None:
        check_light(light)
    if camera is None:
        return CameraSettings(bank, None, 0.0, light or "encoded")  # type: ignore[arg-type]
    shapes = bank if psf_shapes == "bank" else PSFBank([camera.psf])
    return CameraSettings(shapes, camera.disparity_ratio, camera.disparity_falloff,
                          light or camera.light)  # type: ignore[arg-type]


def draw_sequence(
    seed: int | tuple[int, ...],
    lens: str | ThinLens,
    *,
    bank: PSFBank = PAPER_PSF_BANK,
    psf_model: PSFModel = "ours",
    distortion: bool = True,
    noise: bool = True,
    noise_model: NoiseModel = "multiplicative",
    noise_sigmas: tuple[float, ...] = PAPER_NOISE_SIGMAS,
    max_layers: int = 500,
    render_mode: str = "fast",
    disparity_ratio: tuple[float, ...] | None = None,
    disparity_falloff: float = 0.0,
    light: Light = "encoded",
    raw_black_level: float | None = None,
    raw_gains: tuple[float, float] = (1.0, 1.0),
    base_blur: tuple[float, float] = (0.0, 0.0),
) -> SequenceDraw:
    """Draw a sequence's PSF shape and noise strength from ``seed`` for a lens set's ``lens``
    (a name of :data:`~dualpixel.optics.thin_lens.PAPER_LENS_SETS` or a thin lens).

    A paper lens set ``setK`` gets the matching distortion preset ``setK`` (supplement S3); any
    other lens (e.g. one drawn from a defocus profile) a preset drawn from ``seed``. With a
    ``raw_black_level`` the sequence is stored as raw values, its exposure gain drawn
    uniformly from ``raw_gains``; the in-focus blur (:attr:`SequenceDraw.base_blur`) is drawn
    uniformly from ``base_blur`` (px), from a stream of its own so the other draws stay as they
    were without it.
    """
    check_psf_model(psf_model)
    check_render_mode(render_mode)
    if isinstance(lens, str):
        if lens not in PAPER_LENS_SETS:
            raise ParameterError(
                f"lens set must be one of {', '.join(PAPER_LENS_SETS)}, got {lens!r}"
            )
        lens = PAPER_LENS_SETS[lens]
    rng = np.random.default_rng(seed)
    psf = bank.sample(rng)
    sigma = sample_noise_sigma(rng, check_noise_sigmas(noise_sigmas))
    warp = DISTORTION_PRESETS.get(lens.name)
    if warp is None:
        presets = list(DISTORTION_PRESETS.values())
        warp = presets[int(np.random.default_rng((*np.atleast_1d(seed), 2)).integers(len(presets)))]
    raw = None
    if raw_black_level is not None:
        check_raw_storage(raw_black_level, raw_gains)
        gain = float(np.random.default_rng((*np.atleast_1d(seed), 3)).uniform(*raw_gains))
        raw = (float(raw_black_level), gain)
    low, high = check_base_blur_range(base_blur)
    in_focus = low if low == high else float(
        np.random.default_rng((*np.atleast_1d(seed), 4)).uniform(low, high))
    return SequenceDraw(
        lens=lens,
        psf=psf,
        distortion=warp if distortion else None,
        noise_sigma=sigma if noise else None,
        psf_model=psf_model,
        noise_model=noise_model,
        max_layers=max_layers,
        render_mode=render_mode,
        disparity_ratio=disparity_ratio,
        disparity_falloff=disparity_falloff,
        light=light,
        raw=raw,
        base_blur=in_focus,
    )


@dataclass
class DPFrame:
    """A synthetic frame, torch tensors with values in [0, 1] (defocus in pixels).

    ``left`` and ``right`` are at the brightness of the combined image (DPDD convention), so
    ``combined = (left + right) / 2`` (in linear light where the draw's ``light`` is
    "linear"); the paper's half-brightness views are ``left / 2``.
    """

    left: torch.Tensor  # (3, H, W)
    right: torch.Tensor  # (3, H, W)
    combined: torch.Tensor  # (3, H, W)
    target: torch.Tensor  # (3, H, W), the sharp all-in-focus image
    defocus: torch.Tensor  # (H, W), signed CoC radius in pixels


@dataclass(frozen=True)
class _Window:
    """Where a window's render sits: the whole frame's ``(H, W)``, the rendered region's top-left
    pixel, and the window ``(top, left, height, width)``, all in frame pixels."""

    frame: tuple[int, int]
    origin: tuple[int, int]
    window: tuple[int, int, int, int]

    def cut(self, region: torch.Tensor) -> torch.Tensor:
        """The window of ``(..., h, w)`` values of the rendered region."""
        top, left, rows, cols = self.window
        top, left = top - self.origin[0], left - self.origin[1]
        return region[..., top : top + rows, left : left + cols]


def _noisy_view(view: torch.Tensor, draw: SequenceDraw, seed: int,
                window: _Window | None = None) -> torch.Tensor:
    """``view`` ``(C, h, w)`` with its noise: the whole frame's draws (:func:`tiled_normals`),
    so a window's noise is the frame's there."""
    frame = tuple(view.shape[1:]) if window is None else window.frame
    gaussian = tiled_normals(view.shape[0], frame, seed,
                             None if window is None else window.window,
                             dtype=view.dtype, device=view.device)
    # Noise is added to the paper's half-brightness view I_l = view / 2 (Eq. 7).
    half = add_noise(view / 2.0, draw.noise_sigma, model=draw.noise_model, gaussian=gaussian)
    return 2.0 * half


def synthesize_frame(
    rgb: np.ndarray | torch.Tensor,
    depth: np.ndarray | torch.Tensor,
    draw: SequenceDraw,
    *,
    noise_seed: int = 0,
    device: str | torch.device = "cpu",
    window: tuple[int, int, int, int] | None = None,
) -> DPFrame:
    """Synthesise DP views for one all-in-focus frame.

    Args:
        rgb: ``(H, W, 3)`` NumPy or ``(3, H, W)`` torch image in [0, 1].
        depth: ``(H, W)`` depth, same unit as the lens, finite and > 0.
        draw: lens, PSF, distortion and noise of the sequence.
        noise_seed: seed of this frame's noise; the views draw independent noise from it.
        device: where to compute ("cpu", "cuda", ...).
        window: ``(top, left, height, width)`` px: render only this window of the frame, with
            the whole frame's layers and the blur margin around it (:func:`render_region`), so
            it equals that window of the whole frame's render to float rounding (training crops
            on the fly). The default ("fast") render mode only.

    Returns:
        A :class:`DPFrame` on ``device``, of the window's size where one is given.
    """
    image, scene, coc = _prepared(rgb, depth, draw, device)
    if window is None:
        left, right = render_dp_views(
            scene, coc, draw.psf, model=draw.psf_model, max_layers=draw.max_layers,
            mode=draw.render_mode,
        )
        return _finished(image, scene, coc, left, right, draw, noise_seed)
    if draw.render_mode != "fast":
        raise ParameterError("a window is rendered with the default (fast) layering only")
    window = _checked_window(window, coc.shape)
    row0, row1, col0, col1 = render_region(coc, draw, window)
    place = _Window(tuple(coc.shape), (row0, col0), window)
    rows, cols = slice(row0, row1), slice(col0, col1)
    labels, layer_coc = quantise_layers(coc, draw.max_layers, mode="fast")
    left, right = render_fast(scene[:, rows, cols], coc[rows, cols], draw.psf,
                              model=draw.psf_model, layers=(labels[rows, cols], layer_coc))
    return _finished(image[:, rows, cols], scene[:, rows, cols], coc[rows, cols], left, right,
                     draw, noise_seed, place)


def _checked_window(window, frame: tuple[int, int]) -> tuple[int, int, int, int]:
    top, left, rows, cols = (int(v) for v in window)
    if rows < 1 or cols < 1 or top < 0 or left < 0 or top + rows > frame[0] \
            or left + cols > frame[1]:
        raise ParameterError(f"window {cols}x{rows} at ({left}, {top}) does not lie inside the "
                             f"{frame[1]}x{frame[0]} frame")
    return top, left, rows, cols


def render_region(coc: torch.Tensor, draw: SequenceDraw, window: tuple[int, int, int, int]
                  ) -> tuple[int, int, int, int]:
    """Half-open ``(row0, row1, col0, col1)`` of the frame (CoC map ``(H, W)`` px) to render for
    ``window`` ``(top, left, height, width)``: the pixels its distortion reads, grown by the
    blur margin of the frame's largest CoC (:func:`~dualpixel.synthesis.fast_renderer.
    crop_margin`) and the reach of the in-focus blur, from an origin on its coarsest
    resolution's grid, clipped to the frame."""
    height, width = coc.shape
    top, left, rows, cols = window
    needed = (top, top + rows, left, left + cols)
    if draw.distortion is not None:
        needed = window_sources(draw.distortion, (height, width), window)
    largest = float(coc.abs().max())
    margin = crop_margin(largest, draw.psf_model, (draw.psf or PSFParams()).kappa) \
        + gaussian_reach(draw.base_blur)
    grid = downsample_factor(largest)  # the coarsest resolution's cells start on it
    return (max(needed[0] - margin, 0) // grid * grid, min(needed[1] + margin, height),
            max(needed[2] - margin, 0) // grid * grid, min(needed[3] + margin, width))


def sharp_target(rgb: np.ndarray | torch.Tensor, depth: np.ndarray | torch.Tensor,
                 draw: SequenceDraw, *, device: str | torch.device = "cpu") -> torch.Tensor:
    """The frame's sharp target ``(3, H, W)`` in [0, 1] as :func:`synthesize_frame` makes it
    (distorted, in the views' encoding), without rendering the views."""
    image, scene, _ = _prepared(rgb, depth, draw, device)
    target = scene if draw.distortion is None else distort_image(scene, draw.distortion)
    return _encoded_target(image, target, draw).clamp(0.0, 1.0)


def _encoded_target(image: torch.Tensor, target: torch.Tensor, draw: SequenceDraw
                    ) -> torch.Tensor:
    """The sharp target (in the light the lens blurs, distorted) in the views' encoding."""
    if draw.raw is not None:
        return linear_to_raw(target, *draw.raw)
    if draw.light == "linear":  # the target is the input itself unless the distortion moved it
        return linear_to_srgb(target) if draw.distortion is not None else image
    return target


def synthesize_frames(
    frames: list[tuple[np.ndarray | torch.Tensor, np.ndarray | torch.Tensor]],
    draws: list[SequenceDraw],
    noise_seeds: list[int],
    *,
    device: str | torch.device = "cpu",
    windows: list[tuple[int, int, int, int] | None] | None = None,
) -> list[DPFrame]:
    """:func:`synthesize_frame` for many frames at once: the frames of one size are rendered
    together by :func:`~dualpixel.synthesis.batched_renderer.render_batch` (the default
    renderer's layers and compositing, for accelerators), the rest of the formation per frame.
    The draws' render mode must be "fast"; each frame keeps its own lens, PSF and noise.

    ``windows``: per frame ``(top, left, height, width)`` px or None, as
    :func:`synthesize_frame`'s ``window`` (training crops on the fly): the windows of one frame
    size render together, each from a region of its frame grown to the group's common size
    (:func:`common_regions`), and equal those windows of the whole frames' renders."""
    from dualpixel.synthesis.batched_renderer import render_batch

    windows = [None] * len(frames) if windows is None else list(windows)
    if not len(frames) == len(draws) == len(noise_seeds) == len(windows):
        raise ParameterError("frames, draws, noise_seeds and windows need one entry per frame")
    prepared = [_prepared(rgb, depth, draw, device) for (rgb, depth), draw in zip(frames, draws)]
    places: list[_Window | None] = [None] * len(frames)
    groups: dict[tuple, list[int]] = {}
    for k, ((_, scene, coc), draw, window) in enumerate(zip(prepared, draws, windows)):
        if draw.render_mode != "fast":
            raise ParameterError("synthesize_frames renders the default (fast) layering")
        if window is not None:
            window = _checked_window(window, coc.shape)
            places[k] = _Window(tuple(coc.shape), (0, 0), window)
        groups.setdefault((tuple(scene.shape), draw.max_layers, window is not None),
                          []).append(k)
    views: list[tuple[torch.Tensor, torch.Tensor] | None] = [None] * len(frames)
    for (_, max_layers, windowed), members in groups.items():
        regions = [(0, prepared[k][2].shape[0], 0, prepared[k][2].shape[1]) for k in members]
        layers = None
        if windowed:
            regions = common_regions([render_region(prepared[k][2], draws[k], windows[k])
                                      for k in members], prepared[members[0]][2].shape)
            layers = []
            for k, (row0, row1, col0, col1) in zip(members, regions):
                places[k] = _Window(places[k].frame, (row0, col0), places[k].window)
                labels, layer_coc = quantise_layers(prepared[k][2], max_layers, mode="fast")
                layers.append((labels[row0:row1, col0:col1], layer_coc))
        cut = [(slice(r0, r1), slice(c0, c1)) for r0, r1, c0, c1 in regions]
        left, right = render_batch(
            torch.stack([prepared[k][1][:, rows, cols] for k, (rows, cols) in zip(members, cut)]),
            torch.stack([prepared[k][2][rows, cols] for k, (rows, cols) in zip(members, cut)]),
            [draws[k].psf for k in members], model=[draws[k].psf_model for k in members],
            max_layers=max_layers, layers=layers)
        for i, (k, (rows, cols)) in enumerate(zip(members, cut)):
            image, scene, coc = prepared[k]
            prepared[k] = (image[:, rows, cols], scene[:, rows, cols], coc[rows, cols])
            views[k] = (left[i], right[i])
    return [_finished(*inputs, *pair, draw, seed, place)
            for inputs, pair, draw, seed, place in zip(prepared, views, draws, noise_seeds, places)]


def common_regions(regions: list[tuple[int, int, int, int]], frame: tuple[int, int]
                   ) -> list[tuple[int, int, int, int]]:
    """Half-open ``(row0, row1, col0, col1)`` regions of one ``(H, W)`` frame size, each grown to
    hold the one given (:func:`render_region`) at a size common to all, from an origin on the
    :data:`~dualpixel.synthesis.fast_renderer.MAX_DOWNSAMPLE` grid (every resolution's), inside
    the frame: so they render as one batch, each as its own region would."""
    sizes = []
    for axis, total in enumerate(frame):
        spans = [(r[2 * axis], r[2 * axis + 1]) for r in regions]
        size = min(max(hi - lo for lo, hi in spans), total)
        while True:  # one size for all: grown by the grid until every region fits
            starts = [min(lo, total - size) // MAX_DOWNSAMPLE * MAX_DOWNSAMPLE
                      for lo, _ in spans]
            if all(start + size >= hi for start, (_, hi) in zip(starts, spans)):
                break
            size = min(size + MAX_DOWNSAMPLE, total)
        sizes.append([(start, start + size) for start in starts])
    return [(*rows, *cols) for rows, cols in zip(*sizes)]


def _prepared(rgb, depth, draw: SequenceDraw, device) -> tuple[torch.Tensor, ...]:
    """``(image (3, H, W), scene (3, H, W) in the light the lens blurs, coc (H, W) px)``."""
    image = torch.as_tensor(rgb, dtype=torch.float32, device=device)
    if isinstance(rgb, np.ndarray):
        image = image.permute(2, 0, 1)
    depth_t = torch.as_tensor(depth, dtype=torch.float32, device=device)
    if image.ndim != 3 or image.shape[0] != 3 or depth_t.shape != image.shape[1:]:
        raise ParameterError(
            f"rgb and depth must be the same size; got rgb {tuple(image.shape)} and depth "
            f"{tuple(depth_t.shape)}"
        )
    coc = coc_radius(depth_t, draw.lens)
    scene = srgb_to_linear(image) if draw.light == "linear" else image
    return image, scene, coc


def _finished(image: torch.Tensor, scene: torch.Tensor, coc: torch.Tensor, left: torch.Tensor,
              right: torch.Tensor, draw: SequenceDraw, noise_seed: int,
              window: _Window | None = None) -> DPFrame:
    """The rendered views through the rest of the formation: in-focus blur, crosstalk,
    distortion, tone or raw storage, noise, clipping and the combined image. ``window``: the
    inputs are a rendered region of a frame and the result is that window of it."""
    linear = draw.light == "linear"
    if draw.base_blur:  # the in-focus optics, in the light the lens blurs; not the target
        left, right = gaussian_blur(torch.stack((left, right)), draw.base_blur).unbind()
    if draw.disparity_ratio is not None:
        columns = {} if window is None else {"first_column": window.origin[1],
                                              "frame_width": window.frame[1]}
        left, right = apply_crosstalk(left, right, draw.disparity_ratio, draw.disparity_falloff,
                                      **columns)
    target, defocus = scene, coc
    if draw.distortion is not None:
        # one warp for all planes: the inverse-distortion grid is computed once per frame
        planes = torch.cat((left, right, target, coc[None]))
        warped = (distort_image(planes, draw.distortion) if window is None else
                  distort_window(planes, draw.distortion, window.frame, window.origin,
                                 window.window))
        left, right, target, defocus = warped.split((3, 3, 3, 1))
        defocus = defocus[0]
    elif window is not None:
        left, right, target, defocus = (window.cut(t) for t in (left, right, target, defocus))
    if window is not None:
        image = window.cut(image)
    light = (left, right)  # the views' light, before any tone curve or noise
    if draw.raw is not None:  # stored as raw values, still linear; noise is added to them
        left, right = (linear_to_raw(t, *draw.raw) for t in (left, right))
    elif linear:  # the tone curve after the optics; noise is added to the stored values
        left, right = linear_to_srgb(left), linear_to_srgb(right)
    target = _encoded_target(image, target, draw)
    noisy = draw.noise_sigma is not None and draw.noise_sigma > 0
    if noisy:
        left = _noisy_view(left, draw, noise_seed * 2, window)
        right = _noisy_view(right, draw, noise_seed * 2 + 1, window)
    left, right, target = (t.clamp(0.0, 1.0) for t in (left, right, target))
    if linear and draw.raw is None:  # the two photodiodes' light summed, then the tone curve
        if noisy:  # the light of the stored (noisy) views
            light = (srgb_to_linear(left), srgb_to_linear(right))
        combined = linear_to_srgb((light[0].clamp(0.0, 1.0) + light[1].clamp(0.0, 1.0)) / 2.0)
    else:  # stored values (raw ones are linear: the light summed, the black level once)
        combined = (left + right) / 2.0
    return DPFrame(left, right, combined, target, defocus)
