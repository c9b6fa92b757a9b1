"""Process memory: keeping freed memory for reuse (dualpixel.memory.reuse_freed_memory)."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

PROBE = """
import sys
import numpy as np
from dualpixel.memory import reuse_freed_memory

def resident_mib():
    with open("/proc/self/statm") as handle:
        return int(handle.read().split()[1]) * {page} / 2**20

took = reuse_freed_memory() if sys.argv[1] == "reuse" else None
before = resident_mib()
block = np.ones(64 * 2**20, dtype=np.uint8)  # 64 MiB, every page touched
del block
print(took, resident_mib() - before)
"""


def _resident_after_free(mode: str) -> tuple[str, float]:
    code = PROBE.format(page=os.sysconf("SC_PAGE_SIZE"))
    out = subprocess.run([sys.executable, "-c", code, mode], capture_output=True, text=True,
                         check=True).stdout.split()
    return out[0], float(out[1])


@pytest.mark.skipif(not sys.platform.startswith("linux")
                    or not os.confstr("CS_GNU_LIBC_VERSION").startswith("glibc"),
                    reason="glibc only")
def test_reuse_freed_memory_keeps_a_freed_block_resident():
    took, kept = _resident_after_free("reuse")
    assert took == "True"
    assert kept > 60  # the freed 64 MiB stays in the process, ready for the next array
    _, kept_by_default = _resident_after_free("default")
    assert kept_by_default < 8  # glibc's default: given back to the kernel on free


PREFAULT_PROBE = """
import ctypes, resource, sys
from dualpixel.memory import prefault, reuse_freed_memory

def faults():
    return resource.getrusage(resource.RUSAGE_SELF).ru_minflt

reuse_freed_memory()
with prefault(int(sys.argv[1]) * 2**20) as touched:
    pass
before = faults()
libc = ctypes.CDLL(None)  # as torch allocates tensors (numpy asks for huge pages instead)
libc.malloc.restype = ctypes.c_void_p
libc.memset.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.c_size_t]
libc.memset(libc.malloc(128 * 2**20), 1, 128 * 2**20)  # 128 MiB, every page written
print(touched.nbytes, faults() - before)
"""


def _faults_after_prefault(mib: int) -> tuple[int, int]:
    out = subprocess.run([sys.executable, "-c", PREFAULT_PROBE, str(mib)], capture_output=True,
                         text=True, check=True).stdout.split()
    return int(out[0]), int(out[1])


@pytest.mark.skipif(not sys.platform.startswith("linux")
                    or not os.confstr("CS_GNU_LIBC_VERSION").startswith("glibc"),
                    reason="glibc only")
def test_prefault_leaves_the_next_large_array_its_pages_resident():
    pages = 128 * 2**20 // os.sysconf("SC_PAGE_SIZE")
    touched, faults = _faults_after_prefault(160)
    assert touched == 160 * 2**20
    assert faults < pages // 10  # the array found the prefaulted pages in the heap
    touched, faults = _faults_after_prefault(0)  # nothing faulted ahead: every page anew
    assert touched == 0 and faults > pages * 0.9


def test_prefault_does_nothing_without_reuse_or_for_small_blocks():
    """Without :func:`reuse_freed_memory` a freed block would go back to the kernel, and a
    small one is not worth a thread: both give a handle that does nothing."""
    from dualpixel.memory import MIN_PREFAULT, Prefault, prefault

    code = ("from dualpixel.memory import prefault\n"
            "p = prefault(256 * 2**20); p.release(); p.release(); print(p.nbytes)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert out.split() == ["0"]
    assert prefault(MIN_PREFAULT - 1).nbytes == 0
    Prefault().release()
