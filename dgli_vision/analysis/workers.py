"""Worker processes started before this process has loaded its references: the first
thing a command that classifies on ``-j N`` does, so that their start (a new
interpreter, imports, the reference set: half a second of a core) runs beside this
process's own imports instead of after them.

The workers load the reference set from its file themselves;
:func:`~dgli_vision.analysis.evaluate.adopt_workers` hands them to
:func:`~dgli_vision.analysis.evaluate.evaluate_pairs` once this process has loaded the
same file. Only the standard library is imported here: it is imported before the rest.
"""

from __future__ import annotations

from typing import Any

__all__ = ["init_worker", "start_workers_early", "take_early_workers", "worker_references"]

#: The pool started early and what it was started with: (workers, references file or
#: None for the default, colours, pool); None once taken or when none was started.
_EARLY: tuple[int, Any, Any, Any] | None = None
#: A worker process's reference set and calibrated colours (:func:`init_worker`).
_WORKER_REFS: Any = None
_WORKER_COLOURS: dict | None = None


def init_worker(refs: Any, colours: dict | None = None) -> None:
    """A worker process's start: keep its reference set (a ``ReferenceSet``) and
    colours, and keep it to one thread (each worker is one of ``jobs`` processes: no
    oversubscription).

    Workers ignore Ctrl-C: the parent stops the batch and lets running pairs finish, so a
    terminal's interrupt (sent to the whole process group) leaves no half-written state
    and no worker tracebacks. They die with their parent, however it ends
    (:func:`~dgli_vision.core.parallel.die_with_parent`).
    """
    import signal

    import cv2

    from ..core.parallel import die_with_parent

    die_with_parent()
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    global _WORKER_REFS, _WORKER_COLOURS
    _WORKER_REFS = refs
    _WORKER_COLOURS = colours
    cv2.setNumThreads(1)


def worker_references() -> tuple[Any, dict | None]:
    """The reference set and colours :func:`init_worker` kept in this process (None,
    None where it has not run)."""
    return _WORKER_REFS, _WORKER_COLOURS


def _init_from_file(references_path: str | None, colours: dict | None) -> None:
    """A worker's start: its references loaded from their file (a file that cannot be
    read leaves it without: this process reports the problem, in one line)."""
    from ..classifier.references import load_references
    from ..core.errors import DgliError

    try:
        refs = load_references(references_path)
    except DgliError:
        refs = None
    init_worker(refs, colours)


def _warm() -> None:
    """A worker's first task: import what classifying a pair needs."""
    from ..classifier import classify, pipeline  # noqa: F401


def start_workers_early(jobs: int, references_path: str | None, colours: dict | None) -> None:
    """Start the ``jobs - 1`` worker processes of a ``-j jobs`` run now, from a thread
    (starting one waits until it has read its arguments); nothing for ``jobs`` 1.

    Parameters
    ----------
    jobs : int
    references_path : str or None
        The reference set the run loads (None: the default one).
    colours : dict or None
        Calibrated sticker colours.
    """
    global _EARLY
    if jobs < 2:
        return
    import atexit
    import multiprocessing as mp
    import os
    import threading
    from concurrent.futures import ProcessPoolExecutor

    take_early_workers(-1, None, None)  # one started earlier and never used: ended
    for name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(name, "1")  # one thread per library in each worker
    pool = ProcessPoolExecutor(
        jobs - 1,
        mp_context=mp.get_context("spawn"),
        initializer=_init_from_file,
        initargs=(references_path, colours),
    )
    _EARLY = (jobs - 1, references_path, colours, pool)
    atexit.register(take_early_workers, -1, None, None)  # ended if never taken

    def start() -> None:
        try:
            for _ in range(jobs - 1):  # each submit starts a process while none is idle
                pool.submit(_warm)
        except Exception:  # the pool's first real submit raises it again
            return

    threading.Thread(target=start, name="dgli-start-workers", daemon=True).start()


def take_early_workers(workers: int, references_path: str | None, colours: dict | None) -> Any:
    """The pool :func:`start_workers_early` started, if it has ``workers`` processes
    and was started with ``references_path`` and ``colours`` (then it is the caller's);
    None otherwise, and a pool started with something else is ended."""
    global _EARLY
    early, _EARLY = _EARLY, None
    if early is None:
        return None
    if early[:3] == (workers, references_path, colours):
        return early[3]
    early[3].shutdown(wait=True, cancel_futures=True)
    return None
