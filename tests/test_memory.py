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
