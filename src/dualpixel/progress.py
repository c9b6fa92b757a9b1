"""Progress bars: tqdm bars a caller can switch off, which otherwise follow tqdm's own settings
(``TQDM_DISABLE=1`` silences every bar, as ``dualpixel --quiet`` does)."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from tqdm import tqdm

__all__ = ["progress_bar"]


def progress_bar(iterable: Iterable | None = None, *, enabled: bool = True,
                 **options: Any) -> tqdm:
    """``tqdm(iterable, **options)``, disabled when not ``enabled``; when enabled, tqdm's
    environment (``TQDM_DISABLE``, ``TQDM_MININTERVAL``, ...) decides what is not given."""
    if not enabled:
        options["disable"] = True
    return tqdm(iterable, **options)
