"""From cloth coordinates (and which stickers were seen) to a named state.

The distance to a reference is the Spearman distance over the coordinates known in the
observation, plus a visibility term: the mean, over the 16 stickers, of how far the
observation (seen / not seen) is from the reference's rate of being seen. A missing
sticker is evidence: it says what lies on top.

When visibility is given, coordinates of segments with an unseen sticker are ignored even
if a value is supplied (as a simulator can): no camera could have measured them, and a
sticker hidden by a flap lies within a cloth thickness of the flap's own segments, where
the dGLI is near-singular and its sign follows millimetre-level noise.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .dgli import pair_indices
from .distance import pairwise_spearman
from .errors import DetectionError
from .references import ReferenceSet

__all__ = [
    "MIN_COORDINATES",
    "VISIBILITY_WEIGHT",
    "Prediction",
    "RunnerUp",
    "classify_coordinates",
]

#: Fewer known coordinates than this (4 complete segments give 6) cannot be ranked.
MIN_COORDINATES = 6
#: Weight of the visibility term against the Spearman distance (both in [0, 2]).
VISIBILITY_WEIGHT = 1.0


@dataclass(frozen=True)
class RunnerUp:
    """The best reference of another class."""

    class_id: str
    name: str
    variant: str | None
    distance: float


@dataclass(frozen=True)
class Prediction:
    """A verdict.

    Attributes
    ----------
    class_id, name : str
        ``"02"``, ``"corner-over"``.
    variant : str or None
        SPEC's variant string.
    distance : float
        Distance to the winning reference (Spearman + visibility term).
    runner_up : RunnerUp or None
        Best reference of any other class.
    margin : float
        ``runner_up.distance - distance`` (``inf`` without a runner-up).
    """

    class_id: str
    name: str
    variant: str | None
    distance: float
    runner_up: RunnerUp | None
    margin: float


def _n_segments(n_coordinates: int) -> int:
    """m such that m (m - 1) / 2 == n_coordinates."""
    m = round((1 + float(np.sqrt(1 + 8 * n_coordinates))) / 2)
    if m * (m - 1) // 2 != n_coordinates:
        raise ValueError(f"{n_coordinates} is not a number of segment pairs")
    return m


def reference_distances(
    coords: ArrayLike, references: ReferenceSet, visible: ArrayLike | None = None
) -> NDArray[np.float64]:
    """Distance of one observation to every reference, shape (k,).

    Parameters
    ----------
    coords : array_like, shape (28,)
        dGLI coordinates, NaN where unknown.
    references : ReferenceSet
    visible : array_like of bool, shape (16,), optional
        Which stickers were seen.

    Raises
    ------
    DetectionError
        With fewer than :data:`MIN_COORDINATES` known coordinates.
    """
    x = np.asarray(coords, dtype=np.float64)
    ref = references.matrix()
    if x.shape != (ref.shape[1],):
        raise ValueError(f"coords must have shape ({ref.shape[1]},), got {x.shape}")
    known = ~np.isnan(x)
    if visible is not None:
        vis = np.asarray(visible, dtype=bool)
        if vis.shape != (2 * _n_segments(len(x)),):
            raise ValueError(
                f"visible must have shape ({2 * _n_segments(len(x))},), got {vis.shape}"
            )
        seen_segment = vis.reshape(-1, 2).all(axis=1)
        i, j = pair_indices(len(seen_segment))
        known &= seen_segment[i] & seen_segment[j]
    if known.sum() < MIN_COORDINATES:
        raise DetectionError(
            f"only {int(known.sum())} of {len(x)} cloth coordinates are known; "
            f"need at least {MIN_COORDINATES} (4 segments with both stickers seen)"
        )
    dist = pairwise_spearman(x[known][None, :], ref[:, known])[0]
    if visible is not None:
        rates = references.visible_rates()
        dist = dist + VISIBILITY_WEIGHT * np.abs(vis[None, :] - rates).mean(axis=1)
    return dist


def classify_coordinates(
    coords: ArrayLike, references: ReferenceSet, visible: ArrayLike | None = None
) -> Prediction:
    """Nearest reference of an observation (see :func:`reference_distances`).

    Parameters
    ----------
    coords : array_like, shape (28,)
        dGLI coordinates, NaN where a segment is missing.
    references : ReferenceSet
    visible : array_like of bool, shape (16,), optional
        Which stickers were seen (SPEC order); improves the verdict when given.

    Returns
    -------
    Prediction
    """
    dist = reference_distances(coords, references, visible)
    order = np.argsort(dist, kind="stable")
    best = references.references[order[0]]
    runner = None
    for k in order[1:]:
        r = references.references[k]
        if r.class_id != best.class_id:
            runner = RunnerUp(r.class_id, r.name, r.variant, float(dist[k]))
            break
    d = float(dist[order[0]])
    return Prediction(
        best.class_id,
        best.name,
        best.variant,
        d,
        runner,
        (runner.distance - d) if runner else float("inf"),
    )
