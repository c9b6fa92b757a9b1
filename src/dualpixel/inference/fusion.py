"""Convolutions with their activation fused, for inference on the CPU.

Every ``Conv2d`` followed by ``ReLU`` or ``LeakyReLU`` in an ``nn.Sequential`` (the double
convolutions of the encoder, decoder and refiner levels) becomes one oneDNN convolution with
the activation as a post-op (``torch.ops.mkldnn._convolution_pointwise``, the kernel PyTorch's
own compiler emits for this pattern). The separate activation pass reads and writes the whole
feature map once more; in bfloat16 it is also poorly vectorised, so on a 2-core CPU with AMX the
activations took a quarter of a 1680x1120 pass. Fused, the outputs are the same (float32: bit
for bit; bfloat16: to its rounding).

:func:`fused_copy` fuses a copy, so the caller's network stays trainable and unchanged; where
the kernel is missing (a PyTorch built without oneDNN) or disagrees with the plain computation,
nothing is fused.
"""

from __future__ import annotations

import copy
import functools
import itertools

import torch
from torch import nn

__all__ = ["FusedConvActivation", "fused_copy", "fusion_available"]


class FusedConvActivation(nn.Module):
    """``act(conv(x))`` as one oneDNN call on the CPU with weights held in ``dtype``;
    ``(B, cin, H, W)`` -> ``(B, cout, H', W')`` in ``dtype``. Elsewhere (another device, or
    with gradients) it computes the two modules as they were."""

    def __init__(self, conv: nn.Conv2d, activation: nn.ReLU | nn.LeakyReLU,
                 dtype: torch.dtype = torch.float32) -> None:
        super().__init__()
        if conv.padding_mode != "zeros" or isinstance(conv.padding, str):
            raise ValueError("only zero padding given as numbers can be fused")
        self.conv, self.activation = conv, activation
        self.attr = "relu" if isinstance(activation, nn.ReLU) else "leaky_relu"
        self.scalars = [] if self.attr == "relu" else [activation.negative_slope]
        self.dtype = dtype
        self._weight = conv.weight.detach().to(dtype)
        self._bias = None if conv.bias is None else conv.bias.detach().to(dtype)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if x.device.type != "cpu" or torch.is_grad_enabled():
            return self.activation(self.conv(x))
        return torch.ops.mkldnn._convolution_pointwise(
            x.to(self.dtype), self._weight, self._bias, list(self.conv.padding),
            list(self.conv.stride), list(self.conv.dilation), self.conv.groups, self.attr,
            self.scalars, "",
        )


def _fuse_in_place(model: nn.Module, dtype: torch.dtype) -> int:
    count = 0
    for module in model.modules():
        if not isinstance(module, nn.Sequential):
            continue
        children = list(module._modules.items())
        for (name, first), (next_name, second) in itertools.pairwise(children):
            if type(first) is not nn.Conv2d or type(second) not in (nn.ReLU, nn.LeakyReLU):
                continue
            try:
                module._modules[name] = FusedConvActivation(first, second, dtype)
            except ValueError:  # padding the kernel does not take
                continue
            module._modules[next_name] = nn.Identity()
            count += 1
    return count


@functools.cache
def fusion_available() -> bool:
    """Whether this PyTorch has the fused kernel and it matches the plain computation."""
    if not (torch.backends.mkldnn.is_available()
            and hasattr(torch.ops.mkldnn, "_convolution_pointwise")):
        return False
    with torch.random.fork_rng(devices=[]):  # the caller's random stream is left alone
        torch.manual_seed(0)
        probe = nn.Sequential(nn.Conv2d(4, 8, 3, padding=1), nn.LeakyReLU(0.1)).eval()
        x = torch.randn(1, 4, 9, 11)
    try:
        with torch.inference_mode():
            expected = probe(x)
            got = FusedConvActivation(probe[0], probe[1])(x)
    except (RuntimeError, NotImplementedError):
        return False
    return bool(torch.allclose(expected, got, atol=1e-5))


def fused_copy(model: nn.Module, dtype: torch.dtype | None = None) -> tuple[nn.Module, int]:
    """A copy of ``model`` (on the CPU) with its convolution + activation pairs fused, weights
    of the fused ones in ``dtype`` (default float32), and how many were fused; ``model``
    itself when nothing can be (then the count is 0)."""
    if any(p.device.type != "cpu" for p in model.parameters()) or not fusion_available():
        return model, 0
    fused = copy.deepcopy(model)
    count = _fuse_in_place(fused, dtype or torch.float32)
    return (fused, count) if count else (model, 0)
