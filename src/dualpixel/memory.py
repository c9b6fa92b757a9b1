"""Process memory: refusing requests that cannot fit, with the numbers, before allocating
anything; keeping freed memory for reuse, so large tensors do not fault in fresh pages; and
faulting those pages in ahead of time on an idle core."""

from __future__ import annotations

import ctypes
import functools
import os
import threading

from dualpixel.errors import ParameterError

__all__ = ["Prefault", "available_memory", "format_bytes", "prefault", "require_memory",
           "reuse_freed_memory"]

GIB = 1024**3

_M_TRIM_THRESHOLD = -1  # mallopt parameters, <malloc.h>
_M_MMAP_MAX = -4

#: Whether :func:`reuse_freed_memory` took effect in this process (what :func:`prefault` needs).
_REUSING = False

#: Smallest block worth faulting in ahead (:func:`prefault`): below it a thread's start costs
#: more than the faults it saves.
MIN_PREFAULT = 64 * 2**20


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


@functools.cache
def _libc() -> ctypes.CDLL:
    """The C library, through the process's own symbols (``find_library`` would spawn
    ldconfig); raises OSError where there are none to open."""
    return ctypes.CDLL(None)


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
    try:
        mallopt = _libc().mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
    mallopt.restype = ctypes.c_int
    global _REUSING
    _REUSING = bool(mallopt(_M_MMAP_MAX, 0)) and bool(mallopt(_M_TRIM_THRESHOLD, 2**31 - 1))
    return _REUSING


class Prefault:
    """A block of fresh memory that a background thread is faulting in (:func:`prefault`).
    :meth:`release` waits for it and frees the block into the process's heap, where the next
    large arrays find its pages resident. Releasing twice, or one that did nothing, is
    harmless; it is also a context manager."""

    def __init__(self, nbytes: int = 0) -> None:
        self.nbytes, self._pointer, self._thread = 0, None, None
        if nbytes < MIN_PREFAULT or not _REUSING:
            return
        libc = _libc()
        malloc, memset, self._free = libc.malloc, libc.memset, libc.free
        malloc.restype, malloc.argtypes = ctypes.c_void_p, [ctypes.c_size_t]
        memset.restype = ctypes.c_void_p
        memset.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.c_size_t]
        self._free.argtypes = [ctypes.c_void_p]
        self._pointer = malloc(nbytes)  # from the main heap: mmap is off (reuse_freed_memory)
        if not self._pointer:
            return
        self.nbytes = nbytes
        # ctypes lets go of the interpreter's lock during the call: the import or reading the
        # caller does meanwhile runs on the other core
        self._thread = threading.Thread(target=memset, args=(self._pointer, 0, nbytes),
                                        name="dualpixel-prefault", daemon=True)
        self._thread.start()

    def release(self) -> None:
        """Wait for the pages, then free the block (its pages stay in the heap for reuse)."""
        if self._thread is not None:
            self._thread.join()
            self._thread = None
        if self._pointer:
            self._free(self._pointer)
            self._pointer = None

    def __enter__(self) -> Prefault:
        return self

    def __exit__(self, *exc_info) -> None:
        self.release()


def prefault(nbytes: int) -> Prefault:
    """Fault in about ``nbytes`` of fresh memory on a background thread while the caller goes
    on (importing torch, reading images), then :meth:`Prefault.release` it into the heap.

    A process's first pass of a network over a large frame spends a good part of its time in
    the kernel, faulting in and zeroing the pages of its activation maps (the default model's
    first 1680x1120 pass on two cores: about 190,000 faults and 0.2 s of its 1.35 s). Done
    ahead on a core that is otherwise idle, the pass finds its pages resident. Only where
    :func:`reuse_freed_memory` took effect (else a freed block would go back to the kernel);
    blocks under 64 MiB are not worth a thread; at most a quarter of the available memory.
    """
    return Prefault(min(int(nbytes), available_memory() // 4))
