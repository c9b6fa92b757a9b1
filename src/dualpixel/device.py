"""Choosing the torch device, with clear errors for names that cannot work here."""

from __future__ import annotations

import torch

from dualpixel.errors import ParameterError

__all__ = ["resolve_device"]


def resolve_device(name: str | torch.device = "auto") -> torch.device:
    """``"auto"``: CUDA when available, else the CPU; otherwise the named device (``"cpu"``,
    ``"cuda"``, ``"cuda:1"``, ``"mps"``), refused with the reason when it is unknown or absent.

    >>> resolve_device("cpu")
    device(type='cpu')
    """
    if isinstance(name, torch.device):
        device = name
    elif name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    else:
        try:
            device = torch.device(name)
        except (RuntimeError, TypeError):
            raise ParameterError(
                f"unknown device {name!r}; use auto, cpu, cuda or cuda:N"
            ) from None
    if device.type == "cuda":
        if not torch.cuda.is_available():
            raise ParameterError(f"device {name!r}: CUDA is not available on this machine "
                                 "(use \"cpu\" or \"auto\")")
        if device.index is not None and device.index >= torch.cuda.device_count():
            raise ParameterError(f"device {name!r}: only {torch.cuda.device_count()} CUDA "
                                 "device(s) present")
    elif device.type == "mps" and not torch.backends.mps.is_available():
        raise ParameterError(f"device {name!r}: MPS is not available on this machine")
    elif device.type not in ("cpu", "cuda", "mps"):
        raise ParameterError(f"device {name!r} is not supported; use auto, cpu or cuda")
    return device
