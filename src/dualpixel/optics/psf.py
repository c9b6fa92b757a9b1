"""Dual-pixel point spread functions (paper Sec. 2.2, Eq. 2-4) and the baselines of the ablation.

Every model is a pure torch function of a batch of signed CoC radii ``r`` of shape ``(K,)`` that
returns left and right kernels of shape ``(K, S, S)`` on the radii's device and dtype. Pixel
``(S // 2, S // 2)`` is the kernel centre; x grows to the right (columns), y downwards (rows).

Conventions shared by all models:

* Each view sums to 1/2 and the combined PSF ``H = H_l + H_r`` sums to 1.
* ``H_r`` is ``H_l`` mirrored about the vertical axis (``torch.flip(H_l, (-1,))``).
* For ``r > 0`` (behind the focal plane) ``H_l`` falls off towards the right, so the left view is
  displaced to the left; for ``r < 0`` the views swap. ``r = 0`` is a delta in both views.
* The disk ``C`` (and our Butterworth term) is integrated over each pixel, so kernels change
  continuously with ``r``: a sub-pixel radius gives a delta that spreads smoothly as ``r`` grows.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal, NamedTuple

import numpy as np
import torch
import torch.nn.functional as F

from dualpixel.errors import ParameterError, check_range
from dualpixel.memory import require_memory
from dualpixel.names import PSF_MODELS

__all__ = [
    "PSF_MODELS",
    "DPKernels",
    "PSFModel",
    "PSFParams",
    "butterworth_combined_psf",
    "butterworth_disk_terms",
    "check_psf_model",
    "disk_psf",
    "dp_psf",
    "dp_psf_each",
    "gaussian_blur_kernels",
    "gaussian_psf",
    "kernel_size",
    "mix_butterworth_terms",
    "punnappurath_left_psf",
    "split_views",
    "view_spectra",
]

PSFModel = Literal["ours", "punnappurath", "disk", "gaussian"]

#: Standard deviation of the Gaussian baseline PSF, as a fraction of |r|.
GAUSSIAN_SIGMA_PER_RADIUS = 0.5


@dataclass(frozen=True)
class PSFParams:
    """Parameters of our DP PSF model (Eq. 2-4).

    Args:
        n: Butterworth order, in [1, 30].
        alpha: cutoff factor, D_o = alpha * 2|r|; alpha = 1 puts the 3 dB point at the disk's
            diameter. In (0, 2].
        beta: lower bound of the rescaled Butterworth term (depletion at the centre), in (0, 1].
        kappa: Gaussian smoothing, std = kappa * |r|, in [0, 1).
    """

    n: float = 3.0
    alpha: float = 0.4
    beta: float = 0.2
    kappa: float = 0.14

    def __post_init__(self) -> None:
        check_range("n", self.n, 1.0, 30.0)
        check_range("alpha", self.alpha, 0.0, 2.0, low_inclusive=False)
        check_range("beta", self.beta, 0.0, 1.0, low_inclusive=False)
        check_range("kappa", self.kappa, 0.0, 1.0, high_inclusive=False)

    def as_dict(self) -> dict[str, float]:
        return {"n": self.n, "alpha": self.alpha, "beta": self.beta, "kappa": self.kappa}


class DPKernels(NamedTuple):
    """Left and right DP kernels, ``(S, S)`` or ``(K, S, S)`` torch tensors."""

    left: torch.Tensor
    right: torch.Tensor

    @property
    def combined(self) -> torch.Tensor:
        """H = H_l + H_r (sums to 1)."""
        return self.left + self.right

    def numpy(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(left, right, combined) as NumPy arrays of the kernels' dtype."""
        return tuple(t.detach().cpu().numpy() for t in (self.left, self.right, self.combined))


def kernel_size(max_radius: float, model: PSFModel = "ours", kappa: float = 0.14) -> int:
    """Smallest odd kernel size that holds the model's support for |r| <= ``max_radius``."""
    spread = GAUSSIAN_SIGMA_PER_RADIUS if model == "gaussian" else kappa
    half = math.ceil(abs(max_radius) * (1.0 + 3.0 * spread) + 1.0)
    return 2 * half + 1


def _as_radii(radius: float | Sequence[float] | np.ndarray | torch.Tensor, dtype, device):
    if isinstance(radius, torch.Tensor):
        radii = radius.to(dtype=dtype if dtype is not None else radius.dtype, device=device)
    else:
        radii = torch.as_tensor(
            np.asarray(radius, dtype=np.float64), dtype=dtype or torch.float32, device=device
        )
    if not radii.dtype.is_floating_point:
        raise ParameterError(f"radius must be floating point, got dtype {radii.dtype}")
    if not bool(torch.isfinite(radii).all()):
        raise ParameterError("radius must be finite")
    return radii


def _grid(size: int, like: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Pixel offsets (x, y) from the kernel centre, each (S, S)."""
    axis = torch.arange(size, dtype=like.dtype, device=like.device) - size // 2
    y, x = torch.meshgrid(axis, axis, indexing="ij")
    return x, y


#: Sub-samples per pixel side used to integrate the disk and Butterworth terms over each pixel.
SUPERSAMPLING = 4


def _subpixel_radius(size: int, like: torch.Tensor) -> torch.Tensor:
    """Distance from the kernel centre of each sub-pixel sample, ``(S * ss, S * ss)``."""
    ss = SUPERSAMPLING
    axis = (torch.arange(size * ss, dtype=like.dtype, device=like.device) + 0.5) / ss
    axis = axis - size / 2.0
    y, x = torch.meshgrid(axis, axis, indexing="ij")
    return torch.sqrt(x**2 + y**2)


def _pixel_integral(samples: torch.Tensor) -> torch.Tensor:
    """Average ``(K, S * ss, S * ss)`` sub-pixel samples over each pixel: ``(K, S, S)``."""
    return F.avg_pool2d(samples[:, None], SUPERSAMPLING)[:, 0]


def _disk_samples(radius: torch.Tensor, rho: torch.Tensor) -> torch.Tensor:
    """Disk of radius |r| at sub-pixel samples, its edge anti-aliased over one sub-pixel.

    Radii below half a sub-pixel are raised to it, so r = 0 keeps its mass: a delta.
    """
    smallest = 0.5 / SUPERSAMPLING
    edge = (radius.abs().clamp_min(smallest)[:, None, None] - rho) * SUPERSAMPLING + 0.5
    return edge.clamp(0.0, 1.0)


def disk_psf(radius: torch.Tensor, size: int) -> torch.Tensor:
    """Disk C of radius |r| (Eq. 3) integrated over each pixel, unnormalised, ``(K,) -> (K, S, S)``.

    A radius below half a pixel leaves all weight in the centre pixel (a delta).
    """
    return _pixel_integral(_disk_samples(radius, _subpixel_radius(size, radius)))


def check_psf_model(model: str) -> str:
    """The one check of a PSF-model name (``ours``, ``punnappurath``, ``disk``, ``gaussian``)."""
    if model not in PSF_MODELS:
        raise ParameterError(f"psf_model must be one of {', '.join(PSF_MODELS)}, got {model!r}")
    return model


def _normalise(kernels: torch.Tensor, total: float = 1.0) -> torch.Tensor:
    return kernels * (total / kernels.sum(dim=(-2, -1), keepdim=True))


def gaussian_blur_kernels(kernels: torch.Tensor, sigma: torch.Tensor) -> torch.Tensor:
    """Blur each kernel ``(..., K, S, S)`` with its own isotropic Gaussian of std ``sigma[k]``.

    Zero-padded "same" filtering written as ``T_k @ H_k @ T_k^T`` with ``T_k`` the banded
    (Toeplitz) matrix of kernel k's taps: batched matrix products, much faster than a grouped
    convolution with S-tap filters.
    """
    size = kernels.shape[-1]
    t = torch.arange(size, dtype=kernels.dtype, device=kernels.device) - size // 2
    # A vanishing sigma gives a delta (exp(-inf) off-centre), so the blur fades out continuously.
    variance = 2.0 * sigma.clamp_min(1e-6)[:, None] ** 2
    taps = torch.exp(-(t[None, :] ** 2) / variance)
    taps = taps / taps.sum(dim=1, keepdim=True)
    offset = t[None, :] - t[:, None]  # a - i, in [-(S-1), S-1]
    inside = offset.abs() <= size // 2
    index = (offset + size // 2).clamp(0, size - 1).long()
    toeplitz = taps[:, index] * inside  # (K, S, S): T[k, i, a] = taps[k, a - i + S // 2]
    return toeplitz @ kernels @ toeplitz.transpose(-1, -2)


def butterworth_disk_terms(
    radius: torch.Tensor, n: float | torch.Tensor, alpha: float | torch.Tensor, size: int
) -> tuple[torch.Tensor, torch.Tensor]:
    r"""The two pixel-integrated terms of Eq. 2-3 whose mix is our combined PSF: the disk ``[C]``
    and the Butterworth-weighted disk ``[B o C]``, each ``(K, S, S)``.

    .. math:: B = \left(1 + (D_o / \rho)^{2n}\right)^{-1}, \quad D_o = 2 \alpha |r|

    Computed as a logistic function of log-distances, which cannot overflow for large n, and
    integrated over each pixel (``SUPERSAMPLING``^2 samples) so small radii are not aliased.
    The calibration fit reuses them for every beta and kappa.
    """
    rho = _subpixel_radius(size, radius)
    cutoff = _per_kernel(2.0 * alpha, radius) * radius.abs()[:, None, None]
    tiny = torch.finfo(radius.dtype).tiny
    butterworth = torch.sigmoid(_per_kernel(2.0 * n, radius)
                                * (torch.log(rho + tiny) - torch.log(cutoff + tiny)))
    disk = _disk_samples(radius, rho)
    return _pixel_integral(disk), _pixel_integral(butterworth * disk)


def mix_butterworth_terms(
    disk: torch.Tensor, butter_disk: torch.Tensor, radius: torch.Tensor, beta: float | torch.Tensor,
    kappa: float | torch.Tensor,
) -> torch.Tensor:
    r"""``H = G_{\kappa |r|} * ((\beta + (1 - \beta) B) o C)`` from the terms, sums to 1.
    ``beta`` and ``kappa``: one value, or one per kernel ``(K,)`` (float64 gives the same
    values as each alone)."""
    combined = (_per_kernel(beta, radius) * disk
                + _per_kernel(1.0 - beta, radius) * butter_disk)
    if not isinstance(kappa, torch.Tensor):
        if kappa > 0:
            combined = gaussian_blur_kernels(combined, kappa * radius.abs())
        return _normalise(combined)
    smoothed = kappa > 0  # the others as a float kappa of 0 leaves them: unsmoothed
    if bool(smoothed.any()):
        sigma = _per_kernel(kappa[smoothed], radius)[:, 0, 0] * radius[smoothed].abs()
        combined = combined.clone()
        combined[smoothed] = gaussian_blur_kernels(combined[smoothed], sigma)
    return _normalise(combined)


def _per_kernel(value: float | torch.Tensor, like: torch.Tensor) -> float | torch.Tensor:
    """A shape parameter as it multiplies ``(K, S, S)`` kernels: a ``(K,)`` tensor (computed in
    float64, like Python's floats) as ``(K, 1, 1)`` in ``like``'s dtype; a float, or a tensor
    already shaped to broadcast (the calibration's betas), as it is."""
    if not isinstance(value, torch.Tensor) or value.ndim != 1:
        return value
    return value.to(dtype=like.dtype, device=like.device)[:, None, None]


def butterworth_combined_psf(radius: torch.Tensor, params: PSFParams, size: int) -> torch.Tensor:
    r"""Combined DP PSF of our model before the left/right split (Eq. 2-3), sums to 1.

    B (a high-pass, 0 at the centre, 1 far out) is rescaled affinely from [0, 1] to [beta, 1]:
    the pixel integral of ``(beta + (1 - beta) B) C`` is ``beta [C] + (1 - beta) [B C]``.
    """
    disk, butter_disk = butterworth_disk_terms(radius, params.n, params.alpha, size)
    return mix_butterworth_terms(disk, butter_disk, radius, params.beta, params.kappa)


def _require_kernel_memory(radii: torch.Tensor, size: int) -> None:
    """Refuse kernels of ``size`` for ``radii`` that would not fit in memory: three kernels per
    radius, plus the temporaries of a chunk (measured 260 bytes per kernel pixel in float32 at
    r = 500 and 1000 px, about 64 kernel-sized arrays per radius)."""
    itemsize = torch.finfo(radii.dtype).bits // 8
    require_memory(itemsize * size * size * (3 * radii.numel() + 64 * min(radii.numel(), _CHUNK)),
                   f"DP PSFs of size {size}x{size} for {radii.numel()} radii")


def dp_psf_each(radius: torch.Tensor, params: Sequence[PSFParams], size: int) -> DPKernels:
    """Our model's left and right PSFs (Eq. 2-4) for ``(K,)`` radii, each with its own shape
    ``params`` (K of them), all of one odd ``size``: ``(K, S, S)`` each, the same values as
    :func:`dp_psf` gives each radius with its parameters. For renderers whose frames each
    have their own PSF shape: one batch for all their layers."""
    if len(params) != radius.numel():
        raise ParameterError(f"dp_psf_each needs one PSFParams per radius ({radius.numel()}), "
                             f"got {len(params)}")
    _require_kernel_memory(radius, size)
    columns = torch.tensor([[p.n, p.alpha, p.beta, p.kappa] for p in params],
                           dtype=torch.float64)
    views = []
    for start in range(0, radius.numel(), _CHUNK):
        part = slice(start, start + _CHUNK)
        n, alpha, beta, kappa = columns[part].unbind(dim=1)
        disk, butter_disk = butterworth_disk_terms(radius[part], n, alpha, size)
        combined = mix_butterworth_terms(disk, butter_disk, radius[part], beta, kappa)
        views.append(split_views(combined, radius[part]))
    return DPKernels(*(torch.cat(side) for side in zip(*views)))


def gaussian_psf(radius: torch.Tensor, size: int) -> torch.Tensor:
    """Isotropic Gaussian, std ``GAUSSIAN_SIGMA_PER_RADIUS * |r|`` (a delta at r = 0), sums to 1."""
    delta = torch.zeros(radius.shape[0], size, size, dtype=radius.dtype, device=radius.device)
    delta[:, size // 2, size // 2] = 1.0
    return _normalise(gaussian_blur_kernels(delta, GAUSSIAN_SIGMA_PER_RADIUS * radius.abs()))


def split_views(combined: torch.Tensor, radius: torch.Tensor) -> DPKernels:
    """Split a left-right symmetric combined PSF into DP views with a linear ramp (Eq. 4).

    ``H_l = H o M`` with ``M(x) = clip(1/2 - sign(r) x / (2 e), 0, 1)``: a constant decay across
    the kernel, falling towards the right for r > 0. The ramp spans the kernel's own horizontal
    extent, ``e = 2 sigma_x + 1/2`` with ``sigma_x`` the RMS horizontal radius of ``H`` (``e`` is
    ``|r| + 1/2`` for a uniform disk), so the views' centroids ``-/+ sigma_x^2 / e`` separate
    monotonically as the kernel widens. ``H_l`` is scaled to sum to exactly 1/2 and ``H_r`` is its
    mirror; because ``M(x) + M(-x) = 1``, ``H_l + H_r`` equals ``H``.
    """
    x, _ = _grid(combined.shape[-1], radius)
    weight = combined / combined.sum(dim=(-2, -1), keepdim=True)
    sigma_x = torch.sqrt((weight * x**2).sum(dim=(-2, -1)))
    extent = 2.0 * (2.0 * sigma_x + 0.5)[:, None, None]
    ramp = (0.5 - torch.sign(radius)[:, None, None] * x / extent).clamp(0.0, 1.0)
    left = _normalise(combined * ramp, 0.5)
    return DPKernels(left, torch.flip(left, dims=(-1,)))


def punnappurath_left_psf(radius: torch.Tensor, size: int) -> torch.Tensor:
    """Left PSF of Punnappurath et al., ICCP 2020 (the paper's Fig. 5, middle), sums to 1/2.

    The disk C weighted at each pixel by the sum of C shifted horizontally by t = 0 .. 2|r| + 1
    pixels (its overlap with translated copies). The shift is chosen so that the weight grows
    towards the same side as our model's left PSF (the left for r > 0). Because 2|r| + 1 spans the
    whole disk, the sum over shifts is a cumulative sum of C along each row.
    """
    disk = disk_psf(radius, size)
    towards_left = torch.flip(torch.cumsum(torch.flip(disk, (-1,)), dim=-1), (-1,))
    towards_right = torch.cumsum(disk, dim=-1)
    weight = torch.where((radius >= 0)[:, None, None], towards_left, towards_right)
    return _normalise(disk * weight, 0.5)


_CHUNK = 32  # radii per batch of supersampled grids: bounds memory for large kernels


def _model_kernels(radii: torch.Tensor, params: PSFParams, model: str, size: int) -> DPKernels:
    if model == "punnappurath":
        left = punnappurath_left_psf(radii, size)
        return DPKernels(left, torch.flip(left, dims=(-1,)))
    if model == "ours":
        combined = butterworth_combined_psf(radii, params, size)
    elif model == "disk":
        combined = _normalise(disk_psf(radii, size))
    else:
        combined = gaussian_psf(radii, size)
    return split_views(combined, radii)


def dp_psf(
    radius: float | Sequence[float] | np.ndarray | torch.Tensor,
    params: PSFParams | None = None,
    *,
    model: PSFModel = "ours",
    size: int | None = None,
    dtype: torch.dtype | None = None,
    device: torch.device | str | None = None,
) -> DPKernels:
    """Left and right DP PSFs for signed CoC radii (paper Eq. 2-4, or a baseline model).

    Args:
        radius: a float (returns ``(S, S)`` kernels) or a 1-D batch ``(K,)`` (returns
            ``(K, S, S)``) of signed CoC radii in pixels; NumPy, list or torch.
        params: shape parameters of our model (ignored by the baselines); paper defaults if None.
        model: "ours" (Butterworth, Eq. 2-4), "punnappurath" (ICCP 2020), "disk" or "gaussian";
            the disk and Gaussian are split into views with the same ramp as ours.
        size: odd kernel size; by default just large enough for the largest |r|.
        dtype: torch float dtype (default: the radius tensor's, else float32).
        device: torch device (default: the radius tensor's, else CPU).

    Returns:
        :class:`DPKernels` (left, right; ``.combined`` and ``.numpy()`` available).

    >>> k = dp_psf(5.0)
    >>> round(float(k.left.sum()), 6), round(float(k.combined.sum()), 6)
    (0.5, 1.0)
    """
    check_psf_model(model)
    params = params or PSFParams()
    if device is None and isinstance(radius, torch.Tensor):
        device = radius.device
    radii = _as_radii(radius, dtype, device)
    scalar = radii.ndim == 0
    radii = radii.reshape(-1)
    needed = kernel_size(float(radii.detach().abs().max()) if radii.numel() else 0.0, model,
                         params.kappa)
    if size is None:
        size = needed
    elif size < 1 or size % 2 == 0:
        raise ParameterError(f"size must be a positive odd integer, got {size!r}")

    _require_kernel_memory(radii, size)
    chunks = [_model_kernels(chunk, params, model, size) for chunk in radii.split(_CHUNK)]
    kernels = DPKernels(*(torch.cat(views) for views in zip(*chunks)))
    if scalar:
        kernels = DPKernels(kernels.left[0], kernels.right[0])
    return kernels


def view_spectra(radius: float, params: PSFParams | None,
                 shape: tuple[int, int]) -> tuple[torch.Tensor, torch.Tensor]:
    """``(H_c, H_d)`` ``(H, W // 2 + 1)`` complex128: the rfft2 at ``shape`` of the half sum and
    half difference of :func:`dp_psf`'s left and right kernels at CoC radius ``radius`` (each
    scaled to sum to 1), centred on the origin. A pair of views of a sharp image ``S`` with
    disparity ratio ``a`` is then ``S * (H_c +- a H_d)`` (circular convolution)."""
    kernels = dp_psf(float(radius), params)
    size = kernels.left.shape[-1]
    spectra = []
    for kernel in (kernels.left, kernels.right):
        full = torch.zeros(shape, dtype=torch.float64)
        full[:size, :size] = 2.0 * kernel.double()
        spectra.append(torch.fft.rfft2(torch.roll(full, (-(size // 2), -(size // 2)), (0, 1))))
    return (spectra[0] + spectra[1]) / 2, (spectra[0] - spectra[1]) / 2
