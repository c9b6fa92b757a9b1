"""Training loss: MSE plus the multi-scale edge loss (paper Sec. 4, Eq. 13-16).

``G^x`` is the derivative along the image width (the direction of DP disparity) and ``G^y`` along
the height, each computed with the extended Sobel kernels of sizes 3, 7 and 11 (OpenCV's
``getDerivKernels``, each divided by its largest magnitude: 2, 100 and 12096). Eq. 15 averages the
MSE between output and target gradients over the scales; Eq. 16 weights the directions
``lambda_x = 0.03`` and ``lambda_y = 0.02``. Every element of the batch and every frame counts
(the authors' Keras code used the 3x3 kernel for the "7x7" scale and only batch element 0).

How it is computed (same values): the kernels are linear, so the gradients of the difference
``output - target`` are filtered instead of both images, and each kernel is the outer product of
a smoothing and a derivative vector, so two 1-D passes of shifted sums replace the 2-D
convolution. On the CPU the backward pass of ``conv2d`` with these one-channel kernels took over
half of a training step; this way a step takes half the time (``benchmarks/bench_training.py``,
case ``conv2d-edge``).
"""

from __future__ import annotations

import cv2
import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

__all__ = ["LOSS_REDUCTIONS", "PIXEL_LOSSES", "DeblurLoss", "EdgeLoss", "sobel_factors",
           "sobel_kernels"]

LOSS_REDUCTIONS = ("mean", "log")
#: The pixel term of Eq. 16: "mse" (the paper) or "charbonnier" (ours, an option:
#: ``sqrt(d^2 + eps^2)``, a smooth L1 whose minimiser is a median where MSE's is a mean).
PIXEL_LOSSES = ("mse", "charbonnier")
#: Charbonnier's ``eps`` on the [0, 1] scale (a quarter of an 8-bit level).
CHARBONNIER_EPS = 1e-3
#: Keeps the log finite for a perfect patch (1e-8: a PSNR of 80 dB).
LOG_EPS = 1e-8


def sobel_factors(size: int) -> tuple[np.ndarray, np.ndarray]:
    """The 1-D factors ``(smoothing, derivative)``, each ``(size,)``, of the normalised extended
    Sobel kernel: ``np.outer(smoothing, derivative)`` is :func:`sobel_kernels`'s ``d/dx``."""
    if size < 3 or size % 2 == 0 or size > 31:
        raise ValueError(f"Sobel size must be odd in [3, 31], got {size}")
    derivative, smoothing = cv2.getDerivKernels(1, 0, size, normalize=False, ktype=cv2.CV_64F)
    derivative, smoothing = derivative[:, 0], smoothing[:, 0]
    # The kernel's largest magnitude is the product of the factors' (both are outer products).
    return smoothing / np.abs(smoothing).max(), derivative / np.abs(derivative).max()


def sobel_kernels(size: int) -> tuple[np.ndarray, np.ndarray]:
    """Extended Sobel kernels ``(d/dx, d/dy)`` of odd ``size``, normalised to max magnitude 1."""
    smoothing, derivative = sobel_factors(size)
    kernel_x = np.outer(smoothing, derivative)  # rows smooth, columns differentiate
    return kernel_x, kernel_x.T.copy()


def _correlate_valid(image: torch.Tensor, taps: tuple[float, ...], dim: int) -> torch.Tensor:
    """1-D cross-correlation along ``dim`` without padding (``len(taps) - 1`` samples shorter),
    as a sum of shifted views: cheaper forward and backward on the CPU than ``conv2d``."""
    length = image.shape[dim] - len(taps) + 1
    out = None
    for shift, tap in enumerate(taps):
        if tap == 0.0:
            continue
        term = image.narrow(dim, shift, length) * tap
        out = term if out is None else out + term
    return out


class EdgeLoss(nn.Module):
    """Mean over scales of the MSE between Sobel gradients, horizontal and vertical apart (Eq. 15).

    ``forward(output, target)`` takes ``(..., C, H, W)`` and returns ``(loss_x, loss_y)``.
    """

    def __init__(self, sizes: tuple[int, ...] = (3, 7, 11)) -> None:
        super().__init__()
        self.sizes = tuple(sizes)
        self.factors = {size: tuple(tuple(float(t) for t in f) for f in sobel_factors(size))
                        for size in self.sizes}

    def forward(
        self, output: torch.Tensor, target: torch.Tensor, *, per_image: bool = False
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Scalars, or with ``per_image`` one value per image ``(N,)`` (N = all leading dims)."""
        images = output.shape[:-3].numel()
        if not self.sizes:
            zero = output.new_zeros((images,) if per_image else ())
            return zero, zero
        # (N, C, H, W); the gradients are linear, so filter the difference once.
        difference = (output - target).reshape(images, *output.shape[-3:])
        dims = (1, 2, 3) if per_image else (0, 1, 2, 3)
        loss_x = loss_y = output.new_zeros(())
        for size in self.sizes:
            smoothing, derivative = self.factors[size]
            # Valid filtering (no border artefacts): (N, C, H - s + 1, W - s + 1) each.
            grad_x = _correlate_valid(_correlate_valid(difference, derivative, -1), smoothing, -2)
            grad_y = _correlate_valid(_correlate_valid(difference, smoothing, -1), derivative, -2)
            loss_x = loss_x + grad_x.square().mean(dim=dims)
            loss_y = loss_y + grad_y.square().mean(dim=dims)
        return loss_x / len(self.sizes), loss_y / len(self.sizes)


class DeblurLoss(nn.Module):
    """``L = MSE + lambda_x L_edge^x + lambda_y L_edge^y`` (Eq. 16); returns the total and parts.

    ``reduction="mean"`` (the paper) averages over the whole batch. ``reduction="log"`` (ours)
    computes Eq. 16 per image and averages ``10 log10(L_i)`` (dB): every patch then weighs the
    same in decibels, as PSNR is averaged over images in evaluation (the PSNR loss of NAFNet /
    HINet when the edge terms are off). With "mean", blurred patches, whose errors are orders of
    magnitude larger, drown the gradient of the in-focus ones, and noise there is never removed.
    The parts (MSE, edge terms) are batch means in both cases.
    """

    def __init__(
        self, sizes: tuple[int, ...] = (3, 7, 11), lambda_x: float = 0.03, lambda_y: float = 0.02,
        reduction: str = "mean", pixel: str = "mse",
    ) -> None:
        super().__init__()
        if reduction not in LOSS_REDUCTIONS:
            raise ValueError(f"reduction must be one of {LOSS_REDUCTIONS}, got {reduction!r}")
        if pixel not in PIXEL_LOSSES:
            raise ValueError(f"pixel must be one of {PIXEL_LOSSES}, got {pixel!r}")
        self.edge = EdgeLoss(sizes)
        self.lambda_x, self.lambda_y = lambda_x, lambda_y
        self.reduction, self.pixel = reduction, pixel

    def combine(
        self, mse: torch.Tensor, edge_x: torch.Tensor, edge_y: torch.Tensor
    ) -> torch.Tensor:
        """Eq. 16 from its terms (batch means, or per image for ``reduction="log"``)."""
        return mse + self.lambda_x * edge_x + self.lambda_y * edge_y

    def forward(
        self, output: torch.Tensor, target: torch.Tensor
    ) -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
        if self.reduction == "mean":
            mse = F.mse_loss(output, target)
            edge_x, edge_y = self.edge(output, target)
            pixel = mse if self.pixel == "mse" else self._charbonnier(output - target).mean()
            total = self.combine(pixel, edge_x, edge_y)
        else:
            difference = output - target
            mse = difference.square().flatten(-3).mean(-1).flatten()  # (N,)
            pixel = (mse if self.pixel == "mse"
                     else self._charbonnier(difference).flatten(-3).mean(-1).flatten())
            edge_x, edge_y = self.edge(output, target, per_image=True)
            per_image = self.combine(pixel, edge_x, edge_y)
            total = 10.0 * torch.log10(per_image + LOG_EPS).mean()
            mse, edge_x, edge_y = mse.mean(), edge_x.mean(), edge_y.mean()
        return total, {"mse": mse.detach(), "edge_x": edge_x.detach(), "edge_y": edge_y.detach()}

    @staticmethod
    def _charbonnier(difference: torch.Tensor) -> torch.Tensor:
        return (difference.square() + CHARBONNIER_EPS**2).sqrt()
