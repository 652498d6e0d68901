"""The paper's three folding sequences (SPEC section 3), at any point of their folds.

A sequence is a list of folds made one after the other. Its *progress* runs from 0 (flat)
to the number of folds: progress ``k + f`` has the first ``k`` folds laid flat and fold
``k + 1`` turned ``f * 180`` degrees. A fold counts once its flap has turned more than 90
degrees from flat; each frame is labelled with the class (and variant) its completed
folds give.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ...core.errors import InvalidValueError
from ...core.layout import NapkinLayout, default_layout
from .states import ClothState, FoldStep, corner_fold_line, make_state, side_fold_line

__all__ = [
    "SEQUENCES",
    "folding_sequence",
    "sequence_label",
    "sequence_progress",
    "sequence_state",
    "sequence_steps",
]

#: name -> (description, [(class id, variant) after each fold])
SEQUENCES: dict[str, tuple[str, list[tuple[str, str | None]]]] = {
    "I": ("two opposite corners folded one after the other", [("02", "A"), ("06", "AC")]),
    "II": (
        "the four corners folded inwards one by one",
        [("02", "A"), ("04", "AB"), ("07", "D"), ("08", None)],
    ),
    "III": ("folding in half", [("11", "AB")]),
}

#: The fold sizes of the simulator's own sequences (mm), and the range a seeded sequence
#: draws them from: the ranges of the classes the sequence passes through (SPEC section 3).
_SIZES: dict[str, tuple[float, tuple[float, float]]] = {
    "I": (175.0, (150.0, 200.0)),  # corner legs of 02 and 06
    "II": (185.0, (170.0, 200.0)),  # 08's legs, kept throughout
    "III": (202.0, (198.0, 210.0)),  # 11's inset
}


def _check(name: str) -> None:
    if name not in SEQUENCES:
        raise InvalidValueError(
            f"unknown sequence {name!r}; expected one of {', '.join(SEQUENCES)}"
        )


def sequence_steps(
    name: str,
    layout: NapkinLayout | None = None,
    rng: np.random.Generator | None = None,
) -> list[FoldStep]:
    """The folds of sequence ``name`` in order.

    Parameters
    ----------
    name : str
        ``"I"``, ``"II"`` or ``"III"``.
    layout : NapkinLayout, optional
        Defaults to the packaged layout; fold sizes scale with the napkin's side.
    rng : Generator, optional
        Draw every leg (inset) from the range of the sequence's classes; without it, the
        fixed sizes of the simulator's own sequences.
    """
    _check(name)
    layout = layout or default_layout()
    scale = min(layout.width_mm, layout.height_mm) / 400.0
    fixed, (lo, hi) = _SIZES[name]

    def size() -> float:
        return scale * (fixed if rng is None else float(rng.uniform(lo, hi)))

    if name == "III":
        return [side_fold_line(layout, "AB", size())]
    corners = "AC" if name == "I" else "ABCD"
    return [corner_fold_line(layout, c, size(), size()) for c in corners]


def sequence_label(name: str, progress: float) -> tuple[str, str | None]:
    """Class and variant at ``progress`` by the 90-degree rule."""
    _check(name)
    labels = SEQUENCES[name][1]
    k = int(np.floor(progress))
    done = k + (1 if progress - k > 0.5 else 0)
    done = min(done, len(labels))
    return ("01", None) if done == 0 else labels[done - 1]


def sequence_progress(name: str, n_frames: int) -> list[float]:
    """``n_frames`` progress values spread evenly from flat to the last fold laid flat."""
    _check(name)
    if n_frames < 2:
        raise InvalidValueError(f"a sequence needs at least 2 frames, got {n_frames}")
    n_folds = len(SEQUENCES[name][1])
    return [n_folds * i / (n_frames - 1) for i in range(n_frames)]


def sequence_state(
    name: str,
    progress: float,
    *,
    steps: list[FoldStep] | None = None,
    layout: NapkinLayout | None = None,
    **kwargs: Any,
) -> ClothState:
    """The cloth of sequence ``name`` at ``progress``, labelled by the 90-degree rule.

    Parameters
    ----------
    name : str
    progress : float
        In ``[0, number of folds]``.
    steps : list of FoldStep, optional
        The sequence's folds (:func:`sequence_steps`); default the fixed ones.
    layout : NapkinLayout, optional
    **kwargs
        Passed to :func:`~dgli_vision.sim.cloth.states.make_state` (wrinkles, placement).

    Returns
    -------
    ClothState
        ``params["angles_deg"]`` gives the fold angles, ``params["progress"]`` the
        progress, and, while a fold is in progress, ``params["stage"]`` says whether it
        has turned past 90 degrees (``"settling fold 2 of II"``) or not (``"rising
        ..."``).
    """
    layout = layout or default_layout()
    steps = steps if steps is not None else sequence_steps(name, layout)
    if not 0 <= progress <= len(steps):
        raise InvalidValueError(f"progress must be in [0, {len(steps)}], got {progress}")
    k = min(int(np.floor(progress)), len(steps) - 1)
    angles = [np.pi] * k + [np.pi * (progress - k)]
    if progress - k == 0 and k == 0:
        angles = []
    class_id, variant = sequence_label(name, progress)
    params = {
        "sequence": name,
        "progress": round(float(progress), 6),
        "angles_deg": [round(float(np.degrees(a)), 3) for a in angles],
    }
    turned = float(np.degrees(angles[-1])) if angles else 0.0
    if 0.0 < turned < 180.0:  # as the simulator's folds in progress say it
        params["stage"] = f"{'settling' if turned > 90 else 'rising'} fold {k + 1} of {name}"
    return make_state(
        class_id,
        variant,
        steps[: len(angles)],
        layout=layout,
        angles=angles,
        params=params,
        **kwargs,
    )


def folding_sequence(
    name: str, *, frames_per_fold: int = 12, layout: NapkinLayout | None = None
) -> list[ClothState]:
    """The frames of sequence ``name`` (``"I"``, ``"II"`` or ``"III"``).

    Parameters
    ----------
    name : str
        Sequence name.
    frames_per_fold : int, keyword-only
        Frames per fold; fold ``k`` reaches angles ``pi * i / frames_per_fold``.
    layout : NapkinLayout, optional
        Defaults to the packaged layout.

    Returns
    -------
    list of ClothState
        ``1 + frames_per_fold * folds`` frames, the flat napkin first, each labelled with
        its true class; ``params["angles_deg"]`` gives the fold angles.
    """
    if frames_per_fold < 1:
        raise InvalidValueError(f"frames_per_fold must be at least 1, got {frames_per_fold}")
    _check(name)
    layout = layout or default_layout()
    steps = sequence_steps(name, layout)
    n = len(steps) * frames_per_fold + 1
    return [
        sequence_state(name, len(steps) * i / (n - 1), steps=steps, layout=layout)
        for i in range(n)
    ]
