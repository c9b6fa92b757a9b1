"""A camera's DP blur model from real DP pairs with sharp targets (ours; no anchor has it).

For every ``patch x patch`` block and colour channel of a pair (left ``L``, right ``R``, sharp
target ``T``), the views are explained by our model (Eq. 2-4) with view crosstalk
(:mod:`dualpixel.optics.crosstalk`): for a CoC radius ``r >= 0`` on a grid, ``A = T * H_l(r)`` and
``B = T * H_r(r)`` (each view kernel summing to one) and the least-squares fit, closed form per
block,

    L ~ p A + q B + o,    R ~ p B + q A + o

(``p, q`` a gain and the crosstalk, ``o`` an offset for the target's other exposure). The best
``r`` by residual is the block's blur and ``a = (p - q) / (p + q)`` its *signed* disparity ratio:
``|a|`` is the fraction of the model's disparity the camera keeps, the sign says in front of or
behind the focal plane (the same for all channels of a block, so green's sign orients the others).
The camera's ratio per channel is the median over usable blocks (textured, blurred by at least
``min_radius`` px in green and not at the grid's end). The PSF shape is the candidate of least
total residual. The winning shape is then fitted again to the pairs decoded to linear light
(:mod:`dualpixel.optics.tone`); where that fit leaves a smaller share of the views' variance in
most usable blocks, the camera blurs in linear light (``light: "linear"``) and its ratios and
blur sizes come from that fit. Because the fit is our synthesis model itself, data made with
known parameters give them back (``tests/calibration/test_camera.py``).
"""

from __future__ import annotations

import warnings
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from dualpixel.data.statistics import block_sums
from dualpixel.errors import InputFileError, ParameterError, check_range
from dualpixel.optics.camera import DPCamera, load_camera
from dualpixel.optics.psf import PSFParams, dp_psf
from dualpixel.optics.tone import srgb_to_linear_array

# The camera file type lives in dualpixel.optics.camera; DPCamera and load_camera stay
# importable from here until release 0.3.
__all__ = [
    "BlockFits",
    "CameraCalibration",
    "DPCamera",
    "calibrate_camera",
    "disparity_falloff",
    "fit_blocks",
    "linear_light_share",
    "load_camera",
    "view_kernels",
]

#: Blocks whose target's mean absolute horizontal gradient (per channel, [0, 1] units) is below
#: this hold too little texture to show their blur.
MIN_TEXTURE = 0.01
#: Fewest usable blocks a calibration rests on.
MIN_BLOCKS = 20
#: Largest shift (px) between the target and the views' mean that counts as aligned.
MAX_MISALIGNMENT = 1.0
#: The PSF shape a calibration fits unless given candidates (the Pixel 4 fits' mode).
DEFAULT_PSF = PSFParams(n=3, alpha=0.45, beta=0.2, kappa=0.21)


@dataclass
class BlockFits:
    """Per block and channel ``(rows, cols, C)``: CoC radius (px, >= 0), signed disparity ratio,
    residual (sum of squares over both views), target texture, the views' sum of squares about
    their block mean (``residual / variance``: the share the model leaves unexplained);
    ``centres`` ``(rows, cols, 2)`` (x, y) px."""

    radius: np.ndarray
    ratio: np.ndarray
    residual: np.ndarray
    texture: np.ndarray
    centres: np.ndarray
    variance: np.ndarray


def _sums(values: np.ndarray, patch: int) -> np.ndarray:
    """Block sums accumulated in float64 (the normal equations subtract large sums)."""
    return block_sums(values, patch, np.float64)


def view_kernels(radius: float, params: PSFParams) -> tuple[np.ndarray, np.ndarray]:
    """Left and right kernels of CoC radius ``radius`` (each summing to 1), flipped for
    ``cv2.filter2D`` (which correlates)."""
    kernels = dp_psf(float(radius), params)
    return tuple(np.ascontiguousarray((2.0 * k.numpy())[::-1, ::-1], np.float32)
                 for k in (kernels.left, kernels.right))


def fit_blocks(
    left: np.ndarray, right: np.ndarray, target: np.ndarray, params: PSFParams,
    radii: Sequence[float], *, patch: int = 48,
) -> BlockFits:
    """The closed-form fit of the module docstring for every block, channel and radius in
    ``radii`` (px, >= 0); images ``(H, W, C)`` float in [0, 1] of one size."""
    if not (left.shape == right.shape == target.shape) or left.ndim != 3:
        raise ParameterError(f"left, right and target must be (H, W, C) of one size, got "
                             f"{left.shape}, {right.shape} and {target.shape}")
    margin = int(np.ceil(max(radii) * 1.5)) + 2
    height, width = left.shape[:2]
    if min(height, width) < 2 * margin + patch:
        raise ParameterError(f"images of {width}x{height} are too small for {patch}-px blocks "
                             f"and blur up to {max(radii):g} px")
    inner = (slice(margin, height - margin), slice(margin, width - margin))
    lo, ro = (np.asarray(v, np.float32)[inner] for v in (left, right))
    sharp = np.ascontiguousarray(target, np.float32)
    count = 2.0 * patch * patch
    sums = {"ll": _sums(lo * lo + ro * ro, patch), "l1": _sums(lo + ro, patch)}
    best = None
    for radius in radii:
        if radius <= 0:
            a = b = sharp[inner]
        else:
            kl, kr = view_kernels(radius, params)
            a = cv2.filter2D(sharp, -1, kl, borderType=cv2.BORDER_REFLECT)[inner]
            b = cv2.filter2D(sharp, -1, kr, borderType=cv2.BORDER_REFLECT)[inner]
        m11 = _sums(a * a + b * b, patch)
        m12 = 2.0 * _sums(a * b, patch)
        m13 = _sums(a + b, patch)
        rhs = np.stack([_sums(lo * a + ro * b, patch), _sums(lo * b + ro * a, patch),
                        sums["l1"]], axis=-1)
        n = np.full_like(m11, count)
        matrix = np.stack([np.stack([m11, m12, m13], -1), np.stack([m12, m11, m13], -1),
                           np.stack([m13, m13, n], -1)], axis=-2)
        matrix = matrix + 1e-9 * count * np.eye(3)
        solution = np.linalg.solve(matrix, rhs[..., None])[..., 0]
        residual = sums["ll"] - (solution * rhs).sum(-1)
        if best is None:
            best = {"residual": residual, "radius": np.full(residual.shape, float(radius)),
                    "solution": solution}
            continue
        better = residual < best["residual"]
        best["residual"] = np.where(better, residual, best["residual"])
        best["radius"] = np.where(better, float(radius), best["radius"])
        best["solution"] = np.where(better[..., None], solution, best["solution"])
    p, q = best["solution"][..., 0], best["solution"][..., 1]
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = np.where(np.abs(p + q) > 1e-6, (p - q) / (p + q), 0.0)
    gradient = np.abs(np.diff(sharp[inner], axis=1, append=sharp[inner][:, -1:]))
    rows, cols = best["radius"].shape[:2]
    ys, xs = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    centres = np.stack([margin + (xs + 0.5) * patch, margin + (ys + 0.5) * patch], axis=-1)
    variance = sums["ll"] - sums["l1"] ** 2 / count
    return BlockFits(best["radius"], ratio, best["residual"],
                     _sums(gradient, patch) / patch**2, centres, variance)


@dataclass
class CameraCalibration:
    """The camera model and what it was measured from: per PSF candidate the total residual,
    and the block fits of the winning candidate (one :class:`BlockFits` per frame fitted, in
    the light space that won), and the share of blocks that linear light explains better."""

    camera: DPCamera
    scores: list[tuple[PSFParams, float]]
    fits: list[BlockFits]
    usable: list[np.ndarray]  # per frame, (rows, cols) bool: the blocks the ratios rest on
    frames: list[tuple[str, np.ndarray, np.ndarray, np.ndarray]]  # the frames fitted (aligned)
    linear_share: float = 0.0


def linear_light_share(encoded: list[BlockFits], linear: list[BlockFits], min_radius: float,
                       max_radius: float) -> float:
    """The share of blocks usable in both fits (all channels together) that the fit in linear
    light explains better than the fit of the stored values, by the share of the views'
    variance each leaves (:mod:`dualpixel.optics.tone`); 0 without such blocks."""
    better, total = 0, 0
    for a, b in zip(encoded, linear):
        both = _usable(a, min_radius, max_radius) & _usable(b, min_radius, max_radius)
        with np.errstate(invalid="ignore", divide="ignore"):
            left = (a.residual / a.variance).sum(-1)[both]
            right = (b.residual / b.variance).sum(-1)[both]
        better += int((right < left).sum())
        total += int(both.sum())
    return better / total if total else 0.0


def _usable(fit: BlockFits, min_radius: float, max_radius: float) -> np.ndarray:
    green = fit.radius[..., 1]
    return ((fit.texture.min(axis=-1) > MIN_TEXTURE) & (green >= min_radius)
            & (green < max_radius) & np.isfinite(fit.ratio).all(axis=-1))


def image_shift(moving: np.ndarray, fixed: np.ndarray, *, search: int = 4,
                smoothing: float = 3.0) -> tuple[float, float]:
    """The (dx, dy) px, within +-``search``, that best moves grey ``moving`` onto ``fixed``
    (SSD of both smoothed by a Gaussian of std ``smoothing`` px, so defocus matters little;
    integer search refined by a parabola per axis)."""
    a, b = (cv2.GaussianBlur(np.asarray(x, np.float32), (0, 0), smoothing) for x in (moving, fixed))
    m = search + 1
    core = b[m:-m, m:-m]
    cost = np.array([[np.mean((a[m + dy: a.shape[0] - m + dy, m + dx: a.shape[1] - m + dx]
                                - core) ** 2) for dx in range(-search, search + 1)]
                     for dy in range(-search, search + 1)])
    if np.ptp(cost) <= 1e-12:  # no structure: nothing tells a shift
        return 0.0, 0.0
    iy, ix = np.unravel_index(np.argmin(cost), cost.shape)

    def refine(c0: float, c1: float, c2: float) -> float:
        curvature = c0 - 2 * c1 + c2
        return 0.0 if curvature <= 0 else float(np.clip(0.5 * (c0 - c2) / curvature, -0.5, 0.5))

    fx = refine(*cost[iy, ix - 1: ix + 2]) if 0 < ix < 2 * search else 0.0
    fy = refine(*cost[iy - 1: iy + 2, ix]) if 0 < iy < 2 * search else 0.0
    return -(ix - search + fx), -(iy - search + fy)


def check_alignment(left: np.ndarray, right: np.ndarray, target: np.ndarray,
                    source: str | Path, max_radius: float = 12.0) -> None:
    """Refuse a target shifted against the views' mean by more than :data:`MAX_MISALIGNMENT`
    (both smoothed by a third of the largest blur, so strong defocus does not read as a shift)."""
    views = np.asarray((left + right) / 2, np.float32).mean(axis=-1)
    dx, dy = image_shift(np.asarray(target, np.float32).mean(axis=-1), views,
                         smoothing=max(3.0, max_radius / 3))
    if np.hypot(dx, dy) > MAX_MISALIGNMENT:
        raise InputFileError(source, f"the target is shifted by ({dx:+.1f}, {dy:+.1f}) px against "
                                     "the views: pairs must be aligned to calibrate")


def disparity_falloff(fits: Sequence[BlockFits], usable: Sequence[np.ndarray],
                      width: int) -> float:
    """How the blocks' green disparity ratio falls from the middle of the frame to its left and
    right sides (:mod:`dualpixel.optics.crosstalk`): ``ratio = a - b x^2`` fitted to the median
    ratio of the blocks in each fifth of ``|x|`` (``x`` -1 to 1 across ``width``; single blocks'
    ratios have long tails), weighted by their counts; ``b / a`` clipped to [0, 0.9]. 0 where
    fewer than a quarter of the blocks lie in the outer halves of the width."""
    x = np.concatenate([f.centres[..., 0][u] for f, u in zip(fits, usable)]) / width * 2 - 1
    ratio = np.abs(np.concatenate([f.ratio[..., 1][u] for f, u in zip(fits, usable)]))
    if len(x) < MIN_BLOCKS or np.mean(np.abs(x) > 0.5) < 0.25:
        return 0.0
    bins = np.minimum((np.abs(x) * 5).astype(int), 4)
    rows = [(np.mean(x[bins == b] ** 2), np.median(ratio[bins == b]), np.sum(bins == b))
            for b in range(5) if np.sum(bins == b) >= 5]
    if len(rows) < 3:
        return 0.0
    square, median, count = (np.asarray(v, np.float64) for v in zip(*rows))
    weight = np.sqrt(count)
    design = np.stack([np.ones_like(square), -square], axis=1) * weight[:, None]
    level, slope = np.linalg.lstsq(design, median * weight, rcond=None)[0]
    return float(np.clip(slope / level, 0.0, 0.9)) if level > 0 else 0.0


def calibrate_camera(
    frames: Iterable[tuple[str, np.ndarray, np.ndarray, np.ndarray]],
    *,
    name: str = "camera",
    psf_candidates: Sequence[PSFParams] = (DEFAULT_PSF,),
    patch: int = 48,
    max_radius: float = 12.0,
    radius_step: float | None = None,
    min_radius: float = 2.0,
    skip_misaligned: bool = False,
    falloff: bool = False,
    progress: bool = False,
) -> CameraCalibration:
    """Measure a camera's DP model from ``(name, left, right, target)`` frames (float
    ``(H, W, 3)`` in [0, 1], views at the combined image's brightness); see the module docstring.
    With ``falloff`` the disparity ratio's fall towards the frame's sides is measured too
    (:func:`disparity_falloff`; otherwise the camera keeps one ratio everywhere).

    Raises:
        InputFileError: a frame whose target is misaligned with its views (named); with
            ``skip_misaligned`` such frames are left out with a warning instead.
        ParameterError: fewer than :data:`MIN_BLOCKS` usable blocks over all frames.
    """
    from dualpixel.data.statistics import noise_level
    from dualpixel.progress import progress_bar

    check_range("patch", patch, 8)
    radius_step = max_radius / 48 if radius_step is None else radius_step
    check_range("radius_step", radius_step, 0.0, low_inclusive=False)
    check_range("max_radius", max_radius, 2 * radius_step)
    check_range("min_radius", min_radius, 0.0, max_radius)
    if not psf_candidates:
        raise ParameterError("give at least one PSF candidate")
    radii = np.arange(0.0, max_radius + radius_step / 2, radius_step)
    frames = list(frames)
    if not frames:
        raise ParameterError("no frames to calibrate from")
    aligned = []
    for frame in frames:
        try:
            check_alignment(*frame[1:], frame[0], max_radius)
        except InputFileError as error:
            if not skip_misaligned:
                raise
            warnings.warn(f"left out: {error}", stacklevel=2)
            continue
        aligned.append(frame)
    if not aligned:
        raise ParameterError("every frame's target is misaligned with its views")
    frames = aligned
    scores, all_fits = [], []
    bar = progress_bar(total=len(psf_candidates) * len(frames), desc="calibrating camera",
                       enabled=progress)
    for params in psf_candidates:
        fits = []
        for _, left, right, target in frames:
            fits.append(fit_blocks(left, right, target, params, radii, patch=patch))
            bar.update(1)
        total = sum(float(f.residual[_usable(f, min_radius, max_radius)].sum()) for f in fits)
        scores.append((params, total))
        all_fits.append(fits)
    bar.close()
    winner = int(np.argmin([s for _, s in scores]))
    fits = all_fits[winner]
    # where the blur happens: the winning shape fitted again in linear light
    linear_fits = [fit_blocks(srgb_to_linear_array(left), srgb_to_linear_array(right),
                              srgb_to_linear_array(target), scores[winner][0],
                              radii, patch=patch) for _, left, right, target in frames]
    share = linear_light_share(fits, linear_fits, min_radius, max_radius)
    light = "linear" if share > 0.5 else "encoded"
    if light == "linear":
        fits = linear_fits
    usable = [_usable(f, min_radius, max_radius) for f in fits]
    count = int(sum(u.sum() for u in usable))
    if count < MIN_BLOCKS:
        raise ParameterError(
            f"too few usable blocks: {count} of {sum(u.size for u in usable)} are textured and "
            f"blurred by {min_radius:g}-{max_radius:g} px (need {MIN_BLOCKS}); give more or "
            "blurrier pairs, a smaller patch or a larger max_radius")
    ratios = np.concatenate([f.ratio[u] for f, u in zip(fits, usable)])  # (n, C)
    oriented = ratios * np.sign(ratios[:, 1:2])  # green's sign: front or behind focus
    textured = np.concatenate([f.radius[..., 1][f.texture.min(axis=-1) > MIN_TEXTURE]
                               for f in fits])
    camera = DPCamera(
        name=name, width=int(frames[0][1].shape[1]),
        disparity_ratio=tuple(float(np.clip(np.median(oriented[:, c]), 0.0, 1.5))
                              for c in range(oriented.shape[1])),  # type: ignore[arg-type]
        psf=scores[winner][0],
        noise_std=float(np.median([noise_level(np.asarray(left, np.float32))
                                   for _, left, _, _ in frames])),
        coc_percentiles={f"p{p}": round(float(np.percentile(textured, p)), 3)
                         for p in (10, 25, 50, 75, 90)},
        blocks=count,
        light=light,
        disparity_falloff=(disparity_falloff(fits, usable, int(frames[0][1].shape[1]))
                           if falloff else 0.0),
    )
    return CameraCalibration(camera, scores, fits, usable, frames, share)


def read_calibration_frames(
    roots: Sequence[str | Path], split: str | None = None, *, require_target: bool = True,
) -> list[tuple[str, np.ndarray, np.ndarray, np.ndarray | None]]:
    """``(name, left, right, target)`` of every frame under ``roots`` (DPDD-layout folders or
    folders of scene folders), float ``(H, W, 3)`` in [0, 1]; a frame without a target is
    refused by name, or with ``require_target=False`` given with ``target`` None."""
    from dualpixel.data.layout import discover_any, read_frame

    frames = []
    for root in roots:
        for sequence in discover_any(root, split, require_target=require_target):
            for paths in sequence.frames:
                images = read_frame(paths)
                frames.append((str(paths.left), images["left"], images["right"],
                               images.get("target")))
    if not frames:
        raise InputFileError(roots[0], "holds no DP pairs with targets" if require_target
                             else "holds no DP pairs")
    return frames


def estimate_block_kernels(
    left: np.ndarray, right: np.ndarray, target: np.ndarray, centre: tuple[float, float],
    patch: int, half: int, smoothness: float = 0.02,
) -> tuple[np.ndarray, np.ndarray]:
    """Non-parametric left and right kernels ``(2 half + 1,) * 2`` of one grey block around
    ``centre`` (x, y): least squares of ``target * K`` against each view over the block, with a
    ``smoothness`` weight on the kernel's gradient (for figures: the fitted model beside them)."""
    from numpy.lib.stride_tricks import sliding_window_view

    x, y = (round(c) for c in centre)
    h0, w0 = y - patch // 2, x - patch // 2
    grey = [np.asarray(v, np.float64).mean(axis=-1) for v in (left, right, target)]
    sharp = grey[2][h0 - half : h0 + patch + half, w0 - half : w0 + patch + half]
    columns = sliding_window_view(sharp, (2 * half + 1, 2 * half + 1))[:patch, :patch]
    design = columns.reshape(patch * patch, -1)[:, ::-1]  # convolution, not correlation
    design = np.concatenate([design, np.ones((design.shape[0], 1))], axis=1)  # offset
    size = 2 * half + 1
    eye = np.eye(size * size)
    grad_x = (np.roll(eye.reshape(size, size, -1), -1, axis=1)
              - eye.reshape(size, size, -1)).reshape(size * size, -1)
    grad_y = (np.roll(eye.reshape(size, size, -1), -1, axis=0)
              - eye.reshape(size, size, -1)).reshape(size * size, -1)
    penalty = np.zeros((size * size + 1,) * 2)
    penalty[:-1, :-1] = grad_x.T @ grad_x + grad_y.T @ grad_y
    normal = design.T @ design
    normal += smoothness * np.trace(normal) / normal.shape[0] * penalty
    kernels = []
    for view in grey[:2]:
        observed = view[h0 : h0 + patch, w0 : w0 + patch].reshape(-1)
        solution = np.linalg.solve(normal, design.T @ observed)[:-1].reshape(size, size)
        solution = np.clip(solution, 0.0, None)
        kernels.append(solution / max(solution.sum(), 1e-12))
    return kernels[0], kernels[1]
