"""Atomic file writes: a file appears under its final name only once it is complete."""

from __future__ import annotations

import contextlib
import errno
import glob
import os
import re
import stat
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import TextIO

from dualpixel.errors import OutputFileError

__all__ = ["PARTIAL_GLOB", "PARTIAL_MARKER", "atomic_path", "check_writable", "open_for_append",
           "remove_partials"]

#: Marker in the names of :func:`atomic_path`'s temporary files: hidden, then
#: ``.<stem>.dualpixel-partial-p<writer's pid>-<random><suffix>``. Cleanup matches only this
#: project's marker, so a user's own ``.notes.partial.txt`` is never taken for a leftover.
PARTIAL_MARKER = ".dualpixel-partial-"
PARTIAL_GLOB = f".*{PARTIAL_MARKER}*"

_UMASK = os.umask(0)
os.umask(_UMASK)

#: A temporary file of :func:`atomic_path` untouched for this long (seconds) is a killed write's
#: leftover. Writers that share a file (loader workers filling the frame store, two exports of
#: one model) finish theirs in seconds to minutes, so a live writer's file is never taken.
LEFTOVER_AGE = 3600.0


def _is_leftover(path: Path, writer: int | None = None) -> bool:
    """Whether ``path``, a temporary file of :func:`atomic_path`, was left by a killed write:
    its writer's process (``writer``, from the name) is gone, or it was not modified for
    :data:`LEFTOVER_AGE` seconds (a name without a writer, or a process id reused since)."""
    try:
        if not path.is_file():
            return False
        if writer is not None and writer != os.getpid() and not _alive(writer):
            return True
        return time.time() - path.stat().st_mtime > LEFTOVER_AGE
    except OSError:
        return False  # gone already


def _alive(pid: int) -> bool:
    """Whether a process ``pid`` exists (one of another user counts as alive)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError, ValueError):
        return True
    return True


@contextlib.contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success rename it over ``path``, else delete it.

    The temporary name keeps the suffix, so writers that infer the format from it still work.
    A temporary file of the same ``path`` that an earlier, killed write left (its writer's
    process gone, or untouched for :data:`LEFTOVER_AGE`) is removed first; a live writer's is left
    alone, so that processes writing the same file at once (loader workers filling the frame
    store) do not delete each other's.
    """
    target = Path(path)
    _check_folder(target)  # its own temporary file below is the probe check_writable makes
    # the name says which process writes it ("p<pid>-"), so a rerun removes a killed writer's
    # file at once; the stem is shortened where the name would exceed the longest (mkstemp
    # adds 8)
    writer = f"p{os.getpid()}-"
    room = _name_max(target.parent) - len(PARTIAL_MARKER) - len(target.suffix) - len(writer) - 10
    base = f".{target.stem[:max(room, 1)]}{PARTIAL_MARKER}"
    pattern = re.compile(rf"{re.escape(base)}(?:p(\d+)-)?[A-Za-z0-9_]{{8}}"
                         rf"{re.escape(target.suffix)}")
    for leftover in target.parent.glob(f"{glob.escape(base)}*{glob.escape(target.suffix)}"):
        match = pattern.fullmatch(leftover.name)
        if match and _is_leftover(leftover, int(match[1]) if match[1] else None):
            leftover.unlink(missing_ok=True)  # this file's earlier write, killed mid-way
    tmp = _temporary(target, base + writer)
    try:
        yield tmp
        os.chmod(tmp, 0o666 & ~_UMASK)  # mkstemp makes 0600; give the usual permissions
        os.replace(tmp, target)
    except OSError as error:
        tmp.unlink(missing_ok=True)
        if error.filename not in (None, str(tmp), str(target)):
            raise  # about another file (e.g. a source being copied): its own message
        raise _output_error(target, error) from None
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def _temporary(target: Path, prefix: str) -> Path:
    """A new empty file ``prefix...<suffix>`` beside ``target``; a folder that takes no file
    (read-only, a pseudo file system such as /proc) is an :class:`OutputFileError` naming
    ``target``, not the temporary name."""
    try:
        fd, name = tempfile.mkstemp(prefix=prefix, suffix=target.suffix, dir=target.parent)
    except OSError as error:
        raise _output_error(target, error) from None
    os.close(fd)
    return Path(name)


def _output_error(target: Path, error: OSError) -> OutputFileError:
    if error.errno == errno.ENOSPC:
        return OutputFileError(target, "no space left on device")
    if isinstance(error, PermissionError):
        return OutputFileError(target, "permission denied (folder not writable)")
    return OutputFileError(target, f"could not be written ({error.strerror or error})")


def _name_max(folder: Path) -> int:
    """The longest file name (bytes) ``folder``'s file system takes (255 where unknown)."""
    try:
        return os.pathconf(folder, "PC_NAME_MAX")
    except (OSError, ValueError):
        return 255


def check_writable(path: str | Path) -> Path:
    """Make ``path``'s folder and check a file can be written there, before any long work; raise
    :class:`OutputFileError` naming the path otherwise (an existing folder, a read-only folder,
    a parent that is a file, a folder that takes no file)."""
    target = _check_folder(Path(path))
    # the access bits do not tell everything (root passes them; /proc takes no new file): make
    # one, with the partial marker so that a kill right here leaves a file cleanup knows
    _temporary(target, f".probe{PARTIAL_MARKER}p{os.getpid()}-").unlink(missing_ok=True)
    return target


def _check_folder(target: Path) -> Path:
    """:func:`check_writable` without its probe file: the name's length, ``target`` no folder,
    its folder made and writable by the access bits."""
    longest = _name_max(target.parent if target.parent.is_dir() else Path("."))
    if len(os.fsencode(target.name)) > longest:
        raise OutputFileError(target, f"its name is {len(os.fsencode(target.name))} bytes long, "
                                      f"more than this file system allows ({longest})")
    if target.is_dir():
        raise OutputFileError(target, "is a folder; give a file name")
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        raise OutputFileError(target, "its parent is a file, not a folder") from None
    except OSError as error:
        raise _output_error(target, error) from None
    if not os.access(target.parent, os.W_OK | os.X_OK):
        raise OutputFileError(target, "permission denied (folder not writable)")
    return target


def remove_partials(folder: str | Path) -> int:
    """Delete the temporary files a killed writer left under ``folder`` (recursively); return how
    many. Call it when a job (re)starts in a folder no other process is writing."""
    folder = Path(folder)
    if not folder.is_dir():
        return 0
    removed = 0
    for leftover in folder.rglob(PARTIAL_GLOB):
        if leftover.is_file():
            leftover.unlink(missing_ok=True)
            removed += 1
    return removed


def open_for_append(path: str | Path) -> TextIO:
    """``path`` opened to append text (created if missing), never through a symbolic link: a
    link planted in an output folder would have us write into the file it points to."""
    path = Path(path)
    try:
        descriptor = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT | os.O_NOFOLLOW
                             | os.O_CLOEXEC, 0o644)
    except OSError as error:
        if path.is_symlink():
            raise OutputFileError(path, "is a symbolic link; the tool never writes through "
                                        "a link (remove it)") from None
        raise _output_error(path, error) from None
    if not stat.S_ISREG(os.fstat(descriptor).st_mode):
        os.close(descriptor)
        raise OutputFileError(path, "is not a regular file")
    return os.fdopen(descriptor, "a", encoding="utf-8")
