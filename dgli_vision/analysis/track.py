"""A state timeline from the frames of a recording: per-frame verdicts smoothed in time.

Each frame gives its distance to every reference. A hidden Markov model over the states
(class and variant, :func:`~dgli_vision.core.fold_graph.state_keys`) turns them into the most
likely sequence of states (Viterbi): a state stays with high probability, and moves only
to a state one fold or one unfold away (:func:`~dgli_vision.core.fold_graph.neighbours`);
any other move costs :data:`JUMP_PROBABILITY`, so only many frames of clear evidence
make one. The evidence of a frame for a state is ``exp(-d / EMISSION_SCALE)``, ``d`` the
distance to that state's nearest reference; a frame that could not be read is a gap
(no evidence either way). A frame found in none of the twelve states ("no state fits",
"crumpled") is no evidence for any of them and stays what it is on the timeline: its
smoothed state is ``none``, never the neighbouring frames' state.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..classifier.references import ReferenceSet
from ..core.classes import OUTSIDE
from ..core.fold_graph import StateKey, folds_of, neighbours, state_keys
from ..core.json_ready import json_ready

__all__ = [
    "CHANGE_TOLERANCE",
    "EMISSION_SCALE",
    "FOLD_PRIOR",
    "JUMP_PROBABILITY",
    "STAY_PROBABILITY",
    "TIMELINE_COLUMNS",
    "Timeline",
    "TimelineFrame",
    "TimelineScore",
    "change_frames",
    "score_timeline",
    "smooth",
    "state_costs",
    "timeline_rows",
    "track_outcomes",
    "transition_log_matrix",
    "viterbi",
]

#: Probability that the state of one frame is the state of the next. Frames come from a
#: robot at work: most consecutive frames show the same state. With 0.97 a change costs
#: about 5 nats, so one frame alone (a flap seen edge-on, read as folded under) does not
#: make a change and come back, while two frames of clear evidence do.
STAY_PROBABILITY = 0.97
#: Probability of a move to a state that is not one fold or unfold away (frames lost, a
#: fold made between two frames): small enough that a single frame never makes one.
JUMP_PROBABILITY = 1e-9
#: Distance (Spearman + visibility and height terms) worth one nat of evidence. Right
#: answers are nearer than the runner-up by 0.05-0.3: a clear frame weighs 1-6 nats, a
#: frame whose best two references tie weighs nothing, and the last three or four frames
#: of a recording (a fold just laid flat) can make the change. (With 0.1, four frames of
#: a finished fold under three capture conditions at once could not; 0.05 once let one
#: confident wrong frame make a change and come back, before flaps held up were read.)
EMISSION_SCALE = 0.05
#: Cost (distance units) of each fold a state has, added to every frame's evidence: when
#: frames cannot tell two states apart (the stickers that differ are unknown, on a flap
#: held up), the one with fewer folds holds until the evidence shows the fold, as SPEC's
#: rule counts a fold only once it is past 90 degrees. Small against any real margin.
FOLD_PRIOR = 0.02
#: A detected state change counts as found within this many frames of a true one.
CHANGE_TOLERANCE = 2


def transition_log_matrix(
    keys: Sequence[StateKey] | None = None,
    *,
    stay: float = STAY_PROBABILITY,
    jump: float = JUMP_PROBABILITY,
) -> NDArray[np.float64]:
    """Log transition probabilities (S, S) between states, rows summing to 1.

    ``stay`` on the diagonal, the rest shared by the states one fold or unfold away,
    ``jump`` to every other state.
    """
    keys = list(keys or state_keys())
    index = {k: i for i, k in enumerate(keys)}
    n = len(keys)
    p = np.full((n, n), jump)
    for i, k in enumerate(keys):
        near = [index[m] for m in neighbours(k) if m in index]
        p[i, i] = stay
        if near:
            p[i, near] = (1.0 - stay - jump * (n - 1 - len(near))) / len(near)
        p[i] /= p[i].sum()
    return np.log(p)


def state_costs(
    distances: NDArray[np.float64],
    references: ReferenceSet,
    keys: Sequence[StateKey] | None = None,
) -> NDArray[np.float64]:
    """Per frame and state, the distance to the state's nearest reference, shape (T, S).

    Parameters
    ----------
    distances : ndarray, shape (T, K)
        Distance of every frame to every reference; a row of NaN is a gap.
    references : ReferenceSet
    keys : sequence of (class, variant), optional
        The states (default all).

    Returns
    -------
    ndarray, shape (T, S)
        NaN where a frame is a gap or a state has no reference.
    """
    keys = list(keys or state_keys())
    d = np.asarray(distances, dtype=np.float64)
    out = np.full((d.shape[0], len(keys)), np.nan)
    owner = [(r.class_id, r.variant) for r in references.references]
    for s, key in enumerate(keys):
        cols = [k for k, o in enumerate(owner) if o == key]
        if cols:
            block = d[:, cols]
            has = np.isfinite(block).any(axis=1)
            out[has, s] = np.nanmin(block[has], axis=1)
    return out


def viterbi(
    costs: NDArray[np.float64],
    log_transition: NDArray[np.float64],
    *,
    scale: float = EMISSION_SCALE,
) -> NDArray[np.intp]:
    """The most likely state path given per-frame costs (distances).

    Parameters
    ----------
    costs : ndarray, shape (T, S)
        Distance of each frame to each state; NaN rows are gaps; a NaN entry in a frame
        with evidence means the state has no reference (never chosen on evidence).
    log_transition : ndarray, shape (S, S)
    scale : float, keyword-only
        Distance worth one nat.

    Returns
    -------
    ndarray of int, shape (T,)
        State index per frame.
    """
    c = np.asarray(costs, dtype=np.float64)
    n_t, n_s = c.shape
    gap = ~np.isfinite(c).any(axis=1)
    emit = np.where(np.isfinite(c), -c / scale, -1e6)
    emit[gap] = 0.0
    score = emit[0] - np.log(n_s)
    back = np.zeros((n_t, n_s), dtype=np.intp)
    for t in range(1, n_t):
        cand = score[:, None] + log_transition  # from (rows) -> to (columns)
        back[t] = np.argmax(cand, axis=0)
        score = cand[back[t], np.arange(n_s)] + emit[t]
    path = np.zeros(n_t, dtype=np.intp)
    path[-1] = int(np.argmax(score))
    for t in range(n_t - 1, 0, -1):
        path[t - 1] = back[t, path[t]]
    return path


def smooth(
    distances: NDArray[np.float64],
    references: ReferenceSet,
    *,
    stay: float = STAY_PROBABILITY,
) -> tuple[list[StateKey], NDArray[np.float64]]:
    """The smoothed states of frames given their distances to every reference.

    Parameters
    ----------
    distances : ndarray, shape (T, K)
        Distance of every frame to every reference of ``references``; NaN rows are gaps.
    references : ReferenceSet
    stay : float, keyword-only
        :data:`STAY_PROBABILITY`.

    Returns
    -------
    states : list of (class, variant)
        One per frame.
    costs : ndarray, shape (T, S)
        Each frame's distance to each state (:func:`state_costs`), states in
        :func:`~dgli_vision.core.fold_graph.state_keys` order.
    """
    keys = state_keys()
    costs = state_costs(distances, references, keys)
    prior = FOLD_PRIOR * np.array([len(folds_of(*k)) for k in keys])
    path = viterbi(costs + prior[None, :], transition_log_matrix(keys, stay=stay))
    return [keys[p] for p in path], costs


def change_frames(labels: Sequence[object]) -> list[int]:
    """Frames whose label differs from the previous frame's."""
    return [k for k in range(1, len(labels)) if labels[k] != labels[k - 1]]


@dataclass(frozen=True)
class TimelineScore:
    """How a timeline compares with the true labels.

    Attributes
    ----------
    raw_accuracy, smoothed_accuracy : float
        Fraction of frames whose class is right, frame by frame and after smoothing (a
        frame without an answer counts as wrong).
    true_changes, found_changes : tuple of int
        Frames where the true and the smoothed class change.
    precision, recall : float
        Of the found changes, the share within :data:`CHANGE_TOLERANCE` frames of a
        true one (each true change matched once); of the true ones, the share found.
    """

    raw_accuracy: float
    smoothed_accuracy: float
    true_changes: tuple[int, ...]
    found_changes: tuple[int, ...]
    precision: float
    recall: float


def score_timeline(
    truth: Sequence[str],
    raw: Sequence[str | None],
    smoothed: Sequence[str],
    *,
    tolerance: int = CHANGE_TOLERANCE,
) -> TimelineScore:
    """Score raw and smoothed classes against the true ones (see :class:`TimelineScore`)."""
    truth, raw, smoothed = list(truth), list(raw), list(smoothed)
    n = max(len(truth), 1)
    true_changes = change_frames(truth)
    found = change_frames(smoothed)
    unmatched = list(true_changes)
    hits = 0
    for f in found:
        near = [t for t in unmatched if abs(t - f) <= tolerance]
        if near:
            unmatched.remove(min(near, key=lambda t: abs(t - f)))
            hits += 1
    precision = hits / len(found) if found else float(not true_changes)
    recall = hits / len(true_changes) if true_changes else float(not found)
    return TimelineScore(
        raw_accuracy=sum(r == t for r, t in zip(raw, truth)) / n,
        smoothed_accuracy=sum(s == t for s, t in zip(smoothed, truth)) / n,
        true_changes=tuple(true_changes),
        found_changes=tuple(found),
        precision=precision,
        recall=recall,
    )


@dataclass(frozen=True)
class TimelineFrame:
    """One frame of a timeline.

    Attributes
    ----------
    index : int
    color, depth : str
    time : float or None
        Seconds (``frames.csv``).
    raw_class, raw_variant : str or None
        The frame's own verdict (None: no answer, see ``note``).
    smoothed_class, smoothed_variant : str, str or None
        The state on the smoothed path.
    distance : float or None
        Distance of the frame to the smoothed state's nearest reference (None: a gap).
    confidence : float or None
        Confidence of the frame's own best match.
    note : str or None
        Why there is no raw verdict (cannot tell, or the error that made it a gap).
    label, label_variant : str or None
        The true state, when the recording is labelled.
    corners : dict or None
        The frame's corners A-D (point, pixel, state, graspable, placed_by), as
        ``dgli-classify --json`` gives them.
    folds : list or None
        The folds seen in the frame.
    """

    index: int
    color: str
    depth: str
    time: float | None
    raw_class: str | None
    raw_variant: str | None
    smoothed_class: str
    smoothed_variant: str | None
    distance: float | None
    confidence: float | None
    note: str | None
    label: str | None = None
    label_variant: str | None = None
    corners: dict | None = None
    folds: list | None = None

    @property
    def gap(self) -> bool:
        """The frame could not be read or had too little evidence."""
        return self.distance is None


@dataclass(frozen=True)
class Timeline:
    """A recording's smoothed state timeline.

    Attributes
    ----------
    frames : tuple of TimelineFrame
    changes : tuple of (int, StateKey, StateKey)
        Frame index and the states before and after, for every change of the smoothed
        state.
    score : TimelineScore or None
        With labels.
    """

    frames: tuple[TimelineFrame, ...]
    changes: tuple[tuple[int, StateKey, StateKey], ...]
    score: TimelineScore | None = None

    def to_json(self) -> dict[str, object]:
        """The JSON object of the timeline: frames, changes, gaps and the score (the keys of
        ``dgli track --json`` that a timeline gives, docs/json.md)."""
        from dataclasses import asdict

        out: dict[str, object] = {
            "frames": [asdict(f) for f in self.frames],
            "changes": [
                {
                    "frame": t,
                    "from": {"class": a[0], "variant": a[1]},
                    "to": {"class": b[0], "variant": b[1]},
                }
                for t, a, b in self.changes
            ],
            "gaps": [
                {"frame": f.index, "color": f.color, "why": f.note} for f in self.frames if f.gap
            ],
        }
        if self.score is not None:
            out["score"] = asdict(self.score)
        return json_ready(out)


def track_outcomes(
    outcomes: Sequence,
    references: ReferenceSet,
    *,
    times: Sequence[float | None] | None = None,
    labelled: bool = False,
    stay: float = STAY_PROBABILITY,
) -> Timeline:
    """Smooth per-frame outcomes into a timeline.

    Parameters
    ----------
    outcomes : sequence of PairOutcome
        In frame order, with ``distances`` to every reference
        (:func:`~dgli_vision.analysis.evaluate.evaluate_pairs` with ``distances=True``).
    references : ReferenceSet
        The references the distances are to.
    times : sequence of float or None, keyword-only, optional
    labelled : bool, keyword-only
        The outcomes' pair labels are true states: score the timeline.
    stay : float, keyword-only
        :data:`STAY_PROBABILITY`.

    Returns
    -------
    Timeline
        Without frames when there are no outcomes (a run stopped before its first frame).
    """
    if not len(outcomes):
        return Timeline((), ())
    keys = state_keys()
    k_refs = len(references)
    d = np.full((len(outcomes), k_refs), np.nan)
    for t, o in enumerate(outcomes):
        if len(o.distances) == k_refs and not getattr(o, "outside", False):
            d[t] = o.distances  # (a frame in none of the states is no evidence for one)
    states, costs = smooth(d, references, stay=stay)
    path = [keys.index(k) for k in states]
    times = list(times) if times is not None else [None] * len(outcomes)
    frames = []
    for t, (o, s) in enumerate(zip(outcomes, path)):
        cls, var = keys[s]
        dist = costs[t, s]
        if getattr(o, "outside", False):  # a "no known state" span, never smoothed over
            cls, var, dist = OUTSIDE, None, np.nan
        frames.append(
            TimelineFrame(
                index=t,
                color=o.pair.color,
                depth=o.pair.depth,
                time=times[t],
                raw_class=o.predicted,
                raw_variant=o.predicted_variant,
                smoothed_class=cls,
                smoothed_variant=var,
                distance=round(float(dist), 6) if np.isfinite(dist) else None,
                confidence=o.confidence,
                note=o.error or o.reason,
                label=o.pair.label if labelled else None,
                label_variant=o.pair.variant if labelled else None,
                corners=(o.affordances or {}).get("corners"),
                folds=(o.affordances or {}).get("folds"),
            )
        )
    shown = [(f.smoothed_class, f.smoothed_variant) for f in frames]
    changes = tuple(
        (t, shown[t - 1], shown[t]) for t in range(1, len(shown)) if shown[t] != shown[t - 1]
    )
    score = None
    if labelled:
        score = score_timeline(
            [f.label or "" for f in frames],
            [f.raw_class for f in frames],
            [f.smoothed_class for f in frames],
        )
    return Timeline(tuple(frames), changes, score)


#: Columns of a timeline's CSV file.
TIMELINE_COLUMNS = (
    "frame",
    "color",
    "time",
    "raw_class",
    "raw_variant",
    "smoothed_class",
    "smoothed_variant",
    "distance",
    "confidence",
    "label",
    "label_variant",
    "note",
)


def timeline_rows(timeline: Timeline) -> list[tuple[object, ...]]:
    """One row per frame, in the order of :data:`TIMELINE_COLUMNS` (empty for None)."""

    def cell(v: object) -> object:
        return "" if v is None else v

    return [
        tuple(
            cell(v)
            for v in (
                f.index,
                f.color,
                f.time,
                f.raw_class,
                f.raw_variant,
                f.smoothed_class,
                f.smoothed_variant,
                f.distance,
                f.confidence,
                f.label,
                f.label_variant,
                f.note,
            )
        )
        for f in timeline.frames
    ]
