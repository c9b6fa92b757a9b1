"""A camera's DP blur model from its DP pairs alone, without sharp targets (ours).

Two views of one block, ``L = S * K_l + n_l`` and ``R = S * K_r + n_r`` for an unknown sharp
``S`` and white noise of variance ``s^2`` in each view, satisfy the cross-convolution identity
``L * K_r = R * K_l`` up to noise (Punnappurath et al., ICCP 2020). With our kernels at CoC
radius ``r`` (Eq. 2-4) mixed by the disparity ratio ``a`` (:mod:`dualpixel.optics.crosstalk`:
``K_l = H_c + a H_d``, ``K_r = H_c - a H_d``) the residual is

    L * K_r - R * K_l = D * H_c - 2 a C * H_d,    D = L - R,   C = (L + R) / 2,

and eliminating ``S`` per frequency (least squares) whitens it by ``1 / sqrt(|K_l|^2 +
|K_r|^2)``: its noise is then white with variance ``s^2``, whatever ``r`` and ``a``. Here the
whitening ``W = 1 / sqrt(2 |H_c|^2 + 2 a0^2 |H_d|^2 + lambda)`` is taken at a prior ratio ``a0``
and regularised by ``lambda`` (views that depart from the model at frequencies the kernels
suppress are not amplified without bound), so each block's energy is quadratic in ``a``:

    E(r, a) = sum_block (P - 2 a Q)^2 / N(r, a),   P = D * W H_c,   Q = C * W H_d,

divided by ``N(r, a)``, the energy per pixel that unit white noise leaves in ``P - 2 a Q``: noise
adds the same to every candidate's energy, so the least energy is not pulled toward large radii
or small ratios, as the identity's plain residual is (``docs/log/2026-12-02-target-free-camera
.md``). ``E`` over ``sum |D|^2 / 2`` (the energy at ``a = 0``) is the *share* of the views'
difference a candidate leaves.

The camera's constants are pooled over every block of every pair: one ratio per channel, each
block's radius and side of the focal plane shared by its channels, chosen by coordinate descent
on the summed shares of the informative blocks (:func:`pool_constants`);
:func:`calibrate_camera_from_views` adds the PSF shape, the light space and the camera file.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.fft
import torch

from dualpixel.calibration.camera import DEFAULT_PSF, MIN_BLOCKS
from dualpixel.data.statistics import block_sums
from dualpixel.errors import ParameterError, check_range
from dualpixel.optics.camera import DPCamera
from dualpixel.optics.psf import PSFParams, view_spectra
from dualpixel.optics.tone import srgb_to_linear_array

__all__ = ["PooledFit", "TargetFreeCalibration", "ViewEnergies", "blocks_at_ratios",
           "calibrate_camera_from_views", "grey_as_one_channel", "pool_constants",
           "view_energies"]

#: A block is informative when its best candidate leaves at most this share of the views'
#: difference, and the candidates' median leaves at least ``1 + MIN_CONTRAST`` times the best.
MAX_SHARE = 0.8
MIN_CONTRAST = 0.05


@dataclass
class ViewEnergies:
    """Whitened residual energies of one pair.

    ``energy`` ``(C, R, 2, A, rows, cols)``: per channel, radius ``radii[i]`` (px), side (0: the
    ratio ``+a``, 1: ``-a``) and ratio ``ratios[j]``; ``reference`` ``(C, rows, cols)``: the
    energy at ``a = 0`` (half the views' difference); ``centres`` ``(rows, cols, 2)`` (x, y) px.
    """

    energy: np.ndarray
    reference: np.ndarray
    radii: np.ndarray
    ratios: np.ndarray
    centres: np.ndarray


def view_energies(
    left: np.ndarray, right: np.ndarray, params: PSFParams, radii: Sequence[float],
    ratios: Sequence[float], *, patch: int = 48, prior_ratio: float = 0.8,
    regularisation: float = 0.1,
) -> ViewEnergies:
    """The energies of the module docstring for one pair of views ``(H, W, C)`` (linear light or
    stored values, [0, 1]), every ``patch`` block inside a margin of 1.5 times the largest
    radius, every radius in ``radii`` (px, > 0) and ratio in ``ratios`` (> 0; both sides of the
    focal plane are tried); ``prior_ratio`` and ``regularisation``: the whitening's ``a0`` and
    ``lambda`` (0.1: the pooled ratios of six rendered photographs within 0.04 of the camera's,
    with and without noise; 1e-3 amplifies the renderer's departures, 1 loses the noise's
    whitening)."""
    left = np.asarray(left, np.float64)
    right = np.asarray(right, np.float64)
    if left.ndim == 2:
        left, right = left[..., None], right[..., None]
    if left.shape != right.shape:
        raise ParameterError(f"left and right views differ in size: {left.shape} and "
                             f"{right.shape}")
    radii = np.asarray(radii, np.float64)
    ratios = np.asarray(ratios, np.float64)
    margin = int(np.ceil(radii.max() * 1.5)) + 2
    height, width, channels = left.shape
    rows, cols = (height - 2 * margin) // patch, (width - 2 * margin) // patch
    if rows <= 0 or cols <= 0:
        raise ParameterError(f"views of {width}x{height} are too small for {patch}-px blocks "
                             f"and blur up to {radii.max():g} px")
    pad = ((margin, margin), (margin, margin), (0, 0))
    lp, rp = np.pad(left, pad, mode="reflect"), np.pad(right, pad, mode="reflect")
    shape = lp.shape[:2]
    workers = max(1, torch.get_num_threads())
    d = scipy.fft.rfft2(lp - rp, axes=(0, 1), workers=workers)
    c = scipy.fft.rfft2((lp + rp) / 2, axes=(0, 1), workers=workers)
    twice = np.full(shape[1] // 2 + 1, 2.0)  # Parseval: the half plane's mirrored columns
    twice[0] = 1.0
    if shape[1] % 2 == 0:
        twice[-1] = 1.0
    count = shape[0] * shape[1]
    inner = (slice(2 * margin, 2 * margin + rows * patch),
             slice(2 * margin, 2 * margin + cols * patch))

    def sums(x: np.ndarray) -> np.ndarray:
        return np.moveaxis(block_sums(x, patch, np.float64), -1, 0)  # (C, rows, cols)

    energy = np.empty((channels, len(radii), 2, len(ratios), rows, cols))
    a = ratios[:, None, None, None]
    for i, radius in enumerate(radii):
        hc, hd = (h.numpy() for h in view_spectra(radius, params, shape))
        whiten = 1.0 / np.sqrt(2 * np.abs(hc) ** 2 + 2 * prior_ratio**2 * np.abs(hd) ** 2
                               + regularisation)
        gc, gd = hc * whiten, hd * whiten
        p, q = (scipy.fft.irfft2(x * g[..., None], s=shape, axes=(0, 1), workers=workers)
                [inner] for x, g in ((d, gc), (c, gd)))
        pp, pq, qq = sums(p * p), sums(p * q), sums(q * q)
        noise_c = float((twice * 2 * np.abs(gc) ** 2).sum()) / count
        noise_d = float((twice * 2 * np.abs(gd) ** 2).sum()) / count
        noise = noise_c + a * a * noise_d  # (A, 1, 1, 1): the noise's energy per unit variance
        for side, sign in enumerate((1.0, -1.0)):
            energy[:, i, side] = np.moveaxis(
                (pp - 4 * sign * a * pq + 4 * a * a * qq) / noise, 0, 1)
    reference = sums((left - right)[margin: margin + rows * patch,
                                    margin: margin + cols * patch] ** 2) / 2
    ys, xs = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    centres = np.stack([margin + (xs + 0.5) * patch, margin + (ys + 0.5) * patch], axis=-1)
    return ViewEnergies(energy, reference, radii, ratios, centres)


@dataclass
class PooledFit:
    """The camera's constants pooled over pairs: ``ratio`` per channel; per pair ``radius``
    ``(rows, cols)`` px, ``side`` (+1: the ratio ``+a``, -1: ``-a``), ``share`` (the energy left,
    as a share of the views' difference) and ``informative`` (bool)."""

    ratio: np.ndarray
    radius: list[np.ndarray]
    side: list[np.ndarray]
    share: list[np.ndarray]
    informative: list[np.ndarray]
    total: float


def _shares(pairs: Sequence[ViewEnergies], min_radius: float,
            picks: Sequence[int] | None = None):
    """Per pair the energies as shares of the views' difference and the informative blocks:
    the best candidate (at the ratio indices ``picks``, one per channel, if given) leaves at
    most :data:`MAX_SHARE`, stands out of the median one by :data:`MIN_CONTRAST`, and its
    radius is at least ``min_radius`` px (below it the views tell only the product of ratio
    and radius)."""
    if not pairs:
        raise ParameterError("no pairs to pool")
    with np.errstate(invalid="ignore", divide="ignore"):
        shares = [np.nan_to_num(p.energy / p.reference[:, None, None, None], nan=1.0,
                                posinf=1.0) for p in pairs]
    informative = []
    for pair, share in zip(pairs, shares):  # (C, R, 2, A, rows, cols)
        if picks is None:
            summed = share.mean(axis=0).reshape(-1, *share.shape[-2:])
            per_radius = 2 * len(pair.ratios)
        else:
            summed = sum(share[c, :, :, j] for c, j in enumerate(picks)) / len(picks)
            summed = summed.reshape(-1, *share.shape[-2:])
            per_radius = 2
        best = summed.min(axis=0)
        radius = pair.radii[summed.argmin(axis=0) // per_radius]
        informative.append((best <= MAX_SHARE) & (radius >= min_radius)
                           & (np.median(summed, axis=0) >= (1 + MIN_CONTRAST) * best))
    return shares, informative


def _fit(pairs: Sequence[ViewEnergies], shares: list[np.ndarray],
         informative: list[np.ndarray], picks: Sequence[int]) -> PooledFit:
    """Each block's radius and side at the ratio indices ``picks`` (one per channel): the
    candidate of least mean share over the channels."""
    total, radius, side, least_share = 0.0, [], [], []
    for pair, share, useful in zip(pairs, shares, informative):
        per_block = sum(share[c, :, :, j] for c, j in enumerate(picks)) / len(picks)
        flat = per_block.reshape(-1, *per_block.shape[-2:])  # (R * 2, rows, cols)
        index = flat.argmin(axis=0)
        least = np.take_along_axis(flat, index[None], 0)[0]
        total += float(least[useful].sum())
        radius.append(pair.radii[index // 2])
        side.append(np.where(index % 2 == 0, 1, -1))
        least_share.append(least)
    return PooledFit(pairs[0].ratios[list(picks)], radius, side, least_share, informative,
                     total)


def pool_constants(pairs: Sequence[ViewEnergies], *, min_radius: float = 1.5,
                   sweeps: int = 3) -> PooledFit:
    """One ratio per channel for all ``pairs`` and each block's radius and side (shared by its
    channels): coordinate descent on the summed shares (energy over the block's reference) of
    the informative blocks (:func:`blocks_at_ratios`), from the ratio nearest 0.8 in every
    channel."""
    shares, informative = _shares(pairs, min_radius)
    ratios = pairs[0].ratios
    picks = [int(np.abs(ratios - 0.8).argmin())] * pairs[0].energy.shape[0]
    for _ in range(sweeps):
        before = list(picks)
        for c in range(len(picks)):
            scores = [_fit(pairs, shares, informative,
                           [j if k == c else p for k, p in enumerate(picks)]).total
                      for j in range(len(ratios))]
            picks[c] = int(np.argmin(scores))
        if picks == before:
            break
    return _fit(pairs, shares, informative, picks)


def blocks_at_ratios(pairs: Sequence[ViewEnergies], ratios: Sequence[float], *,
                     min_radius: float = 1.5) -> PooledFit:
    """Each block's radius and side at known per-channel ``ratios`` (a camera file's, measured
    with targets): the views fix the product of ratio and radius, so a known ratio gives the
    camera's own blur. Informative blocks as in :func:`pool_constants`, judged at ``ratios``."""
    if not pairs:
        raise ParameterError("no pairs to fit")
    if len(ratios) != pairs[0].energy.shape[0]:
        raise ParameterError(f"give one ratio per channel ({pairs[0].energy.shape[0]}), got "
                             f"{len(ratios)}")
    picks = [int(np.abs(pairs[0].ratios - a).argmin()) for a in ratios]
    shares, informative = _shares(pairs, min_radius, picks)
    return _fit(pairs, shares, informative, picks)


@dataclass
class TargetFreeCalibration:
    """A camera measured from its views alone: the camera, per PSF candidate its mean share over
    the blocks informative for every candidate, the pooled fit of the winner (in the light space
    that won), the pairs' names, their blocks' centres, the share of blocks linear light
    explains better, and the channels whose ratio ran to an end of :data:`RATIO_GRID` (the
    views did not measure them: see :func:`calibrate_camera_from_views`)."""

    camera: DPCamera
    scores: list[tuple[PSFParams, float]]
    fit: PooledFit
    names: list[str]
    centres: list[np.ndarray]
    linear_share: float
    unmeasured: tuple[str, ...] = ()


def _pool_per_candidate(
    pairs: Sequence[tuple[str, np.ndarray, np.ndarray]], params: PSFParams, radii: np.ndarray,
    patch: int, bar,
) -> tuple[list[ViewEnergies], PooledFit]:
    energies = []
    for _, left, right in pairs:
        energies.append(view_energies(left, right, params, radii, RATIO_GRID, patch=patch))
        bar.update(1)
    return energies, pool_constants(energies)


#: The disparity ratios searched (the range :func:`check_disparity_ratio` allows, above 0.2).
RATIO_GRID = np.round(np.arange(0.2, 1.5001, 0.025), 4)


def calibrate_camera_from_views(
    pairs: Iterable[tuple[str, np.ndarray, np.ndarray]],
    *,
    name: str = "camera",
    psf_candidates: Sequence[PSFParams] = (DEFAULT_PSF,),
    patch: int = 48,
    max_radius: float = 12.0,
    radius_step: float | None = None,
    light: str = "auto",
    progress: bool = False,
) -> TargetFreeCalibration:
    """Measure a camera's DP model from ``(name, left, right)`` pairs alone (float ``(H, W, C)``
    or ``(H, W)`` in [0, 1], stored values): see the module docstring. ``light``: "linear"
    (fit the views decoded from sRGB), "encoded" (the stored values) or "auto" (both; linear
    when it leaves the smaller share in most blocks informative in both). Grey views (one
    channel; :func:`grey_as_one_channel` for those stored as RGB) give one ratio, written for
    all three channels; pairs of other widths have their blur sizes scaled to the first pair's.

    Raises:
        ParameterError: no pairs, views of different sizes or channel counts (named), or fewer
            than :data:`~dualpixel.calibration.camera.MIN_BLOCKS` informative blocks over all
            pairs (each pair's count named).
    """
    from dualpixel.data.statistics import noise_level
    from dualpixel.progress import progress_bar

    check_range("patch", patch, 8)
    radius_step = max_radius / 48 if radius_step is None else radius_step
    check_range("radius_step", radius_step, 0.0, low_inclusive=False)
    check_range("max_radius", max_radius, 2 * radius_step)
    if light not in ("auto", "linear", "encoded"):
        raise ParameterError(f"light must be auto, linear or encoded, got {light!r}")
    if not psf_candidates:
        raise ParameterError("give at least one PSF candidate")
    pairs = [(str(n), _channels_last(left), _channels_last(right)) for n, left, right in pairs]
    if not pairs:
        raise ParameterError("no pairs to calibrate from")
    for pair_name, left, right in pairs:
        if left.shape != right.shape:
            raise ParameterError(f"{pair_name}: left and right views differ in size or channels "
                                 f"({left.shape} and {right.shape})")
        if left.shape[-1] != pairs[0][1].shape[-1]:
            raise ParameterError(f"{pair_name}: {left.shape[-1]} channels where "
                                 f"{pairs[0][0]} has {pairs[0][1].shape[-1]}: calibrate one "
                                 "camera's pairs at a time")
    radii = np.arange(radius_step, max_radius + radius_step / 2, radius_step)
    spaces = ["encoded", "linear"] if light == "auto" else [light]
    decoded = {"encoded": pairs}
    if "linear" in spaces:
        decoded["linear"] = [(n, srgb_to_linear_array(lv), srgb_to_linear_array(rv))
                             for n, lv, rv in pairs]
    first = "linear" if light == "auto" else light
    bar = progress_bar(total=len(pairs) * (len(psf_candidates) + len(spaces) - 1),
                       desc="calibrating camera from views", enabled=progress)
    fits = [_pool_per_candidate(decoded[first], params, radii, patch, bar)
            for params in psf_candidates]
    common = [np.logical_and.reduce([f.informative[i] for _, f in fits])
              for i in range(len(pairs))]
    scores = []
    for params, (_, fit) in zip(psf_candidates, fits):
        shares = np.concatenate([s[m] for s, m in zip(fit.share, common)])
        scores.append((params, float(shares.mean()) if shares.size else float("inf")))
    winner = int(np.argmin([s for _, s in scores]))
    energies, fit = fits[winner]
    linear_share = 1.0 if first == "linear" else 0.0
    if light == "auto":
        encoded_energies, encoded = _pool_per_candidate(decoded["encoded"], scores[winner][0],
                                                        radii, patch, bar)
        both = [a & b for a, b in zip(fit.informative, encoded.informative)]
        better = sum(int((lin[m] < enc[m]).sum())
                     for lin, enc, m in zip(fit.share, encoded.share, both))
        total = sum(int(m.sum()) for m in both)
        linear_share = better / total if total else 0.0
        if linear_share <= 0.5:
            energies, fit = encoded_energies, encoded
    bar.close()
    counts = [int(m.sum()) for m in fit.informative]
    if sum(counts) < MIN_BLOCKS:
        listed = ", ".join(f"{n} {c}" for (n, _, _), c in zip(pairs, counts))
        raise ParameterError(f"too few informative blocks: {sum(counts)} (need {MIN_BLOCKS}; "
                             f"per pair: {listed}); give more pairs with textured, blurred "
                             "regions, or a smaller patch")
    for (pair_name, _, _), count in zip(pairs, counts):
        if count == 0:
            warnings.warn(f"{pair_name}: no informative block (too flat or in focus); it adds "
                          "nothing", stacklevel=2)
    _warn_odd_pairs([n for n, _, _ in pairs], energies, fit)
    names = ("R", "G", "B") if len(fit.ratio) == 3 else ("grey",)
    unmeasured = tuple(c for c, a in zip(names, fit.ratio)
                       if a <= RATIO_GRID[0] + 1e-9 or a >= RATIO_GRID[-1] - 1e-9)
    if unmeasured:
        warnings.warn(f"the disparity ratio of {', '.join(unmeasured)} ran to the end of the "
                      f"search ({RATIO_GRID[0]:g}-{RATIO_GRID[-1]:g}): these views do not tell "
                      "the disparity from the blur (a PSF shape unlike the candidates, or too "
                      "little strong blur), so the camera's ratios and blur sizes are "
                      "unreliable; calibrate with targets or PSF patterns", stacklevel=2)
    ratio = [float(v) for v in fit.ratio]
    if len(ratio) == 1:
        ratio = ratio * 3
    width = int(pairs[0][1].shape[1])  # blur sizes at the first pair's width, as CoC scales
    radius = np.concatenate([r[m] * width / pair[1].shape[1]
                             for r, m, pair in zip(fit.radius, fit.informative, pairs)])
    camera = DPCamera(
        name=name, width=width,
        disparity_ratio=tuple(ratio),  # type: ignore[arg-type]
        psf=scores[winner][0],
        noise_std=float(np.median([noise_level(left) for _, left, _ in pairs])),
        coc_percentiles={f"p{p}": round(float(np.percentile(radius, p)), 3)
                         for p in (10, 25, 50, 75, 90)},
        blocks=int(sum(counts)),
        light="linear" if linear_share > 0.5 else "encoded",
    )
    return TargetFreeCalibration(camera, scores, fit, [n for n, _, _ in pairs],
                                 [e.centres for e in energies], linear_share, unmeasured)


#: A pair's own ratio that departs from the others' median by more than this (or three times
#: their spread, if larger) suggests another camera; pairs with fewer informative blocks than
#: :data:`PAIR_BLOCKS`, or whose own fit runs to an end of the ratio grid (the ratio traded
#: against the radius: too few strongly blurred blocks), are not judged.
ODD_RATIO = 0.15
PAIR_BLOCKS = 20


def _warn_odd_pairs(names: list[str], energies: list[ViewEnergies], fit: PooledFit) -> None:
    """Warn, naming them, about pairs whose own ratio (green, or the one channel) disagrees
    with the others' beyond their spread: a folder mixing cameras or settings."""
    channel = 1 if energies[0].energy.shape[0] == 3 else 0
    judged = [i for i, m in enumerate(fit.informative) if m.sum() >= PAIR_BLOCKS]
    if len(judged) < 3:
        return
    own = np.array([pool_constants([ViewEnergies(  # the pair alone, one channel
        energies[i].energy[channel: channel + 1], energies[i].reference[channel: channel + 1],
        energies[i].radii, energies[i].ratios, energies[i].centres)]).ratio[0]
        for i in judged])
    middle = float(np.median(own))
    spread = 1.4826 * float(np.median(np.abs(own - middle)))
    ends = (energies[0].ratios.min(), energies[0].ratios.max())
    odd = [f"{names[i]} ({a:.2f})" for i, a in zip(judged, own)
           if abs(a - middle) > max(ODD_RATIO, 3 * spread) and a not in ends]
    if odd:
        warnings.warn(f"{len(odd)} pair(s) disagree with the others' disparity ratio "
                      f"({middle:.2f} +- {spread:.2f}): {', '.join(odd)}; a folder should hold "
                      "one camera's pairs", stacklevel=3)


def _channels_last(view: np.ndarray) -> np.ndarray:
    view = np.asarray(view, np.float32)
    return view[..., None] if view.ndim == 2 else view


def grey_as_one_channel(left: np.ndarray, right: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Views ``(H, W, 3)`` stored as RGB with equal channels (a phone's green-only DP data, as
    :func:`~dualpixel.io.images.read_rgb` gives them) as one channel; others unchanged."""
    if left.shape[-1] == 3 and all((v == v[..., :1]).all() for v in (left, right)):
        return left[..., :1], right[..., :1]
    return left, right
