"""The paper's three folding sequences (SPEC section 3), frame by frame.

A fold counts once its flap has turned more than 90 degrees from flat; each frame is
labelled with the class (and variant) its completed folds give.
"""

from __future__ import annotations

import numpy as np

from ..layout import NapkinLayout, default_layout
from .states import ClothState, FoldStep, corner_fold_line, make_state, side_fold_line

__all__ = ["SEQUENCES", "folding_sequence"]

#: name -> (description, [(class id, variant) after each fold])
SEQUENCES: dict[str, tuple[str, list[tuple[str, str | None]]]] = {
    "I": ("two opposite corners folded one after the other", [("02", "A"), ("06", "AC")]),
    "II": (
        "the four corners folded inwards one by one",
        [("02", "A"), ("04", "AB"), ("07", "D"), ("08", None)],
    ),
    "III": ("folding in half", [("11", "AB")]),
}


def _steps(name: str, layout: NapkinLayout) -> list[FoldStep]:
    if name == "I":
        return [corner_fold_line(layout, c, 175.0, 175.0) for c in "AC"]
    if name == "II":
        return [corner_fold_line(layout, c, 185.0, 185.0) for c in "ABCD"]
    if name == "III":
        return [side_fold_line(layout, "AB", 202.0)]
    raise ValueError(f"unknown sequence {name!r}; expected one of {', '.join(SEQUENCES)}")


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
        raise ValueError(f"frames_per_fold must be at least 1, got {frames_per_fold}")
    layout = layout or default_layout()
    steps = _steps(name, layout)
    labels = SEQUENCES[name][1]
    frames = [make_state("01", None, [], layout=layout, params={"angles_deg": []})]
    for k in range(len(steps)):
        for i in range(1, frames_per_fold + 1):
            angle = np.pi * i / frames_per_fold
            angles = [np.pi] * k + [angle]
            done = k + 1 if angle > np.pi / 2 else k
            class_id, variant = ("01", None) if done == 0 else labels[done - 1]
            frames.append(
                make_state(
                    class_id,
                    variant,
                    steps[: k + 1],
                    layout=layout,
                    angles=angles,
                    params={"angles_deg": [round(float(np.degrees(a)), 3) for a in angles]},
                )
            )
    return frames
