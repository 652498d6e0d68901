"""The robustness table: for each capture condition, how often the answer is right, an
honest "cannot tell", or wrong; and the reliability table: how often the best guess is
right at each level of confidence, over all conditions.

Each condition renders its own fresh labelled pairs in memory
(:func:`dgli_vision.sim.dataset.render_samples` with that condition) and classifies them with
the full pipeline. Pairs are spread over worker processes, one condition at a time.
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from itertools import pairwise

import numpy as np
from numpy.typing import NDArray

from ..classifier.references import ReferenceSet
from ..core.classes import CLASS_IDS
from .evaluate import outcome_fields

__all__ = [
    "OVERLAY_WIDTH",
    "RELIABILITY_BINS",
    "ConditionScore",
    "ShownPair",
    "reliability_rows",
    "reliability_table",
    "robustness_table",
    "score_condition",
]

#: Lower edges of the confidence bins of the reliability table (the last bin ends at 1,
#: inclusive); 0.25 is the threshold below which the answer is "cannot tell".
RELIABILITY_BINS: tuple[float, ...] = (0.0, 0.1, 0.25, 0.5, 0.75)


#: Width in pixels of the overlays a robustness report keeps (a report of hundreds of
#: pairs stays a few tens of megabytes).
OVERLAY_WIDTH = 640


@dataclass(frozen=True, eq=False)
class ShownPair:
    """A pair a robustness report shows: answered wrong or "cannot tell".

    Attributes
    ----------
    name : str
        The sample's name (``02_003``).
    drawn : tuple of str
        The conditions drawn for it.
    truth : str
        ``class/variant``.
    answer : str or None
        ``class/variant`` answered (None: cannot tell).
    reason : str or None
        Why it could not tell.
    overlay : ndarray of uint8, shape (h, OVERLAY_WIDTH, 3), optional
        BGR overlay of the pair with its verdict.
    """

    name: str
    drawn: tuple[str, ...]
    truth: str
    answer: str | None
    reason: str | None = None
    overlay: NDArray[np.uint8] | None = field(default=None, repr=False)

    @property
    def kind(self) -> str:
        """``"wrong"`` or ``"cannot tell"``."""
        return "cannot tell" if self.answer is None else "wrong"


@dataclass(frozen=True)
class ConditionScore:
    """Outcomes under one condition.

    Attributes
    ----------
    condition : str
    n : int
        Pairs rendered.
    right, abstained, wrong : int
        Class right; no class given (exit 1); a wrong class.
    variant_right : int
        Class and variant right.
    wrong_cases : tuple of str
        ``name: true -> predicted`` for each wrong answer.
    guesses : tuple of (float, bool)
        Confidence of each pair's best guess, given or not (below the threshold it
        became "cannot tell"), and whether its class was right; pairs without any guess
        (too few stickers) are left out.
    subset : bool
        The row is a part of another condition's pairs (``combo with gripper``).
    shown : tuple of ShownPair
        The pairs answered wrong or "cannot tell", with their overlays, when asked for
        (:func:`score_condition` with ``overlays``).
    """

    condition: str
    n: int
    right: int
    abstained: int
    wrong: int
    variant_right: int
    wrong_cases: tuple[str, ...] = ()
    guesses: tuple[tuple[float, bool], ...] = ()
    subset: bool = False
    shown: tuple[ShownPair, ...] = field(default=(), compare=False, repr=False)

    @property
    def outcome_counts(self) -> dict[str, int]:
        """Right, "cannot tell", wrong and unreadable (a render is always read)."""
        return {
            "right": self.right,
            "cannot_tell": self.abstained,
            "wrong": self.wrong,
            "unreadable": 0,
        }

    def to_json(self) -> dict[str, object]:
        """The JSON row: counts, and each as a fraction of the pairs (numbers, not text),
        and the three outcomes as every command gives them (``"outcomes"``,
        ``"coverage"``, ``"accuracy_answered"``)."""
        counts = {
            "right": self.right,
            "cannot_tell": self.abstained,
            "wrong": self.wrong,
            "class_variant_right": self.variant_right,
        }
        return {
            "condition": self.condition,
            "pairs": self.n,
            **counts,
            "fractions": {
                k: (round(v / self.n, 4) if self.n else None) for k, v in counts.items()
            },
            **outcome_fields(self.outcome_counts),
        }

    def to_row(self) -> list[str]:
        """Markdown row: condition, n, right, cannot tell, wrong, variant right, answered
        (coverage), right of the answers."""

        def pct(k: int) -> str:
            return f"{100 * k / self.n:.0f}%" if self.n else "-"

        fields = outcome_fields(self.outcome_counts)
        cov, acc = fields["coverage"], fields["accuracy_answered"]
        return [
            self.condition,
            str(self.n),
            pct(self.right),
            pct(self.abstained),
            pct(self.wrong),
            pct(self.variant_right),
            "-" if cov is None else f"{100 * cov:.0f}%",
            "-" if acc is None else f"{100 * acc:.0f}%",
        ]


_REFS: ReferenceSet | None = None
_OVERLAYS = False


def _init(refs: ReferenceSet, overlays: bool = False) -> None:
    """A worker's start: its references, one OpenCV thread, and its end with its parent."""
    import cv2

    from ..core.parallel import die_with_parent

    die_with_parent()
    global _REFS, _OVERLAYS
    _REFS = refs
    _OVERLAYS = overlays
    cv2.setNumThreads(1)


def _shown_extra(frame: object, result: object, truth: str) -> dict[str, object] | None:
    """The reason and the overlay (:data:`OVERLAY_WIDTH` wide) of a pair answered wrong
    or "cannot tell"; None for a right answer."""
    import cv2

    from .html_report import cannot_tell_text
    from .overlay import overlay_evidence, overlay_image

    p = result.prediction  # type: ignore[attr-defined]
    true_cls = truth.split("/", 1)[0]
    if p is not None and p.class_id == true_cls:
        return None
    verdict = (
        cannot_tell_text(result.reason)  # type: ignore[attr-defined]
        if p is None
        else f"wrong: {p.class_id} {p.variant or ''} (distance {p.distance:.3f})"
    )
    image = overlay_image(
        frame.color,  # type: ignore[attr-defined]
        result.detections.centroids,  # type: ignore[attr-defined]
        verdict,
        detail=f"true {truth}",
        evidence=overlay_evidence(result),
    )
    h, w = image.shape[:2]
    size = (OVERLAY_WIDTH, max(1, round(h * OVERLAY_WIDTH / w)))
    return {
        "reason": None if p is not None else result.reason,  # type: ignore[attr-defined]
        "overlay": cv2.resize(image, size, interpolation=cv2.INTER_AREA),
    }


def _one(args: tuple[str, int, int, str]) -> tuple:
    """Render sample ``k`` of a class under a condition and classify it: name, truth
    (``class/variant``), predicted class and variant (None: cannot tell), the conditions
    drawn, and the best guess's class and confidence (None: no guess); when the worker
    keeps overlays, a seventh item: :func:`_shown_extra`."""
    from ..classifier.pipeline import classify_frame
    from ..core.frame import RGBDFrame
    from ..sim.dataset import render_sample

    condition, seed, k, class_id = args
    names = () if condition == "clean" else (condition,)
    sample = render_sample(class_id, k, seed, conditions=names)
    r = sample.result
    frame = RGBDFrame(r.color, r.depth_mm, r.intrinsics, sample.name, sample.name, "render")
    if _REFS is None:
        raise RuntimeError("worker started without references (initializer not run)")
    result = classify_frame(frame, _REFS)
    p = result.prediction
    truth = f"{sample.state.class_id}/{sample.state.variant}"
    drawn = sample.conditions.names
    g = result.best_guess
    guess = None if g is None else (g.class_id, float(g.confidence))
    out = (
        sample.name, truth, None if p is None else p.class_id,
        None if p is None else p.variant, drawn, guess,
    )
    return (*out, _shown_extra(frame, result, truth)) if _OVERLAYS else out


def score_condition(
    condition: str,
    references: ReferenceSet,
    *,
    per_class: int,
    seed: int,
    jobs: int = 1,
    on_progress: Callable[[int], None] | None = None,
    overlays: bool = False,
    classes: tuple[str, ...] = CLASS_IDS,
) -> list[ConditionScore]:
    """Render ``per_class`` pairs of every class under ``condition`` and classify them.

    Parameters
    ----------
    condition : str
        ``"clean"`` (SPEC's scene with the usual sensor noise) or a name of
        :data:`dgli_vision.sim.conditions.CONDITION_NAMES`.
    references : ReferenceSet
    per_class : int, keyword-only
    seed : int, keyword-only
    jobs : int, keyword-only
        Worker processes (the scores do not depend on it).
    on_progress : callable, keyword-only, optional
        Called with 1 after each pair.
    overlays : bool, keyword-only
        Keep the pairs answered wrong or "cannot tell" with their overlays
        (``ConditionScore.shown``).
    classes : tuple of str, keyword-only
        The classes rendered (default all twelve).

    Returns
    -------
    list of ConditionScore
        One; for ``"combo"`` also the pairs whose three conditions include the gripper
        and those whose do not.
    """
    tasks = [(condition, seed, k, c) for c in classes for k in range(per_class)]
    if jobs > 1:
        import multiprocessing

        ctx = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(
            jobs, mp_context=ctx, initializer=_init, initargs=(references, overlays)
        ) as pool:
            outcomes = []
            for out in pool.map(_one, tasks, chunksize=2):
                outcomes.append(out)
                if on_progress:
                    on_progress(1)
    else:
        _init(references, overlays)
        outcomes = []
        for t in tasks:
            outcomes.append(_one(t))
            if on_progress:
                on_progress(1)
    scores = [_tally(condition, outcomes)]
    if condition == "combo":
        with_ = [o for o in outcomes if "gripper" in o[4]]
        scores.append(_tally("combo with gripper", with_, subset=True))
        without = [o for o in outcomes if "gripper" not in o[4]]
        scores.append(_tally("combo without gripper", without, subset=True))
    return scores


def _tally(label: str, outcomes: list, *, subset: bool = False) -> ConditionScore:
    right = abstained = wrong = variant_right = 0
    cases = []
    guesses = []
    shown = []
    for out in outcomes:
        name, truth, cls, variant, drawn, guess = out[:6]
        extra = out[6] if len(out) > 6 else None
        if extra is not None:
            answer = None if cls is None else f"{cls}/{variant}"
            shown.append(
                ShownPair(name, tuple(drawn), truth, answer, extra["reason"], extra["overlay"])
            )
        true_cls, true_var = truth.split("/", 1)
        if guess is not None:
            guesses.append((guess[1], guess[0] == true_cls))
        if cls is None:
            abstained += 1
        elif cls == true_cls:
            right += 1
            variant_right += str(variant) == true_var
        else:
            wrong += 1
            cases.append(f"{name} ({'+'.join(drawn) or 'clean'}): {truth} -> {cls}/{variant}")
    return ConditionScore(
        label,
        len(outcomes),
        right,
        abstained,
        wrong,
        variant_right,
        tuple(cases),
        tuple(guesses),
        subset,
        tuple(shown),
    )


def robustness_table(scores: list[ConditionScore]) -> tuple[list[str], list[list[str]]]:
    """Header and rows of the robustness table."""
    header = [
        "condition",
        "pairs",
        "right",
        "cannot tell",
        "wrong",
        "class + variant right",
        "answered",
        "right of answers",
    ]
    return header, [s.to_row() for s in scores]


def reliability_rows(
    scores: list[ConditionScore], bins: tuple[float, ...] = RELIABILITY_BINS
) -> list[dict[str, object]]:
    """How often the best guess is right in each confidence bin, over all conditions.

    Every pair's best guess counts, those below the threshold that became "cannot tell"
    included; rows that are parts of another condition's pairs are not counted twice.

    Returns
    -------
    list of dict
        One per bin: ``"confidence"`` (``"[0.25, 0.5)"``; the last bin is closed),
        ``"low"``, ``"high"``, ``"answers"``, ``"right"`` and ``"right_fraction"`` (None
        for an empty bin).
    """
    guesses = [g for s in scores if not s.subset for g in s.guesses]
    edges = [*bins, 1.0]
    rows = []
    for k, (lo, hi) in enumerate(pairwise(edges)):
        last = k == len(bins) - 1
        inside = [ok for c, ok in guesses if lo <= c < hi or (last and c == hi)]
        rows.append(
            {
                "confidence": f"[{lo:g}, {hi:g}{']' if last else ')'}",
                "low": lo,
                "high": hi,
                "answers": len(inside),
                "right": sum(inside),
                "right_fraction": sum(inside) / len(inside) if inside else None,
            }
        )
    return rows


def reliability_table(
    scores: list[ConditionScore], bins: tuple[float, ...] = RELIABILITY_BINS
) -> tuple[list[str], list[list[str]]]:
    """Header and rows of the reliability table (:func:`reliability_rows`)."""
    header = ["confidence", "answers", "right", "right %"]
    rows = []
    for r in reliability_rows(scores, bins):
        frac = r["right_fraction"]
        pct = "-" if frac is None else f"{100 * float(frac):.0f}%"
        rows.append([str(r["confidence"]), str(r["answers"]), str(r["right"]), pct])
    return header, rows
