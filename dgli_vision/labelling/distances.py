"""The classifier's distances and verdicts for many frames at once.

:func:`frame_distances` is :func:`dgli_vision.classifier.classify.batch_distances`:
the classifier's own terms, each computed once for a block of frames (the per-frame
function costs about a millisecond, a batch of 64 frames a few). :func:`verdicts` is
:func:`~dgli_vision.classifier.classify.classify_coordinates`'s winner, runner-up and
confidence, from the distances.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..classifier.classify import FULL_COORDINATES, FULL_MARGIN, batch_distances
from ..classifier.evidence import Evidence
from ..classifier.references import ReferenceSet

__all__ = ["FrameEvidence", "Verdicts", "frame_distances", "verdicts"]


@dataclass(frozen=True, eq=False, kw_only=True)
class FrameEvidence:
    """n frames as the classifier weighs them: their coordinates and the classifier's
    :class:`~dgli_vision.classifier.evidence.Evidence`, stacked (a leading axis n).

    Attributes
    ----------
    coords : ndarray, shape (n, 28)
    evidence : Evidence
    points_m : ndarray, shape (n, 16, 3), optional
        The sticker centres, metres, z up (what the state fit of
        :mod:`~dgli_vision.classifier.state_fit` takes).
    """

    coords: NDArray[np.float64]
    evidence: Evidence
    points_m: NDArray[np.float64] | None = None

    def known_coordinates(self) -> NDArray[np.bool_]:
        """Coordinates the classifier uses: known, both segments seen, shape (n, 28)."""
        return self.evidence.known_coordinates(self.coords)


def frame_distances(ev: FrameEvidence, references: ReferenceSet) -> NDArray[np.float64]:
    """Distance of every frame to every reference, shape (n, K); a row of NaN where a
    frame has fewer than ``MIN_COORDINATES`` known coordinates (the classifier's
    ``DetectionError``)."""
    return batch_distances(ev.coords, ev.evidence, references)


@dataclass(frozen=True, eq=False)
class Verdicts:
    """Each frame's nearest reference, its margin and confidence (arrays of n).

    ``best`` is -1 for a frame without enough coordinates (a gap).
    """

    best: NDArray[np.intp]
    distance: NDArray[np.float64]
    margin: NDArray[np.float64]
    confidence: NDArray[np.float64]


def verdicts(
    distances: NDArray[np.float64],
    references: ReferenceSet,
    n_unknown: NDArray[np.intp],
    n_known: NDArray[np.intp],
) -> Verdicts:
    """The classifier's verdict of every frame from its distances.

    Parameters
    ----------
    distances : ndarray, shape (n, K)
    references : ReferenceSet
    n_unknown : ndarray of int, shape (n,)
        Stickers whose state is unknown and whose flap's lean was not measured.
    n_known : ndarray of int, shape (n,)
        Coordinates the verdict rests on.
    """
    d = np.asarray(distances, dtype=np.float64)
    gap = ~np.isfinite(d).all(axis=1)
    safe = np.where(gap[:, None], 0.0, d)
    best = np.argmin(safe, axis=1)
    classes = np.array([r.class_id for r in references.references])
    other = classes[None, :] != classes[best][:, None]
    runner = np.where(other, safe, np.inf).min(axis=1)
    dist = safe[np.arange(len(d)), best]
    margin = runner - dist
    part = np.where(np.isfinite(margin), np.clip(margin / FULL_MARGIN, 0, 1), 1.0)
    known = np.maximum(1.0 - np.asarray(n_unknown) / 16.0, 0.0)
    coords_part = np.minimum(1.0, np.asarray(n_known) / FULL_COORDINATES)
    conf = np.round(part * known**3 * coords_part, 4)
    return Verdicts(
        best=np.where(gap, -1, best),
        distance=np.where(gap, np.nan, dist),
        margin=np.where(gap, np.nan, margin),
        confidence=np.where(gap, np.nan, conf),
    )
