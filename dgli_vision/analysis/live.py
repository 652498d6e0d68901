"""Classify frames as they come, smoothed over time: the live loop of ``dgli watch``.

The capture thread takes frames from a source (a camera, or a recording played at its
recorded pace or as fast as it reads) and keeps only the newest one not yet taken; a
worker takes it, classifies it, and the state is smoothed online. A frame that arrives
while every worker is busy replaces the one waiting, which is *dropped* and counted: a
live system must not fall behind the scene it watches.

With ``jobs=1`` the worker is a thread of this process and the capture thread decodes
each frame while the worker classifies the one before. Python holds the GIL through
most of a classification, so decoding and classifying hardly overlap that way; with
``jobs=N`` the frames are classified in N worker processes (:class:`_ClassifierPool`),
each fed by a thread here, and sent as recorded (a bag's encoded images, a RealSense
frame's raw pixels through shared memory): decoding, aligning and classifying run in
the workers, side by side, and the answers are smoothed and reported in frame order.

The smoothing is :mod:`~dgli_vision.analysis.track`'s hidden Markov model run forward
(:class:`OnlineSmoother`): after each frame, the state at the end of the most likely
path so far. That is the state ``dgli track`` gives the last frame of the same frames;
earlier frames' states may still be revised by later evidence, which only the whole path
(:meth:`OnlineSmoother.path`, kept as back-pointers, 44 bytes a frame) settles.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..classifier.references import ReferenceSet
from ..core.classes import OUTSIDE
from ..core.errors import DgliError
from ..core.fold_graph import StateKey, folds_of, state_keys
from ..core.json_ready import json_ready
from ..core.why import OUTSIDE_KINDS
from .track import (
    EMISSION_SCALE,
    FOLD_PRIOR,
    STAY_PROBABILITY,
    state_costs,
    transition_log_matrix,
)

__all__ = [
    "LatestFrame",
    "LiveSummary",
    "LiveUpdate",
    "OnlineSmoother",
    "classify_live",
    "frame_points",
    "watch",
]


class OnlineSmoother:
    """The forward pass of :func:`~dgli_vision.analysis.track.viterbi`, one frame at a
    time.

    Parameters
    ----------
    references : ReferenceSet
        The references the frames' distances are to.
    stay : float, keyword-only
        :data:`~dgli_vision.analysis.track.STAY_PROBABILITY`.
    keep_path : bool, keyword-only
        Keep the back-pointers that settle the whole path (:meth:`path`); without them
        only the latest state is known (an endless stream).
    """

    def __init__(
        self,
        references: ReferenceSet,
        *,
        stay: float = STAY_PROBABILITY,
        keep_path: bool = True,
    ) -> None:
        self.references = references
        self.keys = state_keys()
        self.log_transition = transition_log_matrix(self.keys, stay=stay)
        self.prior = FOLD_PRIOR * np.array([len(folds_of(*k)) for k in self.keys])
        self.score: NDArray[np.float64] | None = None
        self.back: list[NDArray[np.int8]] = []
        self.keep_path = keep_path

    def update(self, distances: tuple[float, ...] | NDArray | None) -> StateKey:
        """Take one frame's distances to every reference (None or empty: a gap, no
        evidence) and return the state at the end of the most likely path so far."""
        n_s = len(self.keys)
        row = np.full((1, len(self.references)), np.nan)
        if distances is not None and len(distances) == len(self.references):
            row[0] = distances
        cost = state_costs(row, self.references, self.keys)[0] + self.prior
        if np.isfinite(cost).any():
            emit = np.where(np.isfinite(cost), -cost / EMISSION_SCALE, -1e6)
        else:
            emit = np.zeros(n_s)
        if self.score is None:
            self.score = emit - np.log(n_s)
        else:
            cand = self.score[:, None] + self.log_transition
            best = np.argmax(cand, axis=0)
            if self.keep_path:
                self.back.append(best.astype(np.int8))
            self.score = cand[best, np.arange(n_s)] + emit
        self.score = self.score - self.score.max()  # keeps the numbers small for hours
        return self.keys[int(np.argmax(self.score))]

    def path(self) -> list[StateKey]:
        """The most likely states of every frame taken so far (what ``dgli track`` gives
        the same frames); only the latest without ``keep_path``."""
        if self.score is None:
            return []
        if not self.keep_path:
            return [self.keys[int(np.argmax(self.score))]]
        state = int(np.argmax(self.score))
        out = [state]
        for back in reversed(self.back):
            state = int(back[state])
            out.append(state)
        return [self.keys[s] for s in reversed(out)]


class LatestFrame:
    """A slot holding the newest frame not yet taken: ``put`` replaces a waiting frame
    (counted in ``dropped``), ``take`` waits for one, ``done`` says the frame taken is
    finished. Thread-safe."""

    def __init__(self) -> None:
        self._cond = threading.Condition()
        self._item: Any = None
        self._full = False
        self._closed = False
        self._busy = False
        self.dropped = 0

    def put(self, item: Any, *, wait: bool = False) -> None:
        """Offer ``item``; a frame still waiting is dropped. With ``wait``, first wait
        until no frame is waiting (a recording played as fast as it is classified:
        nothing dropped; one frame waits, read and decoded while the one before it is
        classified)."""
        with self._cond:
            while wait and self._full and not self._closed:
                self._cond.wait(0.1)
            if self._full:
                self.dropped += 1
            self._item, self._full = item, True
            self._cond.notify_all()

    def close(self) -> None:
        """No more frames will come."""
        with self._cond:
            self._closed = True
            self._cond.notify_all()

    def take(self, timeout: float = 0.1) -> tuple[bool, Any]:
        """``(True, frame)``; ``(False, None)`` when none came within ``timeout`` or the
        source has ended (then :attr:`ended`)."""
        with self._cond:
            if not self._full and not self._closed:
                self._cond.wait(timeout)
            if not self._full:
                return False, None
            item, self._item, self._full = self._item, None, False
            self._busy = True
            return True, item

    def done(self) -> None:
        """The frame taken last is done (a waiting ``put`` goes on)."""
        with self._cond:
            self._busy = False
            self._cond.notify_all()

    @property
    def ended(self) -> bool:
        """The source has ended and its last frame was taken."""
        with self._cond:
            return self._closed and not self._full


@dataclass(frozen=True)
class LiveUpdate:
    """One classified frame of a live stream.

    Attributes
    ----------
    frame : int
        Its number in the stream (from 0, counting every frame that arrived).
    time : float or None
        Seconds from the first frame of the stream (the source's own clock).
    state : (str, str or None) or None
        The frame's own class and variant; None when it cannot tell (``note`` says why).
    smoothed : (str, str or None)
        The state at the end of the most likely path so far.
    confidence : float or None
    change : ((str, str or None), (str, str or None)) or None
        The smoothed state before and after, when it changed at this frame.
    dropped : int
        Frames dropped so far (arrived while another was being classified).
    latency_ms : float
        From the frame's arrival to its answer.
    note : str or None
        Why there is no state (cannot tell, or the error that made the frame unreadable).
    corners : dict or None
        The corners ``"A"``-``"D"`` as ``dgli classify --json`` gives them (point in the
        camera frame, pixel, state, graspable, placed_by); None for an unreadable frame.
    up : (float, float, float) or None
        The table's normal, camera frame.
    """

    frame: int
    time: float | None
    state: StateKey | None
    smoothed: StateKey
    confidence: float | None
    change: tuple[StateKey, StateKey] | None
    dropped: int
    latency_ms: float
    note: str | None = None
    corners: dict[str, Any] | None = None
    up: tuple[float, float, float] | None = None

    def to_json(self) -> dict[str, Any]:
        """The JSON line of the frame (docs/live.md)."""

        def state(key: StateKey | None) -> dict[str, Any] | None:
            return None if key is None else {"class": key[0], "variant": key[1]}

        return json_ready({
            "frame": self.frame,
            "time": None if self.time is None else round(self.time, 6),
            "state": state(self.state),
            "smoothed": state(self.smoothed),
            "confidence": None if self.confidence is None else round(self.confidence, 4),
            "change": None
            if self.change is None
            else {"from": state(self.change[0]), "to": state(self.change[1])},
            "dropped": self.dropped,
            "latency_ms": round(self.latency_ms, 2),
            "note": self.note,
            "corners": self.corners,
            "up": None if self.up is None else [round(v, 6) for v in self.up],
        })


@dataclass(frozen=True)
class LiveSummary:
    """What a live run did.

    Attributes
    ----------
    arrived : int
        Frames the source gave.
    skipped : int
        Left out by ``every`` (not dropped: never offered).
    classified : int
    dropped : int
        Offered while the worker was busy, and replaced by a newer frame.
    seconds : float
        Wall time from the first frame offered to the last answer.
    latency_ms : dict of str to float
        ``median``, ``p90`` and ``max`` of the classified frames' latencies.
    changes : list of (int, StateKey, StateKey)
        The online smoothed state's changes: frame, before, after.
    path : list of StateKey
        The most likely states of the classified frames, settled by all of them (what
        ``dgli track`` gives the same frames).
    frames : list of int
        The stream numbers of the classified frames (``path`` is theirs).
    stopped : bool
        Stopped by the caller (Ctrl-C) rather than by the end of the source.
    behind_s : float
        A recording played at its pace: how far the reading fell behind that pace at
        worst, seconds (0: every frame was offered on time).
    """

    arrived: int
    skipped: int
    classified: int
    dropped: int
    seconds: float
    latency_ms: dict[str, float]
    changes: list[tuple[int, StateKey, StateKey]] = field(default_factory=list)
    path: list[StateKey] = field(default_factory=list)
    frames: list[int] = field(default_factory=list)
    stopped: bool = False
    behind_s: float = 0.0

    def to_json(self) -> dict[str, Any]:
        """The summary's JSON object (the last line of ``dgli watch --jsonl``,
        ``{"summary": ...}``: docs/json.md)."""
        from dataclasses import asdict

        data = asdict(self)
        data["changes"] = [
            {"frame": f, "from": {"class": a[0], "variant": a[1]},
             "to": {"class": b[0], "variant": b[1]}}
            for f, a, b in self.changes
        ]
        data["path"] = [{"class": c, "variant": v} for c, v in self.path]
        return json_ready(data)


@dataclass(frozen=True)
class _Arrival:
    """A frame offered to the worker: its stream number, the frame (anything with
    ``load()`` and ``time``) and when it arrived (``time.perf_counter``)."""

    index: int
    pair: Any
    at: float


@dataclass(frozen=True)
class _Decoded:
    """A frame decoded by the capture thread (so that decoding the next frame overlaps
    classifying this one): ``load()`` gives the frame, or raises the error decoding it
    raised."""

    time: float | None
    frame: Any = None
    error: DgliError | None = None

    def load(self) -> Any:
        if self.error is not None:
            raise self.error
        return self.frame


def _decoded(pair: Any) -> _Decoded:
    """``pair`` loaded now (its error kept for the worker to report)."""
    t = getattr(pair, "time", None)
    try:
        return _Decoded(t, pair.load())
    except DgliError as exc:
        return _Decoded(t, error=exc)


def classify_live(
    pair: Any, references: ReferenceSet, colours: dict | None = None
) -> tuple[Any, Any, StateKey | None, float | None, tuple[float, ...], str | None]:
    """Classify one frame as ``dgli track`` does.

    Returns
    -------
    frame, result : RGBDFrame, FrameResult (None when unreadable)
    state : (class, variant) or None
    confidence : float or None
    distances : tuple of float
        To every reference; empty when the frame gives no evidence (a gap).
    note : str or None
        The reason there is no state, or the error.
    """
    from ..classifier.classify import reference_distances
    from ..classifier.pipeline import classify_frame

    try:
        frame = pair.load()
        result = classify_frame(frame, references, colours=colours)
    except DgliError as exc:
        return None, None, None, None, (), str(exc)
    guess = result.best_guess
    distances: tuple[float, ...] = ()
    if guess is not None:
        d = result.distances  # (the pipeline's own, when it ranked the references)
        if d is None:
            obs = result.observation
            d = reference_distances(result.coordinates, references, obs.classifier_evidence())
        distances = tuple(round(float(v), 6) for v in d)
    p = result.prediction
    state = (p.class_id, p.variant) if p is not None else None
    if result.why is not None and str(result.why) in OUTSIDE_KINDS:
        # in none of the twelve states: no evidence for one, and the frame's own answer
        state, distances = (OUTSIDE, None), ()
    confidence = guess.confidence if guess is not None else None
    return frame, result, state, confidence, distances, result.reason if p is None else None


def frame_points(result: Any) -> tuple[dict[str, Any] | None, tuple[float, ...] | None]:
    """A classified frame's corners (their JSON, as ``dgli classify --json`` has them)
    and the table's normal, for its live update; (None, None) without a result."""
    if result is None:
        return None, None
    aff = getattr(result, "affordances", None)
    corners = aff.to_json()["corners"] if aff is not None else None
    up = tuple(float(v) for v in result.observation.up)
    return corners, up


def _capture(
    frames: Iterable[Any],
    slot: LatestFrame,
    counts: dict[str, Any],
    *,
    every: int,
    realtime: bool,
    stop: threading.Event,
    prepare: Callable[[Any], Any] | None = None,
) -> None:
    """The capture thread: offer every ``every``-th frame to ``slot`` as it comes (at
    the recording's own pace with ``realtime``), until the source ends or ``stop``.
    Each frame is decoded here (its arrival is when the source gave it), on the other
    core while the worker classifies the one before: played as fast as it is
    classified, nothing waits for decoding; at the recorded pace (or from a camera) a
    frame that comes while the worker is busy is ready when the worker takes it (a
    frame dropped cost its decoding on this core, which the worker does not use).
    ``prepare`` replaces that decoding (worker processes: a frame they can read
    themselves travels as it is)."""
    prepare = prepare or _decoded
    start_wall = start_t = None
    try:
        for index, pair in enumerate(frames):
            if stop.is_set():
                break
            counts["arrived"] = index + 1
            t = getattr(pair, "time", None)
            if realtime and t is not None:
                if start_wall is None:
                    start_wall, start_t = time.perf_counter(), t
                wait = start_wall + (t - start_t) - time.perf_counter()
                if wait > 0 and stop.wait(wait):
                    break
                counts["behind"] = max(counts["behind"], -wait)  # reading slower than live
            if index % every:
                counts["skipped"] += 1
                continue
            at = time.perf_counter()
            if counts["first"] is None:
                counts["first"] = at
            slot.put(_Arrival(index, prepare(pair), at), wait=not realtime)
    except Exception as exc:  # the source failed part-way: the worker raises it
        counts["error"] = exc
    finally:
        close = getattr(frames, "close", None)
        if close is not None:  # a recording's reader lets its file go
            close()
        slot.close()


class _Worker:
    """The worker's state: the smoother, the changes and the latencies so far."""

    #: Latencies kept for the summary's percentiles (the last ones of a long run).
    KEEP_LATENCIES = 100_000

    def __init__(
        self, references: ReferenceSet, colours: dict | None, keep_path: bool
    ) -> None:
        self.references, self.colours = references, colours
        self.smoother = OnlineSmoother(references, keep_path=keep_path)
        self.keep_path = keep_path
        self.latencies: deque[float] = deque(maxlen=self.KEEP_LATENCIES)
        self.max_latency = 0.0
        self.changes: list[tuple[int, StateKey, StateKey]] = []
        self.frames: list[int] = []
        self.classified = 0
        self.last: StateKey | None = None

    def step(self, arrival: _Arrival, dropped: int) -> tuple[LiveUpdate, Any, Any]:
        """Classify one frame and smooth: its update, frame and result."""
        frame, result, state, conf, dist, note = classify_live(
            arrival.pair, self.references, self.colours
        )
        answer = (state, conf, dist, note, frame_points(result))
        return self.record(arrival, dropped, answer), frame, result

    def record(
        self,
        arrival: _Arrival,
        dropped: int,
        answer: tuple[Any, ...],
    ) -> LiveUpdate:
        """Smooth one frame's answer (state, confidence, distances, note and, when
        known, its corners and table normal: :func:`frame_points`), classified here or
        by a worker process, now: its update, latency measured to now."""
        state, conf, dist, note = answer[:4]
        corners, up = answer[4] if len(answer) > 4 else (None, None)
        smoothed = self.smoother.update(dist)
        if state is not None and state[0] == OUTSIDE:  # a "no known state" span, as it is
            smoothed = (OUTSIDE, None)
        change = None
        if self.last is not None and smoothed != self.last:
            change = (self.last, smoothed)
            self.changes.append((arrival.index, self.last, smoothed))
        self.last = smoothed
        self.classified += 1
        if self.keep_path:
            self.frames.append(arrival.index)
        latency = (time.perf_counter() - arrival.at) * 1e3
        self.latencies.append(latency)
        self.max_latency = max(self.max_latency, latency)
        t = getattr(arrival.pair, "time", None)
        return LiveUpdate(arrival.index, t, state, smoothed, conf, change, dropped, latency, note,
                          corners, up)

    def summary(self, counts: dict[str, Any], dropped: int, stopped: bool) -> LiveSummary:
        """What the run did."""
        seconds = time.perf_counter() - counts["first"] if counts["first"] else 0.0
        lat = np.array(self.latencies) if self.latencies else np.zeros(1)
        return LiveSummary(
            arrived=counts["arrived"],
            skipped=counts["skipped"],
            classified=self.classified,
            dropped=dropped,
            seconds=round(seconds, 3),
            latency_ms={
                "median": round(float(np.median(lat)), 2),
                "p90": round(float(np.percentile(lat, 90)), 2),
                "max": round(self.max_latency, 2),
            },
            changes=self.changes,
            path=self.smoother.path() if self.keep_path else [],
            frames=self.frames,
            stopped=stopped,
            behind_s=round(counts["behind"], 3),
        )


#: How long the live loop waits, when it ends, for the capture thread to stop its source
#: (a camera's pipeline, a recording's playback), s. A camera's driver waits up to 5 s
#: for a frame; the source is stopped before the process ends, or the SDK's own threads
#: abort it ("FATAL: exception not rethrown").
CAPTURE_STOP_S = 6.0


def watch(
    frames: Iterable[Any],
    references: ReferenceSet,
    *,
    every: int = 1,
    realtime: bool = False,
    colours: dict | None = None,
    on_update: Callable[[LiveUpdate, Any, Any], None] | None = None,
    stop: threading.Event | None = None,
    keep_path: bool = True,
    jobs: int = 1,
) -> LiveSummary:
    """Classify the frames of a source as they come, smoothed online.

    Parameters
    ----------
    frames : iterable
        Frames with ``load()`` (an ``RGBDFrame``) and ``time`` (seconds or None): a
        recording's frames, or a camera's (endless).
    references : ReferenceSet
    every : int, keyword-only
        Offer only every ``every``-th frame to the worker.
    realtime : bool, keyword-only
        Offer a recording's frames at the pace of their times (as a camera would);
        otherwise each as soon as the one before is done.
    colours : dict, keyword-only, optional
        Calibrated sticker colours.
    on_update : callable, keyword-only, optional
        Called in the worker after each frame with the :class:`LiveUpdate`, the
        ``RGBDFrame`` and the ``FrameResult`` (both None for an unreadable frame).
    stop : threading.Event, keyword-only, optional
        Set it to stop after the frame being classified (Ctrl-C).
    keep_path : bool, keyword-only
        Keep what settles the whole path (44 bytes a frame) for the summary; an endless
        camera keeps only the latest state.
    jobs : int, keyword-only
        1: classify in a thread of this process (``on_update`` gets the frame and its
        ``FrameResult``). More: in that many worker processes, each taking the newest
        frame when it is free, the answers smoothed in frame order (``on_update`` gets
        None for the frame and the result: they stay in the worker).

    Returns
    -------
    LiveSummary

    Raises
    ------
    DgliError
        The source failed part-way (after the frames before it were classified).
    """
    stop = stop or threading.Event()
    slot = LatestFrame()
    counts: dict[str, Any] = {
        "arrived": 0, "skipped": 0, "first": None, "error": None, "behind": 0.0
    }
    worker = _Worker(references, colours, keep_path)
    pool = _ClassifierPool(jobs, references, colours) if jobs > 1 else None
    capture = threading.Thread(
        target=_capture,
        args=(frames, slot, counts),
        kwargs={
            "every": every,
            "realtime": realtime,
            "stop": stop,
            "prepare": None if pool is None else _for_worker,
        },
        name="dgli-capture",
        daemon=True,  # a camera blocked in its driver never holds the process
    )
    if pool is not None:
        stopped = _run_in_pool(pool, capture, slot, worker, on_update, stop)
    else:
        stopped = _run_here(capture, slot, worker, on_update, stop)
    if isinstance(counts["error"], Exception) and not stopped:
        raise counts["error"]
    return worker.summary(counts, slot.dropped, stopped)


def _run_in_pool(
    pool: Any, capture: threading.Thread, slot: LatestFrame, worker: Any,
    on_update: Callable | None, stop: threading.Event,
) -> bool:
    """:func:`watch` with worker processes: the frames classified in ``pool`` and
    smoothed here, in frame order. Whether it was stopped."""
    try:
        capture.start()
        return pool.run(slot, worker, on_update, stop)
    finally:
        stop.set()
        slot.close()
        capture.join(timeout=CAPTURE_STOP_S)
        pool.close()


def _run_here(
    capture: threading.Thread, slot: LatestFrame, worker: Any,
    on_update: Callable | None, stop: threading.Event,
) -> bool:
    """:func:`watch` in this process: the newest frame classified each time the one
    before is done. Whether it was stopped."""
    capture.start()
    try:
        while not stop.is_set():
            got, arrival = slot.take()
            if not got:
                if slot.ended:
                    break
                continue
            update, frame, result = worker.step(arrival, slot.dropped)
            if on_update is not None:
                on_update(update, frame, result)
            slot.done()
        return stop.is_set()
    finally:  # also when on_update fails (a closed pipe): the source is let go first
        stop.set()
        slot.close()  # a capture waiting to offer a frame goes on, sees the stop
        capture.join(timeout=CAPTURE_STOP_S)


def _for_worker(pair: Any) -> Any:
    """What the capture thread offers a worker process: a frame it can read itself (a
    recording's encoded images, where they lie in its file) as it is; a frame only this
    process can read (the SDK's frames, ``local``) decoded now, unless its pixels can
    go as recorded (``portable``: aligned and classified by the worker)."""
    if getattr(pair, "local", False) and not getattr(pair, "portable", False):
        return _decoded(pair)
    return pair


@dataclass(frozen=True)
class _SlotFrame:
    """A decoded frame whose pixels wait in a shared slot (sent to a worker process
    without pickling them)."""

    time: float | None
    color: Any
    depth: Any
    shape: tuple[int, int]
    intrinsics: Any
    names: tuple[str, str, str]

    def load(self) -> Any:
        from ..core.frame import RGBDFrame

        h, w = self.shape
        color = np.frombuffer(self.color.view(), np.uint8).reshape(h, w, 3)
        depth = np.frombuffer(self.depth.view(), np.uint16).reshape(h, w)
        return RGBDFrame(color, depth, self.intrinsics, *self.names)


def _ship(pair: Any, slots: Any) -> tuple[Any, int | None]:
    """``pair`` as sent to a worker process, and the shared slot holding its pixels (to
    free once its answer is back; None: none used)."""
    shared = getattr(pair, "shared", None)
    if shared is not None:
        return shared(slots)
    frame = pair.frame if isinstance(pair, _Decoded) else None
    if frame is None or frame.color.dtype != np.uint8 or frame.depth_mm.dtype != np.uint16:
        return pair, None
    put = slots.put([np.ascontiguousarray(frame.color), np.ascontiguousarray(frame.depth_mm)])
    if put is None:
        return pair, None
    slot, (c, d) = put
    names = (frame.color_path, frame.depth_path, frame.intrinsics_source)
    return _SlotFrame(pair.time, c, d, frame.depth_mm.shape, frame.intrinsics, names), slot


def _serve(conn: Any, references: ReferenceSet, colours: dict | None) -> None:
    """A worker process: classify each frame it is sent (:func:`classify_live`) and send
    back its state, confidence, distances and note, until it is sent None."""
    from .workers import init_worker

    init_worker(references, colours)
    # what reading and classifying a frame imports, before the first frame comes
    from ..classifier import classify, pipeline  # noqa: F401
    from ..sources import realsense, recording  # noqa: F401

    conn.send("ready")
    while True:
        try:
            pair = conn.recv()
        except (EOFError, OSError):
            return
        if pair is None:
            return
        try:
            _, result, state, conf, dist, note = classify_live(pair, references, colours)
            conn.send(((state, conf, dist, note, frame_points(result)), None))
        except Exception as exc:  # not a frame's problem (those are notes): raised there
            conn.send((None, exc))


class _ClassifierPool:
    """``jobs`` worker processes classifying the frames of the live loop, each fed by a
    thread of this process: the thread takes the newest frame from the slot when its
    process is free, sends it (its pixels through shared memory) and waits for the
    answer (without the GIL); the answers are smoothed and reported in frame order, the
    latency measured when a frame's answer is reported."""

    #: Seconds a worker process is given to start (a new interpreter, the imports, the
    #: references) before the live loop gives up on it.
    START_S = 60.0

    def __init__(self, jobs: int, references: ReferenceSet, colours: dict | None) -> None:
        import multiprocessing as mp

        from ..core.parallel import SharedSlots, limit_library_threads

        limit_library_threads(1)
        ctx = mp.get_context("spawn")  # no fork: the SDK's and this process's threads
        self.conns: list[Any] = []
        self.procs: list[Any] = []
        for k in range(jobs):
            here, there = ctx.Pipe()
            proc = ctx.Process(
                target=_serve, args=(there, references, colours), name=f"dgli-watch-{k}",
                daemon=True,
            )
            proc.start()
            there.close()
            self.conns.append(here)
            self.procs.append(proc)
        for conn in self.conns:  # all started side by side; each says when it is ready
            try:
                ready = conn.poll(self.START_S) and conn.recv() == "ready"
            except (EOFError, OSError):  # it ended while starting
                ready = False
            if not ready:
                self.close()
                raise DgliError("a worker process of the live loop did not start")
        self.slots = SharedSlots(jobs)
        self.take_lock = threading.Lock()  # a frame taken and numbered at once
        self.slots_lock = threading.Lock()
        self.emit = threading.Condition()
        self.answers: dict[int, tuple[_Arrival, Any]] = {}
        self.taken = 0
        self.reported = 0
        self.error: BaseException | None = None

    def run(
        self,
        slot: LatestFrame,
        worker: _Worker,
        on_update: Callable[[LiveUpdate, Any, Any], None] | None,
        stop: threading.Event,
    ) -> bool:
        """Classify the frames offered to ``slot`` until it ends or ``stop``; whether
        stopped by the caller."""
        feeders = [
            threading.Thread(
                target=self._feed, args=(conn, slot, worker, on_update, stop),
                name=f"dgli-feed-{k}", daemon=True,
            )
            for k, conn in enumerate(self.conns)
        ]
        for t in feeders:
            t.start()
        try:
            for t in feeders:
                while t.is_alive():
                    t.join(0.1)
        except BaseException:
            stop.set()
            raise
        stopped = stop.is_set() and self.error is None
        if self.error is not None:
            raise self.error
        return stopped

    def _feed(
        self,
        conn: Any,
        slot: LatestFrame,
        worker: _Worker,
        on_update: Callable[[LiveUpdate, Any, Any], None] | None,
        stop: threading.Event,
    ) -> None:
        try:
            while not stop.is_set():
                with self.take_lock:
                    got, arrival = slot.take()
                    if got:
                        seq, self.taken = self.taken, self.taken + 1
                if not got:
                    if slot.ended:
                        return
                    continue
                slot.done()
                with self.slots_lock:
                    sent, used = _ship(arrival.pair, self.slots)
                try:
                    conn.send(sent)
                    answer, error = conn.recv()
                except (EOFError, OSError):
                    raise DgliError("a worker process of the live loop ended") from None
                finally:
                    if used is not None:
                        with self.slots_lock:
                            self.slots.release(used)
                if error is not None:
                    raise error
                self._report(seq, arrival, answer, slot, worker, on_update)
        except BaseException as exc:
            with self.emit:
                self.error = self.error or exc
            stop.set()

    def _report(
        self,
        seq: int,
        arrival: _Arrival,
        answer: Any,
        slot: LatestFrame,
        worker: _Worker,
        on_update: Callable[[LiveUpdate, Any, Any], None] | None,
    ) -> None:
        """Keep the answer; report every answer now next in frame order."""
        with self.emit:
            self.answers[seq] = (arrival, answer)
            while self.reported in self.answers:
                arr, ans = self.answers.pop(self.reported)
                self.reported += 1
                update = worker.record(arr, slot.dropped, ans)
                if on_update is not None:
                    on_update(update, None, None)

    def close(self) -> None:
        """Stop the worker processes and free the shared slots."""
        for conn in self.conns:
            try:
                conn.send(None)
            except (OSError, ValueError):
                pass
        for proc in self.procs:
            proc.join(timeout=2.0)
            if proc.is_alive():
                proc.terminate()
                proc.join(timeout=1.0)
        for conn in self.conns:
            conn.close()
        slots = getattr(self, "slots", None)
        if slots is not None:
            slots.close()
