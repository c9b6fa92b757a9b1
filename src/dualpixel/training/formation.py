"""The formation loss: a deblurred output, blurred again by the camera's DP PSFs, must give
back each view (no sharp target needed).

For a block at CoC radius ``r`` on side ``s`` of the focal plane, with the camera's left and
right kernels ``K_l(r)``, ``K_r(r)`` (paper Eq. 2-4, each summing to 1; swapped for ``s = -1``)
and per-channel disparity ratio ``a`` (:class:`~dualpixel.optics.camera.DPCamera`), the views of
a sharp image ``S`` are ``L = S * (H_c + a H_d)`` and ``R = S * (H_c - a H_d)`` with
``H_c = (K_l + K_r) / 2`` and ``H_d = (K_l - K_r) / 2``, in the camera's light space. The loss
compares the output so blurred with both views over the blurred, informative blocks of
:class:`~dualpixel.data.views.BlurMap`, and the output with the combined view over its
in-focus blocks (there is nothing to deblur: the output must keep them).
"""

from __future__ import annotations

import torch
from torch import nn

from dualpixel.errors import ParameterError
from dualpixel.optics.camera import DPCamera
from dualpixel.optics.psf import view_spectra
from dualpixel.optics.tone import srgb_to_linear

__all__ = ["FormationLoss"]


class FormationLoss(nn.Module):
    """``forward(output, item) -> (loss, parts)`` for a batch of views crops.

    ``output``, ``item["left"]``, ``item["right"]``: ``(B, 3, h, w)`` stored values in [0, 1];
    ``item["radius"]``, ``item["side"]``, ``item["blurred"]``, ``item["in_focus"]``:
    ``(B, h, w)`` per-pixel maps (:meth:`BlurMap.pixel_maps`, cropped). Pixels within ``border``
    of the crop's edge are left out (the blur there needs what the crop does not hold).
    ``reduction``: "mean" (squared errors averaged) or "log" (each crop's mean in dB, then
    averaged: :class:`~dualpixel.training.losses.DeblurLoss`'s scale-free form).
    ``parts``: ``formation`` and ``in_focus``, the two terms before their weights."""

    def __init__(self, camera: DPCamera, *, formation_weight: float = 1.0,
                 in_focus_weight: float = 1.0, reduction: str = "mean",
                 border: int = 16) -> None:
        super().__init__()
        if reduction not in ("mean", "log"):
            raise ParameterError(f"reduction must be mean or log, got {reduction!r}")
        self.camera, self.reduction, self.border = camera, reduction, border
        self.formation_weight, self.in_focus_weight = formation_weight, in_focus_weight
        self.register_buffer("ratio", torch.tensor(camera.disparity_ratio,
                                                   dtype=torch.float32).view(1, 3, 1, 1))
        self._spectra: dict[tuple[float, int, int], tuple[torch.Tensor, torch.Tensor]] = {}

    def _kernel_spectra(self, radius: float, shape: tuple[int, int], device: torch.device):
        """:func:`~dualpixel.optics.psf.view_spectra` at ``radius`` (side +1), kept per size."""
        key = (radius, *shape)
        if key not in self._spectra:
            self._spectra[key] = tuple(h.to(torch.complex64)
                                       for h in view_spectra(radius, self.camera.psf, shape))
        hc, hd = self._spectra[key]
        return hc.to(device), hd.to(device)

    def _light(self, values: torch.Tensor) -> torch.Tensor:
        return srgb_to_linear(values) if self.camera.light == "linear" else values

    def _reduce(self, squared: torch.Tensor, weights: torch.Tensor) -> torch.Tensor | None:
        """Per crop: the weighted mean of ``squared`` ``(B, C, h, w)``; crops without weight
        are left out; None when none has any."""
        count = weights.sum(dim=(-2, -1)) * squared.shape[1]  # (B,)
        has = count > 0
        if not bool(has.any()):
            return None
        per_crop = (squared * weights[:, None]).sum(dim=(1, 2, 3))[has] / count[has]
        if self.reduction == "log":
            return (10.0 * torch.log10(per_crop + 1e-10)).mean()
        return per_crop.mean()

    def forward(self, output: torch.Tensor, item: dict[str, torch.Tensor]):
        left, right = item["left"], item["right"]
        height, width = output.shape[-2:]
        inside = torch.zeros(height, width, dtype=output.dtype, device=output.device)
        b = self.border
        inside[b:height - b, b:width - b] = 1.0
        blurred_mask = item["blurred"] * inside
        sharp = self._light(output.float())
        views = torch.stack([self._light(left.float()), self._light(right.float())])
        spectrum = torch.fft.rfft2(sharp)
        squared = torch.zeros_like(sharp)
        weights = torch.zeros_like(blurred_mask)
        chosen = blurred_mask > 0
        for value in torch.unique(item["radius"][chosen]).tolist():
            hc, hd = self._kernel_spectra(float(value), (height, width), output.device)
            common = torch.fft.irfft2(spectrum * hc, s=(height, width))
            differing = torch.fft.irfft2(spectrum * hd, s=(height, width)) * self.ratio
            for side in (1.0, -1.0):
                mask = blurred_mask * (item["radius"] == value) * (item["side"] == side)
                if not bool(mask.any()):
                    continue
                error = ((common + side * differing - views[0]) ** 2
                         + (common - side * differing - views[1]) ** 2) / 2
                squared = squared + error * mask[:, None]
                weights = weights + mask
        parts: dict[str, torch.Tensor] = {}
        total = output.new_zeros(())
        formation = self._reduce(squared, (weights > 0).to(squared.dtype))
        if formation is not None:
            parts["formation"] = formation.detach()
            total = total + self.formation_weight * formation
        focus_mask = item["in_focus"] * inside
        kept = self._reduce((output.float() - (left.float() + right.float()) / 2) ** 2,
                            focus_mask)
        if kept is not None:
            parts["in_focus"] = kept.detach()
            total = total + self.in_focus_weight * kept
        return total, parts
