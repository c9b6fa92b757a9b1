"""Non-blind DP PSF estimation from a capture of the disk grid (supplement S1).

For each disk, with ``S`` the known sharp disk and ``B`` the captured (defocused) patch, solve

    argmin_E  sum_i || D_i (S * E - B) ||^2 + lambda || E ||_1   subject to E >= 0,

``D_i`` in {D_x, D_y, D_xx, D_yy, D_xy}, by FISTA with projection onto ``E >= 0`` (batched over all
disks and views with torch; convolutions by FFT on a patch large enough that nothing wraps). Disk
centres come from the combined image (left + right), whose PSF is symmetric, so the same sharp disk
registers both views and their relative displacement (the DP disparity) is kept in the estimates.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from scipy import ndimage
from scipy.fft import next_fast_len
from skimage.filters import threshold_otsu

from dualpixel.calibration.patterns import render_disk
from dualpixel.errors import ParameterError, check_range

__all__ = ["PSFEstimate", "derivative_filters", "estimate_psfs", "locate_disks"]


def derivative_filters() -> list[np.ndarray]:
    """D_x, D_y, D_xx, D_yy, D_xy as small 2-D kernels."""
    dx = np.array([[0.0, -1.0, 1.0]])
    dxx = np.array([[1.0, -2.0, 1.0]])
    dxy = np.array([[1.0, -1.0], [-1.0, 1.0]])
    return [dx, dx.T.copy(), dxx, dxx.T.copy(), dxy]


@dataclass
class PSFEstimate:
    """PSFs per disk: ``psfs[view]`` is ``(N, K, K)`` (each sums to 1), ``centres`` ``(N, 2)``
    (x, y) in the capture, ``gains[view]`` ``(N,)`` the estimated PSF mass before normalising."""

    psfs: dict[str, np.ndarray]
    centres: np.ndarray
    gains: dict[str, np.ndarray]

    def save(self, path) -> None:
        """Write ``centres`` and one ``(N, K, K)`` array per view as ``.npz``, atomically."""
        from dualpixel.io.atomic import atomic_path

        with atomic_path(path) as tmp, open(tmp, "wb") as handle:
            np.savez(handle, centres=self.centres, **self.psfs)


def read_captures(left, right, combined=None) -> dict[str, np.ndarray]:
    """Grey captures ``{"left", "right", "combined"}`` (combined = left + right when not given)
    from image files, refusing files of different sizes by name."""
    from pathlib import Path

    from dualpixel.errors import InputFileError
    from dualpixel.io.images import read_rgb

    paths = {"left": Path(left), "right": Path(right)}
    if combined is not None:
        paths["combined"] = Path(combined)
    views = {name: read_rgb(path).mean(axis=2) for name, path in paths.items()}
    for name, path in paths.items():
        if views[name].shape != views["left"].shape:
            found, expected = views[name].shape, views["left"].shape
            raise InputFileError(path, f"size {found[1]}x{found[0]} differs from "
                                       f"{paths['left'].name} ({expected[1]}x{expected[0]})")
    if combined is None:
        views["combined"] = views["left"] + views["right"]
    return views


def locate_disks(image: np.ndarray, *, min_area: int = 4) -> np.ndarray:
    """Intensity-weighted centroids ``(N, 2)`` (x, y) of bright blobs, row-major order."""
    threshold = threshold_otsu(image)
    labels, count = ndimage.label(image > threshold)
    if count == 0:
        raise ParameterError("no disks found in the capture")
    index = np.arange(1, count + 1)
    areas = ndimage.sum_labels(np.ones_like(image), labels, index)
    weights = np.clip(image - np.median(image), 0, None)
    mass = ndimage.sum_labels(weights, labels, index)
    found = (areas >= min_area) & (mass > 0)  # blobs no brighter than the median have no centre
    centroids = np.array(ndimage.center_of_mass(weights, labels, index[found]),
                         np.float64).reshape(-1, 2)[:, ::-1]
    if len(centroids) == 0:
        raise ParameterError(f"no disks of at least {min_area} px found in the capture")
    row_heights = np.unique(np.round(centroids[:, 1]))
    spacing = np.median(np.diff(row_heights)) if row_heights.size > 1 else 1.0
    rows = np.round((centroids[:, 1] - centroids[:, 1].min()) / max(spacing, 1.0))
    return centroids[np.lexsort((centroids[:, 0], rows))]


def _energy_spectrum(kernels: list[np.ndarray], size: int) -> torch.Tensor:
    """sum_i |FFT(D_i)|^2 on a ``size`` x ``size`` grid: the Fourier form of sum_i D_i^T D_i."""
    total = torch.zeros(size, size, dtype=torch.float64)
    for kernel in kernels:
        padded = torch.zeros(size, size, dtype=torch.float64)
        padded[: kernel.shape[0], : kernel.shape[1]] = torch.from_numpy(kernel)
        total += torch.fft.fft2(padded).abs() ** 2
    return total


def _fista(sharp: torch.Tensor, blurred: torch.Tensor, support: torch.Tensor, lam: float,
           smoothness: float, iterations: int) -> torch.Tensor:
    """Projected FISTA on the derivative-domain objective, all problems at once (P x P FFTs)."""
    size = sharp.shape[-1]
    q_hat = _energy_spectrum(derivative_filters(), size)
    s_hat, b_hat = torch.fft.fft2(sharp), torch.fft.fft2(blurred)
    weight = q_hat * s_hat.abs() ** 2  # Q |S|^2
    if smoothness > 0:  # + smoothness * ||grad E||^2, scaled to the data term
        scale = weight.flatten(-2).max(-1).values[..., None, None]
        weight = weight + smoothness * scale * _energy_spectrum(derivative_filters()[:2], size)
    target = q_hat * s_hat.conj() * b_hat  # Q S* B
    lipschitz = 2 * weight.flatten(-2).max(-1).values[..., None, None]
    estimate = torch.zeros_like(sharp)
    momentum, t = estimate.clone(), 1.0
    for _ in range(iterations):
        grad = 2 * torch.fft.ifft2(weight * torch.fft.fft2(momentum) - target).real + lam
        updated = ((momentum - grad / lipschitz).clamp_min(0)) * support
        t_next = (1 + (1 + 4 * t * t) ** 0.5) / 2
        momentum = updated + ((t - 1) / t_next) * (updated - estimate)
        estimate, t = updated, t_next
    return estimate


def estimate_psfs(
    views: dict[str, np.ndarray],
    *,
    radius: float,
    kernel_size: int,
    centres: np.ndarray | None = None,
    lam: float = 0.1,
    smoothness: float = 0.0,
    iterations: int = 300,
) -> PSFEstimate:
    """Estimate one PSF per disk and view from captures of the disk grid.

    Args:
        views: ``{"left": (H, W), "right": ..., "combined": ...}`` grey captures (any subset).
        radius: the sharp disk's radius in capture pixels (the pattern's radius fraction times the
            spacing measured in the capture).
        kernel_size: odd size of the estimated PSFs.
        centres: disk centres (x, y); found in the ``combined`` view (else the sum of the views)
            when omitted.
        lam: weight of the l1 term.
        smoothness: weight of an extra ``||grad E||^2`` term relative to the data term's largest
            eigenvalue (ours, not in S1; 0 gives the supplement's objective). Noisy captures need
            it: see the README's calibration section for measured correlations.
        iterations: FISTA iterations.
    """
    if kernel_size % 2 == 0 or kernel_size < 3:
        raise ParameterError(f"kernel_size must be odd and >= 3, got {kernel_size}")
    check_range("radius", radius, 0.5, kernel_size)  # a disk of < 1 px diameter has no edge
    check_range("lam", lam, 0.0)
    check_range("smoothness", smoothness, 0.0)
    check_range("iterations", iterations, 1)
    if not views:
        raise ParameterError("no views to estimate PSFs from")
    names = list(views)
    shapes = {n: np.shape(views[n]) for n in names}
    if len(set(shapes.values())) > 1:
        raise ParameterError(f"the views differ in size: {shapes}")
    stack = np.stack([np.asarray(views[n], np.float64) for n in names])
    if centres is None:  # from the combined image: its PSF is symmetric, so centres are unbiased
        combined = views["combined"] if "combined" in views else stack.sum(0)
        centres = locate_disks(np.asarray(combined, np.float64))
    half_k = kernel_size // 2
    size = next_fast_len(int(2 * (half_k + np.ceil(radius)) + 8))
    half = size // 2
    height, width = stack.shape[1:]
    keep = [(x - half >= 0) and (y - half >= 0) and (x + half < width) and (y + half < height)
            for x, y in np.round(centres)]
    centres = np.asarray(centres)[np.array(keep, bool)]
    if len(centres) == 0:
        raise ParameterError("no disk lies far enough from the image border for the patch size")
    sharp, blurred = [], []
    for x, y in centres:
        ix, iy = round(x), round(y)
        sharp.append(render_disk(size, (half + x - ix, half + y - iy), radius))
        patch = stack[:, iy - half : iy + half, ix - half : ix + half]
        border = np.concatenate([patch[:, :2].reshape(len(names), -1),
                                 patch[:, -2:].reshape(len(names), -1)], axis=1)
        blurred.append(patch - np.median(border, axis=1)[:, None, None])  # display black level
    sharp_t = torch.from_numpy(np.stack(sharp).astype(np.float64))[None]  # (1, N, P, P)
    sharp_t = torch.fft.ifftshift(sharp_t, dim=(-2, -1))  # disk centre at index 0
    blurred_t = torch.fft.ifftshift(torch.from_numpy(np.stack(blurred, axis=1)), dim=(-2, -1))
    offsets = torch.arange(size)
    near = torch.minimum(offsets, size - offsets) <= half_k
    support = (near[:, None] & near[None, :]).double()
    estimate = _fista(sharp_t.expand_as(blurred_t), blurred_t, support, lam, smoothness,
                      iterations)
    kernels = torch.fft.fftshift(estimate, dim=(-2, -1))[..., half - half_k : half + half_k + 1,
                                                          half - half_k : half + half_k + 1]
    kernels = kernels.numpy()
    gains = kernels.sum(axis=(-2, -1))
    normalised = kernels / np.maximum(gains[..., None, None], 1e-12)
    return PSFEstimate(
        {n: normalised[i].astype(np.float32) for i, n in enumerate(names)}, centres,
        {n: gains[i] for i, n in enumerate(names)},
    )
