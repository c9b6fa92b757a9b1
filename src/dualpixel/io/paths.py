"""Paths read from files and options stay inside their folders (one check, used everywhere)."""

from __future__ import annotations

from pathlib import Path

from dualpixel.errors import InputFileError, ParameterError

__all__ = ["check_plain_name", "contained"]


def contained(root: str | Path, relative: str | Path, source: str | Path) -> Path:
    """``root / relative``, refused (naming ``source``, the file it was read from) when
    ``relative`` is absolute or, symlinks resolved, leads outside ``root``."""
    root = Path(root)
    candidate = Path(relative)
    if candidate.is_absolute() or not (root / candidate).resolve().is_relative_to(root.resolve()):
        raise InputFileError(source, f"path {str(relative)!r} leads outside {root}")
    return root / candidate


def check_plain_name(name: str, option: str) -> str:
    """A name used as one folder name (a split, a step): no separators, not '.' or '..'."""
    if not name or name in (".", "..") or "/" in name or "\\" in name or "\0" in name:
        raise ParameterError(f"{option} must be a plain name (letters, digits, '-', '_'), "
                             f"got {name!r}")
    return name
