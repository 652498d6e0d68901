"""The robustness table: for each capture condition, how often the answer is right, an
honest "cannot tell", or wrong.

Each condition renders its own fresh labelled pairs in memory
(:func:`dgli_vision.dataset.render_samples` with that condition) and classifies them with
the full pipeline. Pairs are spread over worker processes, one condition at a time.
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass

from .classes import CLASS_IDS
from .references import ReferenceSet

__all__ = ["ConditionScore", "robustness_table", "score_condition"]


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
    """

    condition: str
    n: int
    right: int
    abstained: int
    wrong: int
    variant_right: int
    wrong_cases: tuple[str, ...] = ()

    def to_row(self) -> list[str]:
        """Markdown row: condition, n, right, cannot tell, wrong, variant right."""

        def pct(k: int) -> str:
            return f"{100 * k / self.n:.0f}%" if self.n else "-"

        return [
            self.condition,
            str(self.n),
            pct(self.right),
            pct(self.abstained),
            pct(self.wrong),
            pct(self.variant_right),
        ]


_REFS: ReferenceSet | None = None


def _init(refs: ReferenceSet) -> None:
    import cv2

    global _REFS
    _REFS = refs
    cv2.setNumThreads(1)


def _one(
    args: tuple[str, int, int, str],
) -> tuple[str, str, str | None, str | None, tuple[str, ...]]:
    """Render sample ``k`` of a class under a condition and classify it: name, truth
    (``class/variant``), predicted class and variant (None: cannot tell), and the
    conditions drawn."""
    from .dataset import render_sample
    from .frames import RGBDFrame
    from .pipeline import classify_frame

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
    if p is None:
        return sample.name, truth, None, None, drawn
    return sample.name, truth, p.class_id, p.variant, drawn


def score_condition(
    condition: str,
    references: ReferenceSet,
    *,
    per_class: int,
    seed: int,
    jobs: int = 1,
    on_progress: Callable[[int], None] | None = None,
) -> list[ConditionScore]:
    """Render ``per_class`` pairs of every class under ``condition`` and classify them.

    Parameters
    ----------
    condition : str
        ``"clean"`` (SPEC's scene with the usual sensor noise) or a name of
        :data:`dgli_vision.conditions.CONDITION_NAMES`.
    references : ReferenceSet
    per_class : int, keyword-only
    seed : int, keyword-only
    jobs : int, keyword-only
        Worker processes.

    Returns
    -------
    list of ConditionScore
        One; for ``"combo"`` also the pairs whose three conditions include the gripper
        and those whose do not.
    """
    tasks = [(condition, seed, k, c) for c in CLASS_IDS for k in range(per_class)]
    if jobs > 1:
        import multiprocessing

        ctx = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(
            jobs, mp_context=ctx, initializer=_init, initargs=(references,)
        ) as pool:
            outcomes = []
            for out in pool.map(_one, tasks, chunksize=2):
                outcomes.append(out)
                if on_progress:
                    on_progress(1)
    else:
        _init(references)
        outcomes = []
        for t in tasks:
            outcomes.append(_one(t))
            if on_progress:
                on_progress(1)
    scores = [_tally(condition, outcomes)]
    if condition == "combo":
        scores.append(_tally("combo with gripper", [o for o in outcomes if "gripper" in o[4]]))
        scores.append(
            _tally("combo without gripper", [o for o in outcomes if "gripper" not in o[4]])
        )
    return scores


def _tally(label: str, outcomes: list) -> ConditionScore:
    right = abstained = wrong = variant_right = 0
    cases = []
    for name, truth, cls, variant, drawn in outcomes:
        true_cls, true_var = truth.split("/", 1)
        if cls is None:
            abstained += 1
        elif cls == true_cls:
            right += 1
            variant_right += str(variant) == true_var
        else:
            wrong += 1
            cases.append(f"{name} ({'+'.join(drawn) or 'clean'}): {truth} -> {cls}/{variant}")
    return ConditionScore(
        label, len(outcomes), right, abstained, wrong, variant_right, tuple(cases)
    )


def robustness_table(scores: list[ConditionScore]) -> tuple[list[str], list[list[str]]]:
    """Header and rows of the robustness table."""
    header = ["condition", "pairs", "right", "cannot tell", "wrong", "class + variant right"]
    return header, [s.to_row() for s in scores]
