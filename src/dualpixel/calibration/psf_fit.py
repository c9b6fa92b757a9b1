"""Fitting the parametric DP PSF model to measured PSFs (supplement S2, Fig. 5 and S2).

For each measured PSF ``E`` (left and right views fitted independently; a right view is mirrored
and fitted as a left one, since our model's ``H_r`` mirrors ``H_l``), a brute-force search over

    n in {1..15}, alpha in {0.1..1.0}, beta in {0.1..1.0}, kappa in {0.14, 0.21, ..., 0.42}

and a grid of CoC radii minimises ``sum_i || D_i (E - H(n, alpha, beta, kappa, r)) ||^2`` with
``D_i`` in {D_x, D_y, D_xx, D_yy, D_xy}. Centring: both views of a pair are shifted (sub-pixel,
Fourier shift) so that the *combined* PSF's centroid is at the kernel centre, which keeps their
disparity; the best candidates are then refined over sub-pixel centre offsets. Punnappurath et
al.'s model (one parameter, the radius) is fitted the same way; because the derivative-domain
objective favours its widest radius, its best-case correlation over the radius grid (selected by
correlation itself) is reported too. Similarity is the 2-D normalised cross-correlation at zero
shift (zero-mean, as Pearson's r over pixels).

Vectorised: the expensive supersampled terms ``[C]`` and ``[B o C]`` are computed once per
``(n, alpha, r)``; the Gaussian blur once per kappa; every beta is a linear mix of the two; and the
objective ``<H, QH> - 2 <H, QE>`` (``Q = sum_i D_i^T D_i``) scores all candidates against all
measurements with one matrix product.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
import torch
import torch.nn.functional as F
from scipy import ndimage
from scipy.signal import correlate2d

from dualpixel.calibration.psf_estimation import derivative_filters
from dualpixel.errors import ParameterError
from dualpixel.optics.psf import (
    butterworth_disk_terms,
    gaussian_blur_kernels,
    mix_butterworth_terms,
    punnappurath_left_psf,
    split_views,
)
from dualpixel.progress import progress_bar

__all__ = [
    "BANK_SEARCH_GRID",
    "PAPER_SEARCH_GRID",
    "PSFFit",
    "SearchGrid",
    "fit_psf_models",
    "psf_correlation",
]


@dataclass(frozen=True)
class SearchGrid:
    """The discrete values searched (supplement S2)."""

    n: tuple[float, ...] = tuple(float(v) for v in range(1, 16))
    alpha: tuple[float, ...] = tuple(round(0.1 * k, 2) for k in range(1, 11))
    beta: tuple[float, ...] = tuple(round(0.1 * k, 2) for k in range(1, 11))
    kappa: tuple[float, ...] = (0.14, 0.21, 0.28, 0.35, 0.42)
    radius_step: float = 0.5
    centre_offsets: tuple[float, ...] = (-0.5, -0.25, 0.0, 0.25, 0.5)
    refine_top: int = 5


PAPER_SEARCH_GRID = SearchGrid()
#: The values the supplement kept for the 48-PSF bank (a quick search).
BANK_SEARCH_GRID = SearchGrid(n=(3.0, 6.0, 9.0), alpha=(0.4, 0.6, 0.8, 1.0),
                              beta=(0.1, 0.2, 0.3, 0.4), kappa=(0.14,))


@dataclass
class PSFFit:
    """Best parameters for one measured PSF (one view) and both models' correlations."""

    index: int
    view: str
    n: float
    alpha: float
    beta: float
    kappa: float
    radius: float
    centre_dx: float
    centre_dy: float
    correlation: float
    punnappurath_radius: float
    punnappurath_correlation: float
    punnappurath_best_correlation: float  # best-case: max correlation over its radius grid

    def as_dict(self) -> dict:
        return asdict(self)


def psf_correlation(a: np.ndarray, b: np.ndarray) -> float:
    """Zero-mean normalised cross-correlation of two kernels at zero shift, in [-1, 1]."""
    a = np.asarray(a, np.float64) - np.mean(a)
    b = np.asarray(b, np.float64) - np.mean(b)
    return float((a * b).sum() / np.sqrt((a * a).sum() * (b * b).sum()))


def _q_kernel() -> torch.Tensor:
    """Q = sum_i D_i^T D_i as one convolution kernel (5 x 5)."""
    q = np.zeros((5, 5))
    for d in derivative_filters():
        auto = correlate2d(d, d, mode="full")  # D^T D as a kernel: the autocorrelation
        h, w = auto.shape
        q[(5 - h) // 2 : (5 - h) // 2 + h, (5 - w) // 2 : (5 - w) // 2 + w] += auto
    return torch.from_numpy(q)


def _apply_q(kernels: torch.Tensor, q: torch.Tensor) -> torch.Tensor:
    return F.conv2d(kernels[:, None], q[None, None].to(kernels.dtype), padding=2)[:, 0]


def _centroid(kernel: np.ndarray) -> tuple[float, float]:
    size = kernel.shape[-1]
    axis = np.arange(size) - size // 2
    weight = kernel / kernel.sum()
    return float((weight.sum(0) * axis).sum()), float((weight.sum(1) * axis).sum())


def _shift(kernel: np.ndarray, dx: float, dy: float) -> np.ndarray:
    """Sub-pixel shift by (dx, dy) pixels (Fourier shift), kept non-negative, sum 1."""
    moved = np.fft.ifft2(ndimage.fourier_shift(np.fft.fft2(kernel), (dy, dx))).real
    moved = np.clip(moved, 0, None)
    return moved / moved.sum()


class _Scorer:
    """Keeps, per measurement, the ``keep`` best candidates by the derivative-domain objective."""

    def __init__(self, measured: torch.Tensor, keep: int) -> None:
        self.q = _q_kernel()
        self.q_measured = _apply_q(measured, self.q).flatten(1)  # (M, S*S)
        self.keep = keep
        self.best_scores = torch.full((len(measured), 0), float("inf"), dtype=torch.float64)
        self.best_labels: list[list[tuple]] = [[] for _ in range(len(measured))]

    def add(self, candidates: torch.Tensor, labels: list[tuple]) -> None:
        quad = (candidates * _apply_q(candidates, self.q)).flatten(1).sum(1)  # <H, QH>
        scores = quad[None, :] - 2 * self.q_measured @ candidates.flatten(1).T  # (M, N)
        merged = torch.cat([self.best_scores, scores], dim=1)
        top = torch.topk(merged, min(self.keep, merged.shape[1]), largest=False, dim=1)
        old = self.best_labels
        self.best_labels = [
            [old[m][j] if j < len(old[m]) else labels[j - len(old[m])]
             for j in top.indices[m].tolist()]
            for m in range(len(old))
        ]
        self.best_scores = top.values


def _our_left_kernels(terms: tuple[torch.Tensor, torch.Tensor], radii: torch.Tensor,
                      betas: torch.Tensor, kappa: float) -> torch.Tensor:
    """Left kernels (sum 1) for every beta x radius, beta-major, from ``[C]`` and ``[B o C]``:
    the blur is linear, so it is applied to the two terms once and every beta mixes them."""
    smooth = [gaussian_blur_kernels(t, kappa * radii.abs()) for t in terms]
    every_radius = radii.repeat(len(betas))
    mixed = mix_butterworth_terms(smooth[0][None], smooth[1][None], every_radius,
                                  betas[:, None, None, None], 0.0)
    left = split_views(mixed.flatten(0, 1), every_radius).left
    return left / left.sum(dim=(-2, -1), keepdim=True)


def _ours_batch(labels: list[tuple], size: int) -> torch.Tensor:
    """Our left kernels for explicit (n, alpha, beta, kappa, r) labels."""
    kernels = []
    for n, a, b, k, r in labels:
        radius = torch.tensor([r], dtype=torch.float64)
        terms = butterworth_disk_terms(radius, n, a, size)
        kernels.append(_our_left_kernels(terms, radius, torch.tensor([b]), k)[0])
    return torch.stack(kernels)


def _punnappurath(radii: torch.Tensor, size: int) -> torch.Tensor:
    left = punnappurath_left_psf(radii, size)
    return left / left.sum(dim=(-2, -1), keepdim=True)


def fit_psf_models(
    left: np.ndarray, right: np.ndarray, *, grid: SearchGrid = PAPER_SEARCH_GRID,
    progress: bool = True,
) -> list[PSFFit]:
    """Fit our model and Punnappurath et al.'s to measured DP PSF pairs ``(N, S, S)`` each.

    Returns one :class:`PSFFit` per pair and view (``2N``), in order (0 left, 0 right, 1 ...).
    """
    left, right = np.asarray(left, np.float64), np.asarray(right, np.float64)
    if left.shape != right.shape or left.ndim != 3 or left.shape[1] != left.shape[2]:
        raise ParameterError(f"expected left and right of shape (N, S, S), got {left.shape} and "
                             f"{right.shape}")
    if left.shape[1] % 2 == 0:
        raise ParameterError(f"PSF size must be odd, got {left.shape[1]}")
    if (left < -1e-6).any() or (right < -1e-6).any():
        raise ParameterError("measured PSFs must be non-negative")
    size = left.shape[1]
    measured, views = [], []
    for k in range(len(left)):
        dx, dy = _centroid(left[k] + right[k])
        # r > 0 puts the left view's mass on the left (our convention); the sign is the pair's.
        sign = 1.0 if _centroid(left[k])[0] <= _centroid(right[k])[0] else -1.0
        for view, kernel in (("left", left[k]), ("right", right[k])):
            centred = _shift(kernel, -dx, -dy)
            # Fit everything as a left view with r > 0, mirroring where that is not so.
            flip = (view == "left") != (sign > 0)
            measured.append(centred[:, ::-1].copy() if flip else centred)
            views.append((k, view, sign))
    target = torch.from_numpy(np.stack(measured))

    sigma = np.sqrt([((np.arange(size) - size // 2) ** 2 * m.sum(0)).sum() for m in measured])
    step = grid.radius_step
    low = max(step, np.floor(0.5 * np.sqrt(2) * sigma.min() / step) * step)
    high = 1.6 * np.sqrt(2) * sigma.max()
    radii = torch.arange(low, high + 1e-9, grid.radius_step, dtype=torch.float64)

    ours = _Scorer(target, grid.refine_top)
    betas = torch.tensor(grid.beta, dtype=torch.float64)
    combos = [(n, a) for n in grid.n for a in grid.alpha]
    for n, a in progress_bar(combos, desc="fitting our PSF model", unit="(n,alpha)",
                             enabled=progress):
        terms = butterworth_disk_terms(radii, n, a, size)
        for kappa in grid.kappa:
            ours.add(_our_left_kernels(terms, radii, betas, kappa),
                     [(n, a, float(b), kappa, float(r)) for b in grid.beta for r in radii])
    fine = torch.arange(low, high + 1e-9, 0.1, dtype=torch.float64)
    theirs = _Scorer(target, 3)
    punn_kernels = _punnappurath(fine, size)
    theirs.add(punn_kernels, [(float(r),) for r in fine])

    results = []
    for m, (index, view, sign) in enumerate(views):
        best = _refine(measured[m], ours.best_labels[m], grid,
                       lambda labels: _ours_batch(labels, size))
        best_p = _refine(measured[m], theirs.best_labels[m], grid,
                         lambda labels: _punnappurath(
                             torch.tensor([label[0] for label in labels], dtype=torch.float64),
                             size))
        (n, a, b, k, r), (odx, ody), corr = best
        (rp,), _, corr_p = best_p
        best_case = max(psf_correlation(kernel, measured[m]) for kernel in punn_kernels.numpy())
        results.append(PSFFit(index, view, n, a, b, k, sign * r, odx, ody, corr, sign * rp,
                              corr_p, best_case))
    return results


def _refine(measured: np.ndarray, labels: list[tuple], grid: SearchGrid, make) -> tuple:
    """Best (label, centre offset, correlation) over sub-pixel offsets of the measurement."""
    q = _q_kernel()
    models = make(labels)
    quad = (models * _apply_q(models, q)).flatten(1).sum(1)
    offsets = [(ox, oy) for oy in grid.centre_offsets for ox in grid.centre_offsets]
    shifted = torch.from_numpy(np.stack([_shift(measured, ox, oy) for ox, oy in offsets]))
    scores = quad[:, None] - 2 * models.flatten(1) @ _apply_q(shifted, q).flatten(1).T
    j, k = np.unravel_index(int(torch.argmin(scores)), tuple(scores.shape))
    ox, oy = offsets[k]
    return labels[j], (-ox, -oy), psf_correlation(models[j].numpy(), shifted[k].numpy())
