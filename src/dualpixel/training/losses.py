"""Training loss: MSE plus the multi-scale edge loss (paper Sec. 4, Eq. 13-16).

``G^x`` is the derivative along the image width (the direction of DP disparity) and ``G^y`` along
the height, each computed with the extended Sobel kernels of sizes 3, 7 and 11 (OpenCV's
``getDerivKernels``, each divided by its largest magnitude: 2, 100 and 12096). Eq. 15 averages the
MSE between output and target gradients over the scales; Eq. 16 weights the directions
``lambda_x = 0.03`` and ``lambda_y = 0.02``. Every element of the batch and every frame counts
(the authors' Keras code used the 3x3 kernel for the "7x7" scale and only batch element 0).
"""

from __future__ import annotations

import cv2
import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

__all__ = ["LOSS_REDUCTIONS", "DeblurLoss", "EdgeLoss", "sobel_kernels"]

LOSS_REDUCTIONS = ("mean", "log")
#: Keeps the log finite for a perfect patch (1e-8: a PSNR of 80 dB).
LOG_EPS = 1e-8


def sobel_kernels(size: int) -> tuple[np.ndarray, np.ndarray]:
    """Extended Sobel kernels ``(d/dx, d/dy)`` of odd ``size``, normalised to max magnitude 1."""
    if size < 3 or size % 2 == 0 or size > 31:
        raise ValueError(f"Sobel size must be odd in [3, 31], got {size}")
    derivative, smoothing = cv2.getDerivKernels(1, 0, size, normalize=False, ktype=cv2.CV_64F)
    kernel_x = smoothing @ derivative.T  # rows smooth, columns differentiate
    kernel_x /= np.abs(kernel_x).max()
    return kernel_x, kernel_x.T.copy()


class EdgeLoss(nn.Module):
    """Mean over scales of the MSE between Sobel gradients, horizontal and vertical apart (Eq. 15).

    ``forward(output, target)`` takes ``(..., C, H, W)`` and returns ``(loss_x, loss_y)``.
    """

    def __init__(self, sizes: tuple[int, ...] = (3, 7, 11)) -> None:
        super().__init__()
        self.sizes = tuple(sizes)
        for size in self.sizes:
            kx, ky = sobel_kernels(size)
            kernels = torch.from_numpy(np.stack([kx, ky])).float()[:, None]  # (2, 1, s, s)
            self.register_buffer(f"kernels_{size}", kernels, persistent=False)

    def forward(
        self, output: torch.Tensor, target: torch.Tensor, *, per_image: bool = False
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Scalars, or with ``per_image`` one value per image ``(N,)`` (N = all leading dims)."""
        images = output.shape[:-3].numel()
        if not self.sizes:
            zero = output.new_zeros((images,) if per_image else ())
            return zero, zero
        height, width = output.shape[-2:]
        # Both images in one convolution, each colour channel a separate image.
        planes = torch.stack([output, target]).reshape(-1, 1, height, width)
        loss_x = loss_y = output.new_zeros(())
        for size in self.sizes:
            kernels = getattr(self, f"kernels_{size}").to(planes.dtype)
            grads = F.conv2d(planes, kernels).unflatten(0, (2, -1))  # valid: no border artefacts
            squared = (grads[0] - grads[1]).square()  # (N * C, 2, h, w)
            if per_image:
                squared = squared.unflatten(0, (images, -1)).transpose(1, 2).flatten(2)
                loss_x = loss_x + squared[:, 0].mean(dim=1)
                loss_y = loss_y + squared[:, 1].mean(dim=1)
            else:
                loss_x = loss_x + squared[:, 0].mean()
                loss_y = loss_y + squared[:, 1].mean()
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
        reduction: str = "mean",
    ) -> None:
        super().__init__()
        if reduction not in LOSS_REDUCTIONS:
            raise ValueError(f"reduction must be one of {LOSS_REDUCTIONS}, got {reduction!r}")
        self.edge = EdgeLoss(sizes)
        self.lambda_x, self.lambda_y = lambda_x, lambda_y
        self.reduction = reduction

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
            total = self.combine(mse, edge_x, edge_y)
        else:
            mse = (output - target).square().flatten(-3).mean(-1).flatten()  # (N,)
            edge_x, edge_y = self.edge(output, target, per_image=True)
            per_image = self.combine(mse, edge_x, edge_y)
            total = 10.0 * torch.log10(per_image + LOG_EPS).mean()
            mse, edge_x, edge_y = mse.mean(), edge_x.mean(), edge_y.mean()
        return total, {"mse": mse.detach(), "edge_x": edge_x.detach(), "edge_y": edge_y.detach()}
