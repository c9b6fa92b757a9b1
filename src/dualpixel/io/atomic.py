"""Atomic file writes: a file appears under its final name only once it is complete."""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path

__all__ = ["PARTIAL_GLOB", "atomic_path", "remove_partials"]

#: Names of the temporary files of :func:`atomic_path` (hidden, ``.partial`` before the suffix).
PARTIAL_GLOB = ".*.partial*"

_UMASK = os.umask(0)
os.umask(_UMASK)


@contextlib.contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success rename it over ``path``, else delete it.

    The temporary name keeps the suffix, so writers that infer the format from it still work.
    """
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp_name = tempfile.mkstemp(
        prefix=f".{target.stem}.", suffix=f".partial{target.suffix}", dir=target.parent
    )
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        yield tmp
        os.chmod(tmp, 0o666 & ~_UMASK)  # mkstemp makes 0600; give the usual permissions
        os.replace(tmp, target)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


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
