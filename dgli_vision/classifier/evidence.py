"""What the classifier weighs beside the cloth coordinates, as one record.

A camera frame (:meth:`~dgli_vision.classifier.pipeline.ClothObservation.evidence`) and
a block of simulated frames (:func:`~dgli_vision.labelling.observe.observe_frames`) give
the same :class:`Evidence`: for one frame each array has the shape below, for n frames a
leading axis n. :func:`~dgli_vision.classifier.classify.evidence_distances` turns either
into distances to the references, term by term, with one implementation of each term.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np
from numpy.typing import NDArray

from ..core.dgli import pair_indices

__all__ = ["Evidence"]


@dataclass(frozen=True, kw_only=True, eq=False)
class Evidence:
    """The evidence of one frame, or of n frames stacked (a leading axis n on each).

    Every field is optional: a term whose evidence is None is left out of the distance.

    Attributes
    ----------
    visible : ndarray of bool, shape (16,)
        Which stickers were seen (SPEC order).
    unknown : ndarray of bool, shape (16,)
        Stickers not seen for a reason other than cloth on top (out of view, under an
        object, in a highlight): no evidence either way.
    lifted : ndarray of float, shape (16,)
        1 for a sticker standing more than ``LIFTED_MM`` above the table, 0 for one lying
        on it, NaN where not known.
    heights_mm : ndarray of float, shape (16,)
        Height of each sticker above the table, mm, NaN where not known.
    past : ndarray of float, shape (16,)
        For stickers on a flap held up: 1 where it has turned past 90 degrees, 0 where
        not (in proportion near vertical), NaN where not measured.
    back : ndarray of float, shape (4,)
        For each corner A-D: 1 where its stickers show the back face, 0 the front, NaN
        where they do not tell.
    spread_mm : ndarray of float, shape (120,)
        3D distance between the stickers of each pair (``references.sticker_pairs``),
        mm, NaN where either was not seen.
    tips : ndarray of float, shape (4,)
        For each corner A-D, the share of its tip's flat place seen bare table, NaN
        where not told.
    """

    visible: NDArray[np.bool_] | None = None
    unknown: NDArray[np.bool_] | None = None
    lifted: NDArray[np.float64] | None = None
    heights_mm: NDArray[np.float64] | None = None
    past: NDArray[np.float64] | None = None
    back: NDArray[np.float64] | None = None
    spread_mm: NDArray[np.float64] | None = None
    tips: NDArray[np.float64] | None = None

    def stacked(self) -> Evidence:
        """The evidence of one frame as a block of one (a leading axis of 1); a block
        unchanged."""
        if self.visible is not None and np.ndim(self.visible) == 2:
            return self
        return Evidence(**{
            name: None if v is None else np.asarray(v)[None]
            for name, v in zip(_FIELDS, self._values())
        })

    def _values(self) -> tuple[object, ...]:
        """The fields' values, in :data:`_FIELDS` order."""
        return tuple(getattr(self, name) for name in _FIELDS)

    def frame(self, i: int) -> Evidence:
        """The evidence of frame ``i`` of a block."""
        return Evidence(**{
            name: None if v is None else v[i] for name, v in zip(_FIELDS, self._values())
        })

    def known_coordinates(self, coords: NDArray[np.float64]) -> NDArray[np.bool_]:
        """The coordinates the classifier uses: known (finite) and, when ``visible`` is
        given, of two segments whose stickers were all seen; the shape of ``coords``
        ((28,) or (n, 28))."""
        x = np.asarray(coords, dtype=np.float64)
        known = np.isfinite(x)
        if self.visible is None:
            return known
        vis = np.asarray(self.visible, dtype=bool)
        seen = vis.reshape(*vis.shape[:-1], -1, 2).all(axis=-1)
        i, j = pair_indices(seen.shape[-1])
        return known & seen[..., i] & seen[..., j]


#: The names of :class:`Evidence`'s fields, in order (``dataclasses.fields`` costs
#: microseconds a call).
_FIELDS = tuple(f.name for f in fields(Evidence))
