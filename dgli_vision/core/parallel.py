"""Work spread over processes, results in input order: what ``-j N`` does for commands
whose items are independent (``render``, ``simulate``).

Each item's result depends on the item alone (its own seed), so the results are those of
one process, in the same order, whatever the number of workers.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from typing import Any, TypeVar

__all__ = ["ordered_map"]

T = TypeVar("T")


def _quiet_worker() -> None:
    """Workers ignore Ctrl-C and run OpenCV on one thread: the parent stops the work
    (a terminal's interrupt reaches the whole process group) and there is one process
    per core."""
    import signal

    import cv2

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    cv2.setNumThreads(1)


def ordered_map(func: Callable[[Any], T], items: Iterable[Any], *, jobs: int = 1) -> Iterator[T]:
    """``func`` of every item, in the order of ``items``, on ``jobs`` processes.

    Parameters
    ----------
    func : callable
        A module-level function (sent to spawned workers by name); its argument and
        result must pickle.
    items : iterable
    jobs : int, keyword-only
        Worker processes; 1 works in this process.

    Yields
    ------
    object
        ``func(item)``, as soon as it and every result before it are done. When the
        caller stops early (or Ctrl-C), the items not started are dropped and those
        running finish.
    """
    if jobs < 1:
        raise ValueError(f"jobs must be at least 1, got {jobs}")
    if jobs == 1:
        for item in items:
            yield func(item)
        return
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    pool = ProcessPoolExecutor(
        jobs, mp_context=multiprocessing.get_context("spawn"), initializer=_quiet_worker
    )
    try:
        futures = [pool.submit(func, item) for item in items]
        for future in futures:
            yield future.result()
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
