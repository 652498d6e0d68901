"""What the sticker detector is told and what it returns.

:class:`DetectorParams` says how stickers are found (every field with its unit and
default), :class:`StickerDetections` what was found, and :class:`Rejection` each blob
that was not taken, with the check it failed (a :class:`RejectionKind`) and the values
measured: what a person debugging a real image needs, and what code downstream reads
(never the message, which is made from the data: :attr:`Rejection.reason`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import Enum

import numpy as np
from numpy.typing import NDArray

from .params import DetectorParams

__all__ = ["DetectorParams", "Rejection", "RejectionKind", "StickerDetections"]


class RejectionKind(Enum):
    """The check a blob failed (its value: the words a message begins with).

    Each kind's measured values (:attr:`Rejection.values`), by key:

    - ``NO_DEPTH``: none (no depth reading to judge its size by);
    - ``OBLIQUE``: ``foreshortening`` (minor / major axis, below
      ``DetectorParams.min_foreshortening``);
    - ``TOO_SMALL``, ``TOO_LARGE``: ``z_mm`` (the blob's depth), ``ratio`` (its area over
      a disc's expected there), ``foreshortening`` (minor / major axis, as for
      ``OBLIQUE``; not for a blob judged again at full resolution) and, for a centre
      measured again at full resolution after a halved search, ``full_resolution``
      (True);
    - ``NOT_DISC_SHAPED``: ``solidity``, ``elongation``;
    - ``NOT_WHOLE_DISC``: ``fill`` (the share of the expected disc covered);
    - ``NOT_ON_NAPKIN``: ``surround`` (the whiteness around over the blob's brightness);
    - ``NO_DISC_COLOUR``, ``NO_DOT_COLOUR``: none;
    - ``MIXED_COLOURS``: ``purity``;
    - ``NO_SUCH_STICKER``: ``disc``, ``dot`` (colour names no sticker pairs);
    - ``SECOND_BLOB``: ``sticker`` (the id a better blob holds);
    - ``DOT_WASHED_OUT``: ``disc`` (its colour name), ``possible`` (stickers of that
      colour still free).
    """

    NO_DEPTH = "no depth"
    OBLIQUE = "seen too obliquely"
    TOO_SMALL = "too small"
    TOO_LARGE = "too large"
    NOT_DISC_SHAPED = "not disc-shaped"
    NOT_WHOLE_DISC = "not a whole disc"
    NOT_ON_NAPKIN = "not on the napkin"
    NO_DISC_COLOUR = "no disc colour inside"
    NO_DOT_COLOUR = "no dot colour inside"
    MIXED_COLOURS = "mixed colours"
    NO_SUCH_STICKER = "no such sticker"
    SECOND_BLOB = "second blob"
    DOT_WASHED_OUT = "dot washed out"


@dataclass(frozen=True)
class Rejection:
    """A blob that is not taken as a sticker: where, the check it failed and the values
    that check measured (keys by kind: :class:`RejectionKind`).

    Attributes
    ----------
    centroid : tuple of float
        (u, v), pixels.
    area_px : float
        The blob's area, pixels.
    kind : RejectionKind
    values : mapping of str to float, int or str
        What the check measured.
    """

    centroid: tuple[float, float]
    area_px: float
    kind: RejectionKind
    values: Mapping[str, float | int | str] = field(default_factory=dict)

    @property
    def reason(self) -> str:
        """The rejection in words, made from :attr:`kind` and :attr:`values`."""
        return _rejection_message(self.kind, self.values)

    @property
    def size_ratio(self) -> float | None:
        """The blob's area over a sticker's at its depth, for a blob rejected as too
        small or too large; None for any other kind."""
        if self.kind in (RejectionKind.TOO_SMALL, RejectionKind.TOO_LARGE):
            return float(self.values["ratio"])
        return None


def _rejection_message(kind: RejectionKind, values: Mapping[str, float | int | str]) -> str:
    """A rejection's words, from its kind and measured values (see
    :class:`RejectionKind` for the keys of each)."""
    v = values
    k = RejectionKind
    if kind is k.NO_DEPTH:
        return "no depth to judge its size"
    if kind is k.OBLIQUE:
        return f"seen too obliquely (foreshortened {v['foreshortening']:.2f})"
    if kind in (k.TOO_SMALL, k.TOO_LARGE):
        size = "of a disc" if kind is k.TOO_SMALL else "discs"
        where = " at full resolution" if v.get("full_resolution") else ""
        return (
            f"{kind.value} for a sticker at {v['z_mm']:.0f} mm ({v['ratio']:.2f} "
            f"{size}{where})"
        )
    if kind is k.NOT_DISC_SHAPED:
        return (
            f"not disc-shaped (solidity {v['solidity']:.2f}, elongation "
            f"{v['elongation']:.2f})"
        )
    if kind is k.NOT_WHOLE_DISC:
        return f"not a whole disc (covers {v['fill']:.2f} of one)"
    if kind is k.NOT_ON_NAPKIN:
        return f"not on the napkin (surround {v['surround']:.2f} as bright as the blob)"
    if kind is k.MIXED_COLOURS:
        return f"mixed colours (purity {v['purity']:.2f})"
    if kind is k.NO_SUCH_STICKER:
        return f"no sticker is {v['disc']} with a {v['dot']} dot"
    if kind is k.SECOND_BLOB:
        return f"second blob for sticker {v['sticker']} (lower score)"
    if kind is k.DOT_WASHED_OUT:
        return f"{v['disc']} disc with its dot washed out; {v['possible']} stickers possible"
    return kind.value  # (NO_DISC_COLOUR, NO_DOT_COLOUR: the words say it all)


@dataclass(frozen=True, eq=False)
class StickerDetections:
    """What the detector found.

    Attributes
    ----------
    centroids : ndarray, shape (16, 2)
        Sub-pixel centroid (u, v) of each sticker id; NaN where not found.
    areas : ndarray, shape (16,)
        Blob area in pixels (NaN where not found).
    scores : ndarray, shape (16,)
        Colour purity times shape agreement in [0, 1] (0 where not found).
    depth_mm : ndarray, shape (16,)
        Median valid depth inside the blob, mm (NaN where none).
    rejected : tuple of Rejection
        Blobs that looked like candidates but were rejected, with the check each
        failed and its values.
    foreshortening : ndarray, shape (16,), optional
        Minor / major axis of each sticker's image (1 face-on; lower on a tilted
        flap); NaN where not found.
    pale_px : ndarray, shape (k, 2), optional
        Pixels (x, y) of pastel sticker colour left away from every sticker found: a
        broad sheen's washed-out stickers that no search could read (see
        :func:`.detect.find_washed_out`).
    pale_colours : tuple of str
        The sticker colours (names) of two or more of those samples.
    """

    centroids: NDArray[np.float64]
    areas: NDArray[np.float64]
    scores: NDArray[np.float64]
    depth_mm: NDArray[np.float64]
    rejected: tuple[Rejection, ...] = field(default_factory=tuple)
    foreshortening: NDArray[np.float64] | None = None
    pale_px: NDArray[np.float64] | None = None
    pale_colours: tuple[str, ...] = ()

    @property
    def found(self) -> NDArray[np.bool_]:
        """Which sticker ids were detected, shape (16,)."""
        return ~np.isnan(self.centroids[:, 0])
