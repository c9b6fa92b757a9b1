"""Paths read from files and options stay inside their folders, and no output is an input
(one check each, used everywhere)."""

from __future__ import annotations

import errno
import os
from collections.abc import Iterable, Mapping
from pathlib import Path

from dualpixel.errors import InputFileError, OutputFileError, ParameterError

__all__ = ["broken_link", "check_outputs_apart", "check_plain_name", "contained"]


def contained(root: str | Path, relative: str | Path, source: str | Path) -> Path:
    """``root / relative``, refused (naming ``source``, the file it was read from) when
    ``relative`` is absolute or, symlinks resolved, leads outside ``root``."""
    root = Path(root)
    candidate = Path(relative)
    if candidate.is_absolute() or not (root / candidate).resolve().is_relative_to(root.resolve()):
        raise InputFileError(source, f"path {str(relative)!r} leads outside {root}")
    return root / candidate


def broken_link(path: str | Path) -> str | None:
    """What is wrong with ``path`` when it is a symbolic link that leads nowhere (it loops, or
    its target does not exist), else None: said instead of "missing"."""
    path = Path(path)
    if not path.is_symlink():
        return None
    try:
        os.stat(path)
    except OSError as error:
        if error.errno == errno.ELOOP:
            return "is a symbolic link that loops (following it leads back to a link on the way)"
        return f"is a symbolic link to {os.readlink(path)}, which does not exist"
    return None


def check_plain_name(name: str, option: str) -> str:
    """A name used as one folder name (a split, a step): no separators, not '.' or '..'."""
    if not name or name in (".", "..") or "/" in name or "\\" in name or "\0" in name:
        raise ParameterError(f"{option} must be a plain name (letters, digits, '-', '_'), "
                             f"got {name!r}")
    return name


def check_outputs_apart(inputs: Mapping[str, Iterable[str | Path]],
                        outputs: Mapping[str, str | Path]) -> None:
    """Refuse, before any work, an output that is an input, a folder that holds one, or a path
    inside an input folder (symlinks resolved: a link to an input is that input).
    ``inputs`` and ``outputs`` are keyed by the option that names them (e.g. ``--left``);
    inputs that do not exist are skipped (their readers say so)."""
    existing = [(option, Path(path), Path(path).resolve()) for option, paths in inputs.items()
                for path in paths if Path(path).exists()]
    for out_option, out in outputs.items():
        target = Path(out).resolve()
        for option, given, source in existing:
            if target == source and not source.is_dir():
                problem = f"is the input {option} ({given})"
            elif source.is_relative_to(target):  # the input folder itself, or one inside
                problem = f"is a folder that holds the input {option} ({given})"
            elif source.is_dir() and target.is_relative_to(source):
                problem = f"lies inside the input folder {option} ({given})"
            else:
                continue
            raise OutputFileError(out, f"{problem} ({out_option}): inputs are never outputs; "
                                       "write elsewhere")
