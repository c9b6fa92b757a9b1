"""The networks this package trains: RDPD (the paper), DPDNet (its baseline) and their variants.

=============  =====  ======  =========  ==========================================
name           views  radial  recurrent  paper
=============  =====  ======  =========  ==========================================
rdpd           2      yes     yes        RDPD / RDPD+ / sRDPD+ (Sec. 4, Fig. 6)
rspd           1      yes     yes        RSPD+ (supplement, single DP view)
dpdnet         2      no      no         DPDNet (Abuolaim & Brown, ECCV 2020)
dpdnet-single  1      no      no         DPDNet-Single
=============  =====  ======  =========  ==========================================

``width`` multiplies every layer width (1.0 = the published models) so a light model can be trained
on a CPU. Inputs are assembled by :meth:`ModelSpec.make_input`: left RGB, right RGB (dual-view
models) and the radial distance channel (models with ``radial``).
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from dualpixel.errors import ParameterError
from dualpixel.models.unet import DeblurNet, NetworkShape

__all__ = ["MODELS", "ModelSpec", "build_model", "count_parameters", "model_spec"]


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
    )
}


def model_spec(name: str) -> ModelSpec:
    """The spec of a named model, with a clear error for an unknown name."""
    try:
        return MODELS[name]
    except KeyError:
        raise ParameterError(f"unknown model {name!r}; choose from {', '.join(MODELS)}") from None


def _scaled(width: int, multiplier: float) -> int:
    return max(1, round(width * multiplier))


def build_model(
    name: str,
    *,
    width: float = 1.0,
    peepholes: bool = True,
    lstm_dropout: float = 0.4,
    residual: bool = False,
    refiner: tuple[int, ...] = (),
) -> DeblurNet:
    """Build a named network; ``width`` scales every layer (0 < width <= 4); ``residual`` adds
    the blurred input to the output and ``refiner`` (channel widths, not scaled by ``width``)
    appends a correcting second stage (clamped-output models only; neither is in the paper)."""
    spec = model_spec(name)
    if not 0.0 < width <= 4.0:
        raise ParameterError(f"width must be in (0, 4], got {width}")
    shape = NetworkShape(
        in_channels=spec.in_channels,
        encoder=tuple(_scaled(c, width) for c in spec.encoder),
        bottleneck=_scaled(spec.bottleneck, width),
        recurrent=spec.recurrent,
        output=spec.output,
        encoder_dropout=spec.encoder_dropout,
        lstm_dropout=lstm_dropout,
        peepholes=peepholes,
        residual=residual,
        refiner=tuple(refiner),
    )
    for option, value in (("residual", residual), ("a refiner", refiner)):
        if value and spec.output != "clamp":
            raise ParameterError(f"model {name!r} has a sigmoid output; {option} needs rdpd or "
                                 "rspd")
    if any(w < 1 for w in refiner):
        raise ParameterError(f"refiner widths must be >= 1, got {list(refiner)}")
    model = DeblurNet(shape)
    model.spec = spec
    model.width = width
    return model


def count_parameters(model: torch.nn.Module) -> int:
    """Number of trainable parameters."""
    return sum(p.numel() for p in model.parameters() if p.requires_grad)
