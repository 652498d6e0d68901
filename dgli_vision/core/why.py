"""The kinds of "cannot tell": why a frame read gives no class, as data.

A verdict that gives no class says why in words (``reason``, for people) and of what
kind (``why``, for programs: ``"why": {"kind": ...}`` in the JSON). Programs branch on
the kind, never on the words.
"""

from __future__ import annotations

from enum import Enum

__all__ = ["OUTSIDE_KINDS", "WhyKind"]


class WhyKind(str, Enum):
    """The kinds of "cannot tell"; each member is its JSON string.

    ``GEOMETRY``: the napkin's measured geometry is wrong (depth scale, lens, stickers too
    small, colour and depth of different instants); ``TOO_FEW``: too few stickers to rank
    the states; ``MIRROR``: the layout reads mirrored, or the cloth covers more table than
    the state allows; ``TOO_CLOSE``: the nearest states are too close to call for the
    evidence seen; ``CHANNELS``: a colour array whose red and blue channels are swapped;
    ``NO_STATE_FITS``: the napkin is in none of the twelve states (the nearest state's
    folds leave stickers unexplained); ``CRUMPLED``: cloth in a heap.
    """

    GEOMETRY = "geometry"
    TOO_FEW = "too few stickers"
    MIRROR = "mirror or footprint"
    TOO_CLOSE = "too close to call"
    CHANNELS = "colour channels"
    NO_STATE_FITS = "no state fits"
    CRUMPLED = "crumpled"
    #: (internal to the pipeline: a corner stretched as a diagonal fold's crease cuts
    #: it, left for the state fit to judge; never a result's kind)
    DEFERRED = "deferred"

    def __str__(self) -> str:
        return self.value


#: The kinds that say the napkin is in none of the twelve states.
OUTSIDE_KINDS: frozenset[str] = frozenset({WhyKind.NO_STATE_FITS.value, WhyKind.CRUMPLED.value})
