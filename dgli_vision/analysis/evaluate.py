"""Batch evaluation of labelled folders: parallel, streaming, and robust to bad pairs.

Each pair is read and classified in a worker process; only a small record comes back
(no images), so memory stays flat in the number of pairs. A pair that cannot be read is
recorded as a failure with its one-line error and the run goes on.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from functools import partial
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..classifier.references import ReferenceSet
from ..core.classes import OUTSIDE, VARIANTS
from ..core.errors import DgliError, InvalidValueError
from ..core.json_ready import json_ready
from ..core.why import OUTSIDE_KINDS
from ..sources.labelled import LabelledPair
from .workers import init_worker, worker_references

__all__ = [
    "SPLIT_COLUMNS",
    "EvaluationResult",
    "PairOutcome",
    "accuracy_answered",
    "adopt_workers",
    "coordinate_matrix",
    "counts_text",
    "coverage",
    "evaluate_pairs",
    "failure_text",
    "outcome_counts",
    "outcome_fields",
    "outcome_from_dict",
    "outcomes_text",
    "summarise",
]


@dataclass(frozen=True)
class PairOutcome:
    """What happened to one pair.

    ``error`` is set when it could not be read (a failure); ``predicted`` is None when
    it was read but no class could be given (``reason``).
    """

    pair: LabelledPair
    predicted: str | None = None
    predicted_variant: str | None = None
    distance: float | None = None
    runner_up: str | None = None
    runner_up_distance: float | None = None
    coordinates: tuple[float, ...] = ()
    centroids: tuple[tuple[float, float], ...] = ()
    reason: str | None = None
    error: str | None = None
    confidence: float | None = None
    distances: tuple[float, ...] = ()
    affordances: dict[str, Any] | None = None
    why: str | None = None

    @property
    def outside(self) -> bool:
        """Read and found in none of the twelve states ("no state fits", "crumpled")."""
        return self.error is None and self.why in OUTSIDE_KINDS

    @property
    def correct(self) -> bool:
        """Class predicted right; for a pair labelled ``none`` (a state outside the
        twelve), read and given no class."""
        if self.pair.label == OUTSIDE:
            return self.predicted is None and self.error is None
        return self.predicted == self.pair.label

    def to_json(self) -> dict[str, Any]:
        """The JSON object of the outcome (one line of ``results.jsonl``); a coordinate
        that was not measured (NaN) is null. :func:`outcome_from_dict` reads it back."""
        from dataclasses import asdict

        return json_ready(asdict(self))

    @property
    def variant_correct(self) -> bool:
        """Class and variant predicted right."""
        return self.correct and self.predicted_variant == self.pair.variant


def _internal_error(name: str, exc: Exception) -> str:
    """The one line a frame that met a bug of this tool gets in a batch's report: the
    frame, the exception, and what to do.

    Parameters
    ----------
    name : str
        The frame (its colour image's name).
    exc : Exception

    Returns
    -------
    str
    """
    what = f"{type(exc).__name__}: {exc}".strip().splitlines()[0]
    return f"{name}: internal error ({what}); please report it with this frame"


def _classify_pair(
    pair: LabelledPair,
    refs: ReferenceSet | None = None,
    colours: dict | None = None,
    distances: bool = False,
) -> PairOutcome:
    from ..classifier.classify import reference_distances
    from ..classifier.pipeline import classify_frame

    if refs is None:
        refs, colours = worker_references()
    if refs is None:
        raise RuntimeError("worker started without references (pool initializer not run)")
    try:
        frame = pair.load()  # one thread: one pair per core
        result = classify_frame(frame, refs, colours=colours)
    except Exception as exc:  # a bug met on one frame too: the batch (a robot's run) goes on
        what = str(exc) if isinstance(exc, DgliError) else _internal_error(pair.color, exc)
        where = f" (labels.csv line {pair.line})" if pair.line is not None else ""
        return PairOutcome(pair.light(), error=f"{what}{where}")
    p = result.prediction
    coords = tuple(float(v) for v in result.coordinates)
    cents = tuple((float(u), float(v)) for u, v in result.detections.centroids)
    dist: tuple[float, ...] = ()
    if distances and result.best_guess is not None:  # to every reference, for tracking
        d = result.distances
        if d is None:
            obs = result.observation
            d = reference_distances(result.coordinates, refs, obs.classifier_evidence())
        dist = tuple(round(v, 6) for v in np.asarray(d, dtype=np.float64).tolist())
    guess = result.best_guess
    confidence = guess.confidence if guess is not None else None
    aff = result.affordances.to_json() if result.affordances is not None else None
    if p is None:
        return PairOutcome(
            pair.light(),
            coordinates=coords,
            centroids=cents,
            reason=result.reason,
            confidence=confidence,
            distances=dist,
            affordances=aff,
            why=None if result.why is None else str(result.why),
        )
    return PairOutcome(
        pair.light(),
        p.class_id,
        p.variant,
        p.distance,
        p.runner_up.class_id if p.runner_up else None,
        p.runner_up.distance if p.runner_up else None,
        coords,
        cents,
        confidence=confidence,
        distances=dist,
        affordances=aff,
    )


def evaluate_pairs(
    pairs: Iterable[LabelledPair],
    references: ReferenceSet,
    *,
    jobs: int = 1,
    on_progress: Callable[[int], None] | None = None,
    colours: dict | None = None,
    distances: bool = False,
) -> Iterator[PairOutcome]:
    """Classify labelled pairs, in input order, with ``jobs`` worker processes.

    Parameters
    ----------
    pairs : iterable of LabelledPair
        Taken one at a time, as the work goes (a recording's frames are read as they are
        classified, never all held).
    references : ReferenceSet
    jobs : int, keyword-only
        Worker processes; 1 runs in this process.
    on_progress : callable, keyword-only
        Called with 1 after each pair (for a progress bar).
    colours : dict, keyword-only, optional
        Calibrated sticker colours (``dgli calibrate``).
    distances : bool, keyword-only
        Keep each pair's distance to every reference (``PairOutcome.distances``), the
        evidence :mod:`dgli_vision.analysis.track` smooths over time.

    Yields
    ------
    PairOutcome
        One per pair, in the order of ``pairs``.
    """
    if jobs < 1:
        raise InvalidValueError(f"jobs must be at least 1, got {jobs}")
    if jobs == 1:
        for pair in pairs:
            yield _classify_pair(pair, references, colours, distances)
            if on_progress:
                on_progress(1)
        return
    for outcome in _shared_work(pairs, references, jobs, colours, distances):
        yield outcome
        if on_progress:
            on_progress(1)


_POOL: tuple[tuple, ProcessPoolExecutor] | None = None


def _worker_pool(
    workers: int, references: ReferenceSet, colours: dict | None
) -> ProcessPoolExecutor:
    """The worker processes, kept between calls with the same references and colours
    (a robustness run or a program classifying batch after batch starts them once)."""
    global _POOL
    # the set itself, not its id: compared by identity, and kept alive while in use
    key = (workers, references, None if colours is None else tuple(sorted(colours.items())))
    if _POOL is not None and _POOL[0] == key:
        return _POOL[1]
    _shutdown_pool()
    import atexit
    import multiprocessing as mp

    from ..core.parallel import limit_library_threads

    limit_library_threads()  # one thread per library in each worker (one per core)
    # Spawned, not forked: the parent may hold OpenCV, Open3D or decoding threads, and a
    # forked child inherits their locks.
    pool = ProcessPoolExecutor(
        workers,
        mp_context=mp.get_context("spawn"),
        initializer=init_worker,
        initargs=(references, colours),
    )
    if _POOL is None:
        atexit.register(_shutdown_pool)
    _POOL = (key, pool)
    return pool


def adopt_workers(
    jobs: int, references: ReferenceSet, colours: dict | None, references_path: str | None
) -> None:
    """Make the workers :func:`~dgli_vision.analysis.workers.start_workers_early` started
    with ``references_path`` and ``colours`` those that :func:`evaluate_pairs` with
    ``jobs`` and ``references`` (loaded from that file) uses; nothing when none were."""
    global _POOL
    from .workers import take_early_workers

    pool = take_early_workers(jobs - 1, references_path, colours)
    if pool is None:
        return
    first = _POOL is None
    _shutdown_pool()
    if first:
        import atexit

        atexit.register(_shutdown_pool)
    key = (jobs - 1, references, None if colours is None else tuple(sorted(colours.items())))
    _POOL = (key, pool)


def _shutdown_pool() -> None:
    global _POOL
    if _POOL is not None:
        _POOL[1].shutdown(wait=True, cancel_futures=True)
        _POOL = None


def _shared_work(
    pairs: Iterable[LabelledPair],
    references: ReferenceSet,
    jobs: int,
    colours: dict | None,
    distances: bool,
) -> Iterator[PairOutcome]:
    """Outcomes in input order from ``jobs - 1`` worker processes and this process.

    This process classifies pairs too, from the first moment: the workers take a few
    tenths of a second to start (spawn, imports, references), during which it is already
    at work, and there is one process per core, not one more. The workers stay up for the
    next call (:func:`_worker_pool`); each is kept a few pairs ahead so that it never
    waits for this process.
    """
    from concurrent.futures import FIRST_COMPLETED, Future, wait

    import cv2

    from ..core.parallel import SharedSlots

    pool = _worker_pool(jobs - 1, references, colours)
    work = partial(_classify_pair, distances=distances)
    ahead = 6 * (jobs - 1)  # pairs handed to workers and not back yet, at most
    slots = SharedSlots(ahead)  # a recording's pixels go through shared memory
    slot_of: dict[int, int] = {}
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)  # one process per core, this one included
    todo = iter(pairs)  # taken one at a time: a recording is read as it is classified
    done: dict[int, PairOutcome] = {}
    pending: dict[Future, int] = {}
    mine: dict[int, LabelledPair] = {}  # handed to a worker, kept in case it is taken back
    handed, given, more = 0, 0, True  # next index to hand out; next to yield
    try:
        while more or given < handed:
            while more and len(pending) < ahead:
                pair = next(todo, None)
                if pair is None:
                    more = False
                    break
                pending[pool.submit(work, _to_slot(pair, slots, slot_of, handed))] = handed
                mine[handed] = pair
                handed += 1
            for future in [f for f in pending if f.done()]:
                index = pending.pop(future)
                _free_slot(slots, slot_of, index)
                done[index] = future.result()
                del mine[index]
            while given in done:
                yield done.pop(given)
                given += 1
            pair = next(todo, None) if more else None
            if pair is not None:
                done[handed] = _classify_pair(pair, references, colours, distances)
                handed += 1
                continue
            more = False
            if pending and given not in done:
                stolen = _take_back(pending)
                if stolen is None:
                    wait(pending, return_when=FIRST_COMPLETED)
                else:  # the tail: a waiting worker pair is done here rather than idling
                    _free_slot(slots, slot_of, stolen)
                    pair = mine.pop(stolen)
                    done[stolen] = _classify_pair(pair, references, colours, distances)
    finally:  # also on Ctrl-C or when the caller stops early: drop what has not started
        cv2.setNumThreads(threads)
        for future in pending:
            future.cancel()
        wait(pending)
        slots.close()


def _to_slot(pair: Any, slots: Any, slot_of: dict[int, int], index: int) -> Any:
    """What to send a worker for ``pair``: a recorded frame with its pixels in a shared
    slot (its slot kept in ``slot_of``), anything else as it is."""
    if not hasattr(pair, "shared"):
        return pair
    sent, slot = pair.shared(slots)
    if slot is not None:
        slot_of[index] = slot
    return sent


def _free_slot(slots: Any, slot_of: dict[int, int], index: int) -> None:
    slot = slot_of.pop(index, None)
    if slot is not None:
        slots.release(slot)


def _take_back(pending: dict) -> int | None:
    """Cancel the last-handed pair no worker has started, and return its index (None if
    every pending pair is already running): at the end of a batch this process takes the
    queued pairs back instead of waiting for one worker to work through them alone."""
    for future, index in sorted(pending.items(), key=lambda item: -item[1]):
        if future.cancel():
            del pending[future]
            return index
    return None


@dataclass(frozen=True)
class EvaluationResult:
    """The summary of DESIGN.md's ``dgli evaluate --json`` plus the outcomes."""

    n: int
    classified: int
    accuracy: float
    variant_accuracy: float | None
    labels: list[str]
    confusion: list[list[int]]
    per_class: dict[str, dict[str, float]]
    failures: list[dict[str, str]]
    seconds: float
    outcomes: list[PairOutcome] = field(default_factory=list, repr=False)
    cannot_tell: list[dict[str, str]] = field(default_factory=list)

    def variant_accuracy_text(self) -> str:
        """Variant accuracy as a percentage, or ``n/a`` when no variant is known."""
        return "n/a" if self.variant_accuracy is None else f"{self.variant_accuracy:.2%}"

    @property
    def outcome_counts(self) -> dict[str, int]:
        """Pairs answered right, answered "cannot tell", answered wrong, and not read
        (:func:`outcome_counts`)."""
        return outcome_counts(self.outcomes)

    @property
    def coverage(self) -> float | None:
        """Share of the pairs read that got a class (None when none was read)."""
        return coverage(self.outcome_counts)

    @property
    def accuracy_answered(self) -> float | None:
        """Class accuracy over the pairs that got a class (None when none did)."""
        return accuracy_answered(self.outcome_counts)

    def confusion_split(self) -> list[list[int]]:
        """The rows of ``confusion`` with its last column (``"none"``) split in two:
        answered "cannot tell", and not read (the columns of :data:`SPLIT_COLUMNS`)."""
        index = {c: k for k, c in enumerate(self.labels)}
        rows = [[*row[:-1], 0, 0] for row in self.confusion]
        for o in self.outcomes:
            if o.predicted is None and not o.correct:
                rows[index[o.pair.label]][-2 if o.error is None else -1] += 1
        return rows

    def outcomes_text(self) -> str:
        """``"right 40, cannot tell 7, wrong 1, unreadable 0; ..."`` for people."""
        return outcomes_text(self.outcome_counts)

    def to_json(self) -> dict[str, Any]:
        """The JSON object of ``dgli evaluate --json`` (outcomes left out)."""
        return json_ready({
            "n": self.n,
            "classified": self.classified,
            "accuracy": self.accuracy,
            "variant_accuracy": self.variant_accuracy,
            "labels": self.labels,
            "confusion": self.confusion,
            "per_class": self.per_class,
            "failures": self.failures,
            "cannot_tell": self.cannot_tell,
            "seconds": self.seconds,
            **outcome_fields(self.outcome_counts),
        })


#: The last two columns of :meth:`EvaluationResult.confusion_split`, after the classes.
SPLIT_COLUMNS = ("cannot tell", "not read")


def outcome_counts(outcomes: Iterable[PairOutcome]) -> dict[str, int]:
    """Pairs answered right, answered "cannot tell", answered wrong, and not read.

    "Cannot tell" is an answer, not a failure: a robot acts on it by looking again.
    The pairs' labels are the truth (every pair must have one).
    """
    outs = list(outcomes)
    return {
        "right": sum(o.error is None and o.correct for o in outs),
        "cannot_tell": sum(
            o.error is None and o.predicted is None and o.pair.label != OUTSIDE for o in outs
        ),
        "wrong": sum(o.predicted is not None and not o.correct for o in outs),
        "unreadable": sum(o.error is not None for o in outs),
    }


def coverage(counts: dict[str, int]) -> float | None:
    """Share of the pairs read that got a class, of :func:`outcome_counts` (None when
    none was read), to four decimals."""
    read = counts["right"] + counts["cannot_tell"] + counts["wrong"]
    return round((counts["right"] + counts["wrong"]) / read, 4) if read else None


def accuracy_answered(counts: dict[str, int]) -> float | None:
    """Class accuracy over the pairs that got a class, of :func:`outcome_counts` (None
    when none did), to four decimals."""
    answered = counts["right"] + counts["wrong"]
    return round(counts["right"] / answered, 4) if answered else None


def outcome_fields(counts: dict[str, int]) -> dict[str, Any]:
    """The JSON fields of the three outcomes: ``"outcomes"`` (right, cannot_tell, wrong,
    unreadable), ``"coverage"`` and ``"accuracy_answered"``."""
    return {
        "outcomes": dict(counts),
        "coverage": coverage(counts),
        "accuracy_answered": accuracy_answered(counts),
    }


def counts_text(counts: dict[str, int]) -> str:
    """``"40 right, 7 cannot tell, 1 wrong, 0 unreadable"``: the four outcomes apart."""
    return (
        f"{counts['right']} right, {counts['cannot_tell']} cannot tell, {counts['wrong']} "
        f"wrong, {counts.get('unreadable', 0)} unreadable"
    )


def outcomes_text(counts: dict[str, int], unit: str = "pairs") -> str:
    """``"right 40, cannot tell 7, wrong 1, unreadable 0; answered 98% of the pairs
    read, 97.92% of the answers right"`` for people (``unit``: what was read, "pairs"
    or a recording's "frames")."""
    cov, acc = coverage(counts), accuracy_answered(counts)
    cov_text = "n/a" if cov is None else f"{cov:.0%}"
    acc_text = "n/a" if acc is None else f"{acc:.2%}"
    return (
        f"right {counts['right']}, cannot tell {counts['cannot_tell']}, wrong "
        f"{counts['wrong']}, unreadable {counts.get('unreadable', 0)}; answered {cov_text} "
        f"of the {unit} read, {acc_text} of the answers right"
    )


NO_CLASS = "none"


def _float(v: Any) -> float:
    return float("nan") if v is None else float(v)


def outcome_from_dict(data: dict[str, Any]) -> PairOutcome:
    """The outcome of :meth:`PairOutcome.to_json`.

    Raises
    ------
    ValueError, KeyError, TypeError
        Malformed data.
    """
    pair = LabelledPair(**data["pair"])
    return PairOutcome(
        pair,
        data.get("predicted"),
        data.get("predicted_variant"),
        data.get("distance"),
        data.get("runner_up"),
        data.get("runner_up_distance"),
        tuple(_float(v) for v in data.get("coordinates") or ()),
        tuple((_float(u), _float(v)) for u, v in data.get("centroids") or ()),
        data.get("reason"),
        data.get("error"),
        data.get("confidence"),
        tuple(_float(v) for v in data.get("distances") or ()),
        data.get("affordances"),
        data.get("why"),
    )


def summarise(outcomes: Iterable[PairOutcome], seconds: float) -> EvaluationResult:
    """Metrics of a set of outcomes.

    Accuracy is over all pairs (a failure or a pair without a class counts as wrong).
    Variant accuracy is over the pairs whose true variant is known: labelled with one, or
    of a class without variants (class folders carry no variant); None if there are none.
    The confusion matrix has true labels as rows and predictions as columns, over
    ``labels`` (every class seen as truth or prediction, sorted) plus a last column
    ``"none"`` for pairs that failed or got no class.
    """
    outs = list(outcomes)
    n = len(outs)
    with_variant = [o for o in outs if o.pair.variant or VARIANTS.get(o.pair.label) == (None,)]
    labels = sorted({o.pair.label for o in outs} | {o.predicted for o in outs if o.predicted})
    index = {c: k for k, c in enumerate(labels)}
    conf = np.zeros((len(labels), len(labels) + 1), dtype=int)
    for o in outs:
        # (a state outside the twelve given no class is the diagonal: right)
        col = index[o.predicted] if o.predicted else (
            index[OUTSIDE] if o.correct else len(labels)
        )
        conf[index[o.pair.label], col] += 1
    per_class = {}
    for c, k in index.items():
        tp = int(conf[k, k])
        predicted = int(conf[:, k].sum())
        support = int(conf[k].sum())
        precision = tp / predicted if predicted else 0.0
        recall = tp / support if support else 0.0
        f1 = 2 * precision * recall / (precision + recall) if precision + recall else 0.0
        per_class[c] = {
            "precision": round(precision, 4),
            "recall": round(recall, 4),
            "f1": round(f1, 4),
            "support": support,
        }
    return EvaluationResult(
        n=n,
        classified=sum(o.predicted is not None for o in outs),
        accuracy=round(sum(o.correct for o in outs) / n, 4) if n else 0.0,
        variant_accuracy=(
            round(sum(o.variant_correct for o in with_variant) / len(with_variant), 4)
            if with_variant
            else None
        ),
        labels=labels,
        confusion=conf.tolist(),
        per_class=per_class,
        failures=[
            {"color": o.pair.color, "depth": o.pair.depth, "error": failure_text(o)}
            for o in outs
            if o.error is not None or (o.predicted is not None and not o.correct)
        ],
        seconds=round(seconds, 3),
        outcomes=outs,
        cannot_tell=[
            {"color": o.pair.color, "depth": o.pair.depth, "reason": o.reason or ""}
            for o in outs
            if o.error is None and o.predicted is None and not o.correct
        ],
    )


def failure_text(outcome: PairOutcome) -> str:
    """Why a pair is a failure: its read error, or ``"wrong: labelled 02, answered 05"``
    for a wrong class (an empty string for a pair that is not a failure)."""
    if outcome.error is not None:
        return outcome.error
    if outcome.predicted is not None and not outcome.correct:
        return f"wrong: labelled {outcome.pair.label}, answered {outcome.predicted}"
    return ""


def coordinate_matrix(outcomes: list[PairOutcome]) -> NDArray[np.float64]:
    """Coordinates (n, 28) of the outcomes that have them (NaN rows otherwise)."""
    return np.array(
        [o.coordinates if o.coordinates else (np.nan,) * 28 for o in outcomes], dtype=float
    )


def pair_key(pair: Any) -> tuple[str, str]:
    """A pair's colour and depth files by their real paths: the same pair however named."""
    import os

    # realpath, not Path.resolve: a symbolic link loop is the pair's read error, not a crash
    return os.path.realpath(pair.color), os.path.realpath(pair.depth)


def outcomes_of(items: list, pairs: list | None) -> dict[tuple[str, str], PairOutcome]:
    """Outcomes of ``pairs`` (None: any) among the objects of a results.jsonl (others
    left out), by pair (:func:`pair_key`)."""
    wanted = None if pairs is None else {pair_key(p) for p in pairs}
    done = {}
    for item in items:
        try:
            outcome = outcome_from_dict(item)
        except (KeyError, TypeError, ValueError):
            continue
        if wanted is None or pair_key(outcome.pair) in wanted:
            done[pair_key(outcome.pair)] = outcome
    return done
