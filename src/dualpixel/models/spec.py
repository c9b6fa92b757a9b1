"""What each named network takes: views, radial channel, recurrence and layer widths
(:data:`MODELS`; built by :func:`dualpixel.models.registry.build_model`)."""

from __future__ import annotations

from dataclasses import dataclass

import torch

from dualpixel.errors import ParameterError

__all__ = ["ARCHITECTURES", "MODELS", "ModelSpec", "model_spec"]


@dataclass(frozen=True)
class ModelSpec:
    """What a named network takes and how wide it is at ``width=1``."""

    name: str
    views: int
    radial: bool
    recurrent: bool
    encoder: tuple[int, ...]
    bottleneck: int
    output: str
    encoder_dropout: float
    description: str
    #: What each level is made of: "conv" (two 3x3 convolutions with ReLU, max-pooling down,
    #: the paper's) or "naf" (NAF blocks, :mod:`dualpixel.models.naf`).
    block: str = "conv"
    #: NAF blocks per encoder level, in the bottleneck, per decoder level (coarsest first):
    #: ``2 * len(encoder) + 1`` counts ("naf" only).
    block_counts: tuple[int, ...] = ()

    @property
    def in_channels(self) -> int:
        return 3 * self.views + int(self.radial)

    def make_input(
        self, left: torch.Tensor, right: torch.Tensor | None, radial: torch.Tensor | None
    ) -> torch.Tensor:
        """Stack the channels this model reads along dim -3 (works for frames and sequences)."""
        parts = [left]
        if self.views == 2:
            if right is None:
                raise ParameterError(f"model {self.name!r} needs the right view")
            parts.append(right)
        if self.radial:
            if radial is None:
                raise ParameterError(f"model {self.name!r} needs the radial distance channel")
            parts.append(radial.expand(*left.shape[:-3], 1, *left.shape[-2:]))
        return torch.cat(parts, dim=-3)


MODELS: dict[str, ModelSpec] = {
    spec.name: spec
    for spec in (
        ModelSpec("rdpd", 2, True, True, (32, 64, 128, 256), 512, "clamp", 0.0,
                  "recurrent DP deblurring (left, right, radial distance)"),
        ModelSpec("rspd", 1, True, True, (32, 64, 128, 256), 512, "clamp", 0.0,
                  "recurrent single-view deblurring (left, radial distance)"),
        ModelSpec("dpdnet", 2, False, False, (64, 128, 256, 512), 1024, "sigmoid", 0.4,
                  "DP deblurring U-Net of Abuolaim & Brown 2020 (left, right)"),
        ModelSpec("dpdnet-single", 1, False, False, (64, 128, 256, 512), 1024, "sigmoid", 0.4,
                  "DPDNet on a single view (left)"),
        ModelSpec("dpnaf", 2, True, False, (32, 64, 128, 256), 512, "clamp", 0.0,
                  "NAF-block DP U-Net, ours (left, right, radial distance)", block="naf",
                  block_counts=(1, 1, 2, 4, 6, 1, 1, 1, 1)),
    )
}


def model_spec(name: str) -> ModelSpec:
    """The spec of a named model, with a clear error for an unknown name."""
    try:
        return MODELS[name]
    except KeyError:
        raise ParameterError(f"unknown model {name!r}; choose from {', '.join(MODELS)}") from None


#: Shipped architectures by name: a network of :data:`MODELS` and its build options (what
#: :func:`~dualpixel.models.registry.build_model` takes). Each shipped weight file names one.
ARCHITECTURES: dict[str, dict[str, object]] = {
    "rdpd-light": {"model": "rdpd", "width": 0.5, "residual": True, "refiner": (32, 64, 128)},
    "rdpd-light-base": {"model": "rdpd", "width": 0.5, "residual": True},
    "rdpd-wide": {"model": "rdpd", "width": 1.0, "residual": True, "refiner": (32, 64, 128)},
    "rdpd-wide-base": {"model": "rdpd", "width": 1.0, "residual": True},
    "dpnaf-light": {"model": "dpnaf", "width": 0.5, "residual": True},
}
