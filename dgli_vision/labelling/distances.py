"""The classifier's distances and verdicts for many frames at once.

:func:`frame_distances` is :func:`dgli_vision.classifier.classify.reference_distances`
for a batch of frames, term by term with the classifier's own weights and slacks (a test
checks that both agree within 1e-6): the per-frame function costs about a millisecond,
a batch of 64 frames a few. :func:`verdicts` is
:func:`~dgli_vision.classifier.classify.classify_coordinates`'s winner, runner-up and
confidence, from the distances.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..classifier.classify import (
    FACE_WEIGHT,
    FULL_COORDINATES,
    FULL_MARGIN,
    HEIGHT_SCALE_MM,
    HEIGHT_SLACK_MM,
    HEIGHT_WEIGHT,
    LIFTED_WEIGHT,
    MIN_COORDINATES,
    PAST_WEIGHT,
    SPREAD_SCALE_MM,
    SPREAD_SLACK_MM,
    SPREAD_WEIGHT,
    TIE_SCALE,
    VISIBILITY_WEIGHT,
)
from ..classifier.references import ReferenceSet
from ..core.dgli import pair_indices
from ..core.distance import soft_centred_unit_ranks

__all__ = ["FrameEvidence", "Verdicts", "frame_distances", "verdicts"]


@dataclass(frozen=True, eq=False)
class FrameEvidence:
    """What the classifier weighs for n frames (the arguments of
    ``reference_distances``, stacked), see :mod:`dgli_vision.classifier.classify`.

    Attributes
    ----------
    coords : (n, 28)
    visible, unknown : (n, 16) bool
    lifted, heights_mm, past : (n, 16), NaN where not told
    back : (n, 4), NaN where not told
    spread_mm : (n, 120), NaN where not told
    """

    coords: NDArray[np.float64]
    visible: NDArray[np.bool_]
    unknown: NDArray[np.bool_]
    lifted: NDArray[np.float64]
    heights_mm: NDArray[np.float64]
    past: NDArray[np.float64]
    back: NDArray[np.float64]
    spread_mm: NDArray[np.float64]

    def known_coordinates(self) -> NDArray[np.bool_]:
        """Coordinates the classifier uses: known, both segments seen, shape (n, 28)."""
        seen = self.visible.reshape(len(self.visible), -1, 2).all(axis=2)
        i, j = pair_indices(seen.shape[1])
        return np.isfinite(self.coords) & seen[:, i] & seen[:, j]


def _mean_over(told: NDArray[np.bool_], gap: NDArray[np.float64]) -> NDArray[np.float64]:
    """Mean of ``gap`` (n, K, s) over the told entries (n, s); 0 where none is told."""
    g = np.where(told[:, None, :], gap, 0.0).sum(axis=2)
    return g / np.maximum(told.sum(axis=1), 1)[:, None]


def _rate_gap(x: NDArray, rates: NDArray) -> NDArray:
    told = np.isfinite(x)
    return _mean_over(told, np.abs(np.nan_to_num(x)[:, None, :] - rates[None]))


def _height_gap(h: NDArray, ranges: NDArray) -> NDArray:
    told = np.isfinite(h)
    hh = np.nan_to_num(h)[:, None, :]
    outside = np.maximum(ranges[None, ..., 0] - hh, hh - ranges[None, ..., 1]) - HEIGHT_SLACK_MM
    gap = np.clip(outside / HEIGHT_SCALE_MM, 0.0, 1.0)
    return _mean_over(told, np.where(np.isfinite(gap), gap, 0.0))


def _face_gap(back: NDArray, rates: NDArray) -> NDArray:
    both = np.isfinite(back)[:, None, :] & np.isfinite(rates)[None]
    diff = np.abs(np.nan_to_num(back)[:, None, :] - np.nan_to_num(rates)[None])
    return np.where(both, diff, 0.0).sum(axis=2) / np.maximum(both.sum(axis=2), 1)


def _spread_gap(d: NDArray, ranges: NDArray) -> NDArray:
    told = np.isfinite(d)
    out = np.zeros((len(d), len(ranges)))
    finite_range = np.isfinite(ranges).all(axis=(0, 2))  # (120,)
    usable = told.any(axis=1) & ~(told & ~finite_range[None]).any(axis=1)
    if not usable.any():
        return out
    # outside the range [lo, hi] = |d - mid| - half, computed in place over (n, K, 120)
    # in float32 (the largest term, n x K x 120): within 1e-6 of the classifier's
    r = np.nan_to_num(ranges)
    mid = (0.5 * (r[..., 0] + r[..., 1])).astype(np.float32)
    half = (0.5 * (r[..., 1] - r[..., 0]) + SPREAD_SLACK_MM).astype(np.float32)
    sub = told[usable]
    dd = np.where(sub, d[usable], 0.0).astype(np.float32)[:, None, :]
    gap = np.subtract(dd, mid[None])
    np.abs(gap, out=gap)
    gap -= half[None]
    gap /= SPREAD_SCALE_MM
    np.clip(gap, 0.0, 1.0, out=gap)
    gap *= sub[:, None, :]
    out[usable] = gap.sum(axis=2, dtype=np.float64) / np.maximum(sub.sum(axis=1), 1)[:, None]
    return out


def frame_distances(ev: FrameEvidence, references: ReferenceSet) -> NDArray[np.float64]:
    """Distance of every frame to every reference, shape (n, K); a row of NaN where a
    frame has fewer than ``MIN_COORDINATES`` known coordinates (the classifier's
    ``DetectionError``)."""
    n, ref = len(ev.coords), references.matrix()
    out = np.full((n, len(ref)), np.nan)
    known = ev.known_coordinates()
    ok = known.sum(axis=1) >= MIN_COORDINATES
    masks, group = np.unique(known[ok], axis=0, return_inverse=True)
    rows = np.flatnonzero(ok)
    for g, mask in enumerate(masks):
        sel = rows[group.ravel() == g]
        x = soft_centred_unit_ranks(ev.coords[sel][:, mask], TIE_SCALE)
        out[sel] = np.clip(1.0 - x @ references.ranked(mask).T, 0.0, 2.0)
    use = ~ev.unknown
    vis = ev.visible.astype(float)
    gap = _mean_over(use, np.abs(vis[:, None, :] - references.visible_rates()[None]))
    out += VISIBILITY_WEIGHT * np.where(use.any(axis=1)[:, None], gap, 0.0)
    out += LIFTED_WEIGHT * _rate_gap(ev.lifted, references.lifted_rates())
    out += HEIGHT_WEIGHT * _height_gap(ev.heights_mm, references.height_ranges())
    out += PAST_WEIGHT * _rate_gap(ev.past, references.past_rates())
    out += FACE_WEIGHT * _face_gap(ev.back, references.back_rates())
    out += SPREAD_WEIGHT * _spread_gap(ev.spread_mm, references.spread_ranges())
    return out


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
