"""Process memory: refusing requests that cannot fit, with the numbers, before allocating
anything; and keeping freed memory for reuse, so large tensors do not fault in fresh pages."""

from __future__ import annotations

import ctypes
import os

from dualpixel.errors import ParameterError

__all__ = ["available_memory", "format_bytes", "require_memory", "reuse_freed_memory"]

GIB = 1024**3

_M_TRIM_THRESHOLD = -1  # mallopt parameters, <malloc.h>
_M_MMAP_MAX = -4


def format_bytes(nbytes: float) -> str:
    """``nbytes`` in the largest binary unit that keeps it at least 1 (``"10.4 KiB"``).

    >>> format_bytes(10_650), format_bytes(6.4e9)
    ('10.4 KiB', '5.96 GiB')
    """
    for unit, size in (("GiB", GIB), ("MiB", 1024**2), ("KiB", 1024)):
        if nbytes >= size:
            return f"{nbytes / size:.3g} {unit}"
    return f"{nbytes:.0f} bytes"


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


def reuse_freed_memory() -> bool:
    """Let the process keep memory it frees and reuse it for the next large arrays (glibc).

    glibc gives every block of 32 MiB or more back to the kernel when it is freed, so each
    activation map of a full-resolution image (a 1680x1120x32 bfloat16 map is 120 MB) starts on
    fresh pages that the kernel must fault in and zero: on two cores about a third of a
    deblurring pass. This serves such blocks from glibc's heap instead and trims it only above
    2 GiB of free memory; the process's resident memory then stays near its peak. The
    ``dualpixel`` command calls it at start-up; notebooks may call it once. The same can be had
    with the environment variables ``MALLOC_MMAP_MAX_=0 MALLOC_TRIM_THRESHOLD_=2147483647``.

    Returns whether it took effect (False with other C libraries, e.g. musl, macOS, Windows).
    """
    try:
        if not os.confstr("CS_GNU_LIBC_VERSION").startswith("glibc"):
            return False
    except (ValueError, OSError, AttributeError):  # not glibc, or no confstr (Windows)
        return False
    try:  # the process's own symbols hold glibc's (find_library would spawn ldconfig)
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
    mallopt.restype = ctypes.c_int
    return bool(mallopt(_M_MMAP_MAX, 0)) and bool(mallopt(_M_TRIM_THRESHOLD, 2**31 - 1))
