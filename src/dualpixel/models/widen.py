"""Function-preserving widening of a trained network (ours; Net2WiderNet, Chen et al. 2016,
"Net2Net: Accelerating Learning via Knowledge Transfer").

A network ``k`` times as wide as a trained one (every encoder level, the bottleneck and the
ConvLSTM; the same inputs, head and refiner) starts from the trained one's function: each unit
of the trained network becomes ``k`` copies, and every weight reading those copies is split
among them so that they sum to the trained weight. The split is uneven (centred random parts,
``noise`` of the weight's size), so that copies receive different gradients and can learn
different things; with equal parts they would stay equal for ever. The output is the trained
network's up to rounding, so a short training run on a GPU starts from a shipped model's
quality instead of from nothing.
"""

from __future__ import annotations

import torch
from torch import nn

from dualpixel.errors import ParameterError
from dualpixel.models.unet import DeblurNet

__all__ = ["widen_network", "widening_factor"]


def widening_factor(small: DeblurNet, big: DeblurNet) -> int:
    """The integer ``k`` by which ``big`` is ``small`` widened; refuses any other pair."""
    a, b = small.shape, big.shape
    same = ("in_channels", "recurrent", "output", "peepholes", "residual", "head_relu")
    differing = [name for name in same if getattr(a, name) != getattr(b, name)]
    if small.spec.name != big.spec.name or differing or len(a.encoder) != len(b.encoder):
        raise ParameterError(f"cannot widen {small.spec.name} into {big.spec.name}: the networks "
                             f"differ in more than width ({', '.join(differing) or 'levels'})")
    if a.refiner and a.refiner != b.refiner:
        raise ParameterError(f"cannot widen a network with refiner {list(a.refiner)} into one "
                             f"with refiner {list(b.refiner)}")
    factors = {wide / narrow for narrow, wide in
               zip((*a.encoder, a.bottleneck), (*b.encoder, b.bottleneck), strict=True)}
    k = factors.pop()
    if factors or k != int(k) or k < 1:
        raise ParameterError(f"cannot widen widths {[*a.encoder, a.bottleneck]} into "
                             f"{[*b.encoder, b.bottleneck]}: not one integer multiple")
    return int(k)


def _copies(channels: int, k: int) -> torch.Tensor:
    """For each of the ``k * channels`` widened channels, the trained channel it copies."""
    return torch.arange(k * channels) % channels


def _gates(hidden: int, k: int) -> torch.Tensor:
    """The same for the ConvLSTM's stacked gates ``(4 hidden)``: copies within each gate."""
    return torch.cat([g * hidden + _copies(hidden, k) for g in range(4)])


def _copy_conv(dst: nn.Conv2d, src: nn.Conv2d, out_map: torch.Tensor, in_map: torch.Tensor,
               noise: float, generator: torch.Generator) -> None:
    """``dst`` reads the copies ``in_map`` of ``src``'s inputs and writes the copies ``out_map``
    of its outputs; each trained input weight is split among its copies (summing to it)."""
    n_in = src.weight.shape[1]
    group = torch.bincount(in_map, minlength=n_in).to(src.weight.dtype)  # copies per input
    weight = src.weight[out_map][:, in_map] / group[in_map][None, :, None, None]
    if noise > 0:
        eps = torch.randn(weight.shape, generator=generator, dtype=weight.dtype)
        eps = eps * noise * weight.abs()
        sums = torch.zeros(weight.shape[0], n_in, *weight.shape[2:], dtype=weight.dtype)
        sums.index_add_(1, in_map, eps)
        weight = weight + eps - sums[:, in_map] / group[in_map][None, :, None, None]
    dst.weight.copy_(weight)
    if src.bias is not None:
        dst.bias.copy_(src.bias[out_map])


@torch.no_grad()
def widen_network(small: DeblurNet, big: DeblurNet, *, noise: float = 0.1,
                  seed: int = 0) -> None:
    """Give ``big`` (``k`` times ``small``'s widths) ``small``'s function, up to rounding.

    ``noise``: the relative size of the uneven split of each weight among its copies (0: even
    split, copies stay identical in training). ``small``'s refiner, if it has one, is copied; a
    ``big`` refiner without one in ``small`` keeps its own (identity) weights.
    """
    k = widening_factor(small, big)
    generator = torch.Generator().manual_seed(seed)
    a = small.shape

    def same(channels: int) -> torch.Tensor:
        return torch.arange(channels)

    def conv(dst: nn.Module, src: nn.Module, out_map, in_map) -> None:
        _copy_conv(dst, src, out_map, in_map, noise, generator)

    cin = same(a.in_channels)
    for narrow, dst, src in zip(a.encoder, big.encoders, small.encoders, strict=True):
        conv(dst[0], src[0], _copies(narrow, k), cin)
        conv(dst[2], src[2], _copies(narrow, k), _copies(narrow, k))
        cin = _copies(narrow, k)
    bottleneck = _copies(a.bottleneck, k)
    if small.lstm is not None:
        conv(big.bottleneck[0], small.bottleneck[0], bottleneck, cin)
        hidden = _gates(a.bottleneck, k)
        conv(big.lstm.input_conv, small.lstm.input_conv, hidden, bottleneck)
        conv(big.lstm.recurrent_conv, small.lstm.recurrent_conv, hidden, bottleneck)
        if small.lstm.peephole is not None:
            big.lstm.peephole.copy_(small.lstm.peephole[:, bottleneck])
    else:
        conv(big.bottleneck[0][0], small.bottleneck[0][0], bottleneck, cin)
        conv(big.bottleneck[0][2], small.bottleneck[0][2], bottleneck, bottleneck)
    cin = bottleneck
    for narrow, up_dst, up_src, dec_dst, dec_src in zip(
            reversed(a.encoder), big.upconvs, small.upconvs, big.decoders, small.decoders,
            strict=True):
        conv(up_dst.conv, up_src.conv, _copies(narrow, k), cin)
        joined = torch.cat([_copies(narrow, k), narrow + _copies(narrow, k)])  # [skip, up]
        conv(dec_dst[0], dec_src[0], _copies(narrow, k), joined)
        conv(dec_dst[2], dec_src[2], _copies(narrow, k), _copies(narrow, k))
        cin = _copies(narrow, k)
    conv(big.head[0], small.head[0], same(3), cin)
    big.head[2].load_state_dict(small.head[2].state_dict())
    if small.refiner is not None:
        big.refiner.load_state_dict(small.refiner.state_dict())
