"""Labelling many episodes: in this process, over local processes (``-j``) or on a Dask
distributed cluster (``--dask``).

Each task labels part of one episode (:func:`~.label.label_part`): the worker reads the
episode itself, so only file names travel to it and only distances come back. Episodes
are yielded in the order they were given, each as soon as all its parts are back. A
bad episode comes back as an :class:`~.label.EpisodeFailure` and the batch goes on.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from concurrent.futures import Future, ProcessPoolExecutor
from dataclasses import dataclass, field
from typing import Any

from ..core.errors import InvalidInputError
from .episodes import ReadOptions
from .goal import GoalSpec
from .label import EpisodeFailure, EpisodeLabels, assemble, cached_references, label_part

__all__ = ["LabelJob", "label_episodes"]


@dataclass(frozen=True)
class LabelJob:
    """What to label and how.

    Attributes
    ----------
    paths : tuple of str
        The episodes (files or mesh folders), in output order.
    options : ReadOptions
    references_path : str or None
        None: the shipped reference set.
    jobs : int
        Local processes (1: this process).
    dask : str or None
        A Dask scheduler's address (``tcp://host:8786``), or a ``distributed.Client``'s
        address; overrides ``jobs``.
    goal : GoalSpec or None
        Judge each episode's last frame against this goal (``dgli label --goal``).
    """

    paths: tuple[str, ...]
    options: ReadOptions = field(default_factory=ReadOptions)
    references_path: str | None = None
    jobs: int = 1
    dask: str | None = None
    goal: GoalSpec | None = None


def _tasks(job: LabelJob, workers: int) -> list[tuple[int, int, int]]:
    """(episode, part, parts): episodes split into parts when there are fewer episodes
    than workers, so that frames spread over them."""
    per = max(1, -(-workers // max(len(job.paths), 1)))
    return [(e, k, per) for e in range(len(job.paths)) for k in range(per)]


def _in_order(
    job: LabelJob, tasks: list[tuple[int, int, int]], results: Sequence[Any], get: Any
) -> Iterator[EpisodeLabels | EpisodeFailure]:
    """Episodes in input order from the results of ``tasks`` (``get`` waits for one)."""
    refs = cached_references(job.references_path)
    by_episode: dict[int, list[int]] = {}
    for i, (e, _, _) in enumerate(tasks):
        by_episode.setdefault(e, []).append(i)
    for e in range(len(job.paths)):
        yield assemble([get(results[i]) for i in by_episode[e]], refs, job.goal)


def _dask_client(address: str) -> Any:
    try:
        from distributed import Client
    except ImportError:
        raise InvalidInputError(
            "--dask needs the 'dask' extra: pip install 'dgli_vision[dask]'"
        ) from None
    try:
        return Client(address, timeout="10s", set_as_default=False)
    except (OSError, TimeoutError, ValueError) as exc:
        raise InvalidInputError(f"cannot reach the Dask scheduler '{address}': {exc}") from None


def label_episodes(job: LabelJob) -> Iterator[EpisodeLabels | EpisodeFailure]:
    """Label every episode of ``job``, yielding them in order.

    Raises
    ------
    InvalidInputError
        The Dask scheduler cannot be reached (or the extra is not installed).
    """
    if job.dask:
        client = _dask_client(job.dask)
        try:
            workers = max(1, sum(client.nthreads().values()))
            tasks = _tasks(job, workers)
            futures = [
                client.submit(
                    label_part, job.paths[e], job.options, job.references_path, k, n, pure=False
                )
                for e, k, n in tasks
            ]
            yield from _in_order(job, tasks, futures, lambda f: f.result())
        finally:
            client.close()
        return
    if job.jobs <= 1:
        tasks = _tasks(job, 1)
        yield from _in_order(
            job,
            tasks,
            tasks,
            lambda t: label_part(job.paths[t[0]], job.options, job.references_path, t[1], t[2]),
        )
        return
    import multiprocessing

    tasks = _tasks(job, job.jobs)
    ctx = multiprocessing.get_context("spawn")
    pool = ProcessPoolExecutor(max_workers=job.jobs, mp_context=ctx)
    try:
        futures: list[Future] = [
            pool.submit(label_part, job.paths[e], job.options, job.references_path, k, n)
            for e, k, n in tasks
        ]
        yield from _in_order(job, tasks, futures, lambda f: f.result())
    except BaseException:  # stopped (Ctrl-C, SIGTERM): drop the queued parts at once
        pool.shutdown(wait=False, cancel_futures=True)
        raise
    pool.shutdown()
