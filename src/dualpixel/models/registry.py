"""The networks this package trains: RDPD (the paper), DPDNet (its baseline) and their variants.

=============  =====  ======  =========  ==========================================
name           views  radial  recurrent  paper
=============  =====  ======  =========  ==========================================
rdpd           2      yes     yes        RDPD / RDPD+ / sRDPD+ (Sec. 4, Fig. 6)
rspd           1      yes     yes        RSPD+ (supplement, single DP view)
dpdnet         2      no      no         DPDNet (Abuolaim & Brown, ECCV 2020)
dpdnet-single  1      no      no         DPDNet-Single
dpnaf          2      yes     no         ours: the U-Net with NAF-block levels
=============  =====  ======  =========  ==========================================

``width`` multiplies every layer width (1.0 = the published models) so a light model can be trained
on a CPU. Inputs are assembled by :meth:`ModelSpec.make_input`: left RGB, right RGB (dual-view
models) and the radial distance channel (models with ``radial``).
"""

from __future__ import annotations

import torch

from dualpixel.errors import ParameterError
from dualpixel.models.spec import ARCHITECTURES, MODELS, ModelSpec, model_spec
from dualpixel.models.unet import DeblurNet, NetworkShape

__all__ = ["ARCHITECTURES", "MODELS", "ModelSpec", "build_architecture", "build_model",
           "check_conv_bottleneck", "count_parameters", "model_spec"]


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
    head_relu: bool = True,
    conv_bottleneck: bool = False,
    encoder_dropout: float | None = None,
) -> DeblurNet:
    """Build a named network; ``width`` scales every layer (0 < width <= 4); ``residual`` adds
    the blurred input to the output and ``refiner`` (channel widths, not scaled by ``width``)
    appends a correcting second stage (clamped-output models only; neither is in the paper);
    ``head_relu=False`` drops the ReLU of a non-residual head; ``conv_bottleneck=True`` gives a
    recurrent network DPDNet's two 3x3 convolutions in place of its convolution and ConvLSTM
    (a network without state; both ours); ``encoder_dropout`` replaces the network's dropout
    after its last encoder level and its convolution bottleneck (DPDNet 0.4, the others 0)."""
    spec = model_spec(name)
    check_head_relu(name, residual=residual, head_relu=head_relu)
    check_conv_bottleneck(name, conv_bottleneck)
    if not 0.0 < width <= 4.0:
        raise ParameterError(f"width must be in (0, 4], got {width}")
    shape = NetworkShape(
        in_channels=spec.in_channels,
        encoder=tuple(_scaled(c, width) for c in spec.encoder),
        bottleneck=_scaled(spec.bottleneck, width),
        recurrent=spec.recurrent and not conv_bottleneck,
        output=spec.output,
        encoder_dropout=spec.encoder_dropout if encoder_dropout is None else encoder_dropout,
        lstm_dropout=lstm_dropout,
        peepholes=peepholes,
        residual=residual,
        refiner=tuple(refiner),
        block=spec.block,
        block_counts=spec.block_counts,
        head_relu=head_relu,
    )
    for option, value in (("residual", residual), ("a refiner", refiner)):
        if value and spec.output != "clamp":
            raise ParameterError(f"model {name!r} has a sigmoid output; {option} needs rdpd or "
                                 "rspd")
    if any(w < 1 for w in refiner):
        raise ParameterError(f"refiner widths must be >= 1, got {list(refiner)}")
    return DeblurNet(shape, spec=spec, width=width)


def check_head_relu(name: str, *, residual: bool, head_relu: bool) -> None:
    """Refuse ``head_relu=False`` where the head has no ReLU to drop: a residual head, or a
    model without the paper's levels (``dpnaf``)."""
    if not head_relu and (residual or model_spec(name).block != "conv"):
        raise ParameterError("head_relu false is for the non-residual networks of the paper's "
                             "levels (residual false, model rdpd, rspd, dpdnet or "
                             f"dpdnet-single): {'a residual' if residual else repr(name)} head "
                             "has no ReLU to drop")


def check_conv_bottleneck(name: str, conv_bottleneck: bool) -> None:
    """Refuse ``conv_bottleneck=True`` for a network whose bottleneck has no ConvLSTM to
    replace (DPDNet has the two convolutions already; ``dpnaf`` has NAF blocks)."""
    if conv_bottleneck and not model_spec(name).recurrent:
        raise ParameterError(f"conv_bottleneck true is for the recurrent networks (rdpd, rspd): "
                             f"{name!r} has no ConvLSTM to replace")


def build_architecture(name: str, **options) -> DeblurNet:
    """A shipped architecture by name (:data:`~dualpixel.models.spec.ARCHITECTURES`), e.g.
    ``"rdpd-light"``; ``options`` (e.g. ``lstm_dropout``) go to :func:`build_model`."""
    if name not in ARCHITECTURES:
        raise ParameterError(f"unknown architecture {name!r}; choose from "
                             f"{', '.join(ARCHITECTURES)}")
    settings = dict(ARCHITECTURES[name])
    return build_model(str(settings.pop("model")), **{**settings, **options})


def count_parameters(model: torch.nn.Module) -> int:
    """Number of trainable parameters."""
    return sum(p.numel() for p in model.parameters() if p.requires_grad)
