"""The one check every resumable output folder makes: was it started with these settings?

``scenes``, ``synth`` and ``train`` each record their settings in the folder (``scenes.json``,
``dataset.json``, ``config.yaml``) and continue a folder only when the settings agree; this module
says which settings differ, in the words their errors use.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

__all__ = ["differing_settings"]


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
