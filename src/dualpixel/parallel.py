"""Independent jobs in worker processes (dataset synthesis, procedural scenes).

Workers never outlive the command: an error, Ctrl-C or a closed generator in the parent
terminates them, and each worker watches its parent and exits as soon as it is gone (a parent
killed by SIGKILL or SIGTERM runs no cleanup), so no orphan keeps writing.

Workers are spawned, not forked: a fork copies OpenCV's and torch's thread pools in whatever state
the parent left them, and the children can hang on their locks (seen with ``filter2D``). Each
worker runs one torch and one OpenCV thread, so ``workers`` processes use ``workers`` cores.
"""

from __future__ import annotations

import multiprocessing
import os
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
    before = set(multiprocessing.active_children())  # this process's children, ours or not
    pool = ProcessPoolExecutor(max_workers=workers, mp_context=context,
                               initializer=_watch_parent, initargs=(os.getpid(),))
    try:
        futures = [pool.submit(_single_threaded, function, job) for job in jobs]
        for future in as_completed(futures):
            yield future.result()
    except BaseException:  # an error, KeyboardInterrupt, or the caller closing the generator
        # shutdown() stops no running job: the pool's workers (the children started since it
        # was made) are terminated
        workers_started = set(multiprocessing.active_children()) - before
        pool.shutdown(wait=False, cancel_futures=True)
        for process in workers_started:
            process.terminate()
        raise
    pool.shutdown()


#: How often (s) a worker checks that its parent is still there.
PARENT_POLL = 0.25


def _watch_parent(parent: int) -> None:
    """Worker initializer: a daemon thread that ends this process once ``parent`` is gone (the
    worker is then re-parented, so ``os.getppid()`` changes)."""
    import threading
    import time

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(PARENT_POLL)
        os._exit(1)

    threading.Thread(target=watch, name="watch-parent", daemon=True).start()



def _single_threaded(function: Callable[..., Any], job: tuple) -> Any:
    import cv2
    import torch

    torch.set_num_threads(1)
    cv2.setNumThreads(1)  # e.g. the fast renderer's filter2D: one thread per worker process
    return function(*job)
