"""Refusing requests that cannot fit in memory, with the numbers, before allocating anything."""

from __future__ import annotations

import os

from dualpixel.errors import ParameterError

__all__ = ["available_memory", "require_memory"]

GIB = 1024**3


def available_memory() -> int:
    """Bytes of memory available to new allocations (Linux ``MemAvailable``; else physical)."""
    try:
        with open("/proc/meminfo", encoding="ascii") as handle:
            for line in handle:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return 2**62  # unknown: do not refuse


def require_memory(nbytes: float, what: str) -> None:
    """Raise :class:`ParameterError` when ``what`` needs more than the available memory.

    >>> require_memory(1024, "a tiny request")
    """
    available = available_memory()
    if nbytes > available:
        raise ParameterError(
            f"{what} needs about {nbytes / GIB:.1f} GiB of memory, but only "
            f"{available / GIB:.1f} GiB is available; ask for less"
        )
