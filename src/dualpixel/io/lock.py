"""One writer per folder: an advisory lock file that names its holder (issue #34).

``with folder_lock(folder, "synth"):`` takes ``folder/.dualpixel.lock`` with ``fcntl.flock``
(exclusive, non-blocking) and writes the holder's pid and command into it. A second writer gets
an error naming the holder. The kernel releases the lock when its process ends, however it ends,
so a lock left by a killed process is simply taken over.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import stat
import sys
from collections.abc import Iterator
from pathlib import Path

from dualpixel.errors import OutputFileError

__all__ = ["LOCK_NAME", "folder_lock"]

LOCK_NAME = ".dualpixel.lock"


@contextlib.contextmanager
def folder_lock(folder: str | Path, command: str) -> Iterator[Path]:
    """Hold the lock of ``folder`` (created if needed) while the block runs."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / LOCK_NAME
    try:  # never through a link: a planted link would have us truncate what it points to
        descriptor = os.open(path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC, 0o644)
    except OSError as error:
        if path.is_symlink():
            raise OutputFileError(path, "is a symbolic link; the lock file is never opened "
                                        "through a link (remove it)") from None
        raise OutputFileError(path, f"cannot be opened ({error.strerror})") from None
    if not stat.S_ISREG(os.fstat(descriptor).st_mode):
        os.close(descriptor)
        raise OutputFileError(path, "is not a regular file (remove it)")
    handle = os.fdopen(descriptor, "r+", encoding="utf-8")  # held open: the lock lives with it
    try:
        try:
            fcntl.flock(handle.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            handle.seek(0)
            holder = handle.read().strip() or "another process"
            raise OutputFileError(folder, f"is being written by {holder}; wait for it to end "
                                          "or choose another folder") from None
        handle.seek(0)
        handle.truncate()
        handle.write(f"pid {os.getpid()} ({command}: {' '.join(sys.argv)[:200]})\n")
        handle.flush()
        yield path
    finally:
        handle.close()  # releases the lock
