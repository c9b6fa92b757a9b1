"""Independent jobs in worker processes (dataset synthesis, procedural scenes).

Workers are spawned, not forked: a fork copies OpenCV's and torch's thread pools in whatever state
the parent left them, and the children can hang on their locks (seen with ``filter2D``). Each
worker runs one torch and one OpenCV thread, so ``workers`` processes use ``workers`` cores.
"""

from __future__ import annotations

import multiprocessing
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import ProcessPoolExecutor, as_completed
from typing import Any

__all__ = ["completed"]


def completed(
    function: Callable[..., Any], jobs: Iterable[tuple], workers: int
) -> Iterator[Any]:
    """``function(*job)`` for every job, in this process when ``workers <= 1`` (in order), else
    in ``workers`` spawned processes (in the order they finish). ``function`` must be defined at
    a module's top level (it is pickled)."""
    if workers <= 1:
        for job in jobs:
            yield function(*job)
        return
    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=workers, mp_context=context) as pool:
        futures = [pool.submit(_single_threaded, function, job) for job in jobs]
        for future in as_completed(futures):
            yield future.result()


def _single_threaded(function: Callable[..., Any], job: tuple) -> Any:
    import cv2
    import torch

    torch.set_num_threads(1)
    cv2.setNumThreads(1)  # e.g. the fast renderer's filter2D: one thread per worker process
    return function(*job)
