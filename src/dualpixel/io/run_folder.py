"""The one check every resumable output folder makes: was it started with these settings?

``scenes``, ``synth`` and ``train`` each record their settings in the folder (``scenes.json``,
``dataset.json``, ``config.yaml``) and continue a folder only when the settings agree; this module
says which settings differ, in the words their errors use, and where a path setting points, so
that a folder moved or copied together with the data it was made from still counts as the same.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

__all__ = ["differing_settings", "locate", "same_location"]


def differing_settings(mine: Mapping[str, Any], theirs: Mapping[str, Any], *,
                       ignore: Iterable[str] = ()) -> list[str]:
    """Sorted names of the settings that differ between two records, ``ignore`` left out.

    A setting that is a mapping on both sides (e.g. a ``config`` block) is compared entry by
    entry and its differing entries are named instead of it.

    >>> differing_settings({"config": {"a": 1, "b": 2}, "seed": 0},
    ...                    {"config": {"a": 1, "b": 3}, "seed": 1})
    ['b', 'seed']
    """
    skipped = set(ignore)
    differ: set[str] = set()
    for key in (set(mine) | set(theirs)) - skipped:
        a, b = mine.get(key), theirs.get(key)
        if isinstance(a, Mapping) and isinstance(b, Mapping):
            differ.update(differing_settings(a, b, ignore=skipped))
        elif a != b:
            differ.add(key)
    return sorted(differ)


def locate(path: str | Path, folder: str | Path) -> tuple[str, str | None]:
    """``path`` as an absolute path and as seen from ``folder`` (None where no relative path
    exists: Windows, different drives).

    >>> locate("/runs/a/data/x", "/runs/a/phases/01")[1]
    '../../data/x'
    """
    resolved = Path(path).resolve()
    try:
        relative: str | None = os.path.relpath(resolved, Path(folder).resolve())
    except ValueError:
        relative = None
    return str(resolved), relative


def same_location(mine: tuple[str, str | None], theirs: tuple[str | None, str | None]) -> bool:
    """Whether two :func:`locate` records name the same data: the same absolute path (the
    working directory changed), or the same path relative to the folder that records it (the
    folder moved together with the data).

    >>> same_location(("/new/a/data/x", "../data/x"), ("/old/a/data/x", "../data/x"))
    True
    >>> same_location(("/new/a/data/y", "../data/y"), ("/old/a/data/x", "../data/x"))
    False
    """
    if mine[0] == theirs[0]:
        return True
    return theirs[1] is not None and theirs[1] == mine[1]
