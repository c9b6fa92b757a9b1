"""One writer per folder: an advisory lock file that names its holder.

``with folder_lock(folder, "synth"):`` takes ``folder/.dualpixel.lock`` with ``filelock``
(an exclusive ``flock`` on Unix, never waiting) and writes the holder's pid and command into it.
A second writer gets an error naming the holder. The kernel releases the lock when its process
ends, however it ends, so a lock left by a killed process is simply taken over. The lock file is
never opened through a symbolic link (a planted link would have us write to what it points to).
On release the holder's line is cleared (a finished folder's files do not depend on who wrote
them), and a folder this call made that holds nothing else (a run refused before it wrote
anything) is removed with its lock file.
"""

from __future__ import annotations

import contextlib
import os
import stat
import sys
from collections.abc import Iterator
from pathlib import Path

import filelock

from dualpixel.errors import OutputFileError

__all__ = ["LOCK_NAME", "folder_lock"]

LOCK_NAME = ".dualpixel.lock"
_OPEN_FLAGS = os.O_NOFOLLOW | os.O_CLOEXEC


def _check_plain_file(path: Path) -> None:
    """Refuse a lock path that is a link or not a regular file."""
    if path.is_symlink():
        raise OutputFileError(path, "is a symbolic link; the lock file is never opened "
                                    "through a link (remove it)")
    if path.exists() and not stat.S_ISREG(path.stat().st_mode):
        raise OutputFileError(path, "is not a regular file (remove it)")


def _holder(path: Path) -> str:
    """Who holds the lock, as the holder wrote it."""
    try:
        descriptor = os.open(path, os.O_RDONLY | _OPEN_FLAGS)
    except OSError:
        return "another process"
    with os.fdopen(descriptor, encoding="utf-8", errors="replace") as handle:
        return handle.read(400).strip() or "another process"


@contextlib.contextmanager
def folder_lock(folder: str | Path, command: str) -> Iterator[Path]:
    """Hold the lock of ``folder`` (created if needed) while the block runs."""
    folder = Path(folder)
    made = [f for f in (folder, *folder.parents) if not f.exists()]
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / LOCK_NAME
    _check_plain_file(path)
    lock = filelock.FileLock(path, timeout=0, mode=0o644)
    try:
        lock.acquire()
    except filelock.Timeout:
        raise OutputFileError(folder, f"is being written by {_holder(path)}; wait for it to end "
                                      "or choose another folder") from None
    except OSError as error:
        _check_plain_file(path)
        raise OutputFileError(path, f"cannot be opened ({error.strerror})") from None
    try:
        _check_plain_file(path)  # the file locked is the plain file named
        descriptor = os.open(path, os.O_WRONLY | os.O_TRUNC | _OPEN_FLAGS)
        with os.fdopen(descriptor, "w", encoding="utf-8") as handle:
            handle.write(f"pid {os.getpid()} ({command}: {' '.join(sys.argv)[:200]})\n")
        yield path
    finally:
        _clear(path, made)
        lock.release()


def _clear(path: Path, made: list[Path]) -> None:
    """Clear the holder's line, or, where the folders in ``made`` (deepest first) hold nothing
    but the lock, remove it and them; done while the lock is still held."""
    with contextlib.suppress(OSError):
        if made and [p.name for p in path.parent.iterdir()] == [LOCK_NAME]:
            path.unlink()
            for folder in made:
                folder.rmdir()  # stops (OSError) at the first that holds something
            return
        descriptor = os.open(path, os.O_WRONLY | os.O_TRUNC | _OPEN_FLAGS)
        os.close(descriptor)
