"""Which number format inference runs in: ``auto`` picks the fastest that keeps the
output within 0.02 dB of float32 on real photographs.

- CUDA: bfloat16 autocast where the GPU has it (Ampere and later), else float16.
- CPU: bfloat16 autocast where the CPU computes it natively (x86 ``avx512_bf16`` or ``amx_bf16``,
  Arm ``bf16``); float32 elsewhere, where emulated bfloat16 would be slower than float32.

Every precision runs the network in channels-last memory, which oneDNN and cuDNN convolve fastest
(on this project's 2-core CPU it alone takes float32 from 19 to 13 s per 1680x1120 image).
"""

from __future__ import annotations

import functools
import platform
from dataclasses import dataclass

import torch

from dualpixel.errors import ParameterError
from dualpixel.names import PRECISIONS

__all__ = ["PRECISIONS", "Precision", "cpu_has_native_bf16", "resolve_precision"]

_DTYPES = {"fp32": torch.float32, "bf16": torch.bfloat16, "fp16": torch.float16}


@dataclass(frozen=True)
class Precision:
    """A resolved precision: its name, the autocast dtype (``None``: plain float32) and whether
    the network uses channels-last memory."""

    name: str
    dtype: torch.dtype | None
    channels_last: bool

    def autocast(self, device: torch.device):
        """The autocast context for ``device`` (a no-op for float32)."""
        return torch.autocast(device.type, dtype=self.dtype or torch.float32,
                              enabled=self.dtype is not None)


@functools.cache
def cpu_has_native_bf16() -> bool:
    """Whether this CPU computes bfloat16 natively (read from ``/proc/cpuinfo`` on Linux)."""
    try:
        with open("/proc/cpuinfo", encoding="ascii", errors="replace") as handle:
            text = handle.read()
    except OSError:
        return False
    flags = set()
    for line in text.splitlines():
        if line.startswith(("flags", "Features")):
            flags.update(line.split(":", 1)[-1].split())
    if platform.machine().lower() in ("aarch64", "arm64"):
        return "bf16" in flags
    return bool({"avx512_bf16", "amx_bf16"} & flags)


def resolve_precision(precision: str, device: torch.device | str) -> Precision:
    """``precision`` (one of :data:`PRECISIONS`) for ``device``; an explicit choice the device
    cannot run well is refused with what to use instead."""
    device = torch.device(device)
    if precision not in PRECISIONS:
        raise ParameterError(f"precision must be one of {', '.join(PRECISIONS)}, "
                             f"got {precision!r}")
    if precision == "auto":
        if device.type == "cuda":
            precision = "bf16" if torch.cuda.is_bf16_supported() else "fp16"
        elif device.type == "cpu" and cpu_has_native_bf16():
            precision = "bf16"
        else:
            precision = "fp32"
    elif precision == "fp16" and device.type != "cuda":
        raise ParameterError(f"precision fp16 runs on CUDA only; on {device.type} use bf16 "
                             "(where the CPU has it) or fp32")
    elif precision == "bf16" and device.type == "cpu" and not cpu_has_native_bf16():
        raise ParameterError("precision bf16: this CPU has no native bfloat16 (avx512_bf16, "
                             "amx_bf16 or Arm bf16), where it runs slower than fp32; use fp32 "
                             "or auto")
    return Precision(precision, None if precision == "fp32" else _DTYPES[precision],
                     channels_last=True)
