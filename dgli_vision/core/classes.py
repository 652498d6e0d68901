"""The twelve cloth states of SPEC section 3: ids, names and variant strings.

A light module (no numerical imports), so that reading references and printing verdicts
does not pull in the simulator.
"""

from __future__ import annotations

__all__ = [
    "CLASS_HINT",
    "CLASS_IDS",
    "CLASS_NAMES",
    "CORNERS",
    "LANDING_PAIRS",
    "LIFTED_MM",
    "OUTSIDE",
    "PAST_BAND_DEG",
    "SIDES",
    "VARIANTS",
    "class_id_of",
    "digits_note",
    "foreign_digits",
]

CLASS_NAMES: dict[str, str] = {
    "01": "flat",
    "02": "corner-over",
    "03": "corner-under",
    "04": "two-adjacent-corners",
    "05": "two-adjacent-corners-crossing",
    "06": "two-opposite-corners",
    "07": "three-corners",
    "08": "four-corners-centre",
    "09": "strip-over",
    "10": "strip-under",
    "11": "half-fold",
    "12": "diagonal-fold",
}
CLASS_IDS: tuple[str, ...] = tuple(CLASS_NAMES)
#: The label of a state none of the twelve (labels.csv, a recording's labels, a
#: simulated state outside them): scored right only when no class is given.
OUTSIDE = "none"

#: How a class may be written, for messages.
CLASS_HINT = "a class: 01-12 (or 1-12), a name such as corner-over, or both (02_corner-over)"


def _ascii_digits(text: str) -> bool:
    """Whether ``text`` is one or more of the ASCII digits 0-9 (``str.isdigit`` is also
    true of other scripts' digits and of superscripts)."""
    return text.isascii() and text.isdigit()


def foreign_digits(text: str) -> bool:
    """Whether ``text`` holds a digit that is not one of the ASCII digits 0-9 (Arabic-
    Indic ``٠٢``, full-width digits, a superscript ``²``): a class id written so is
    refused, with this said."""
    return any(c.isdigit() and not c.isascii() for c in text)


def digits_note(text: str) -> str:
    """For a message refusing ``text`` as a class: ``" (its digits are not ASCII 0-9)"``
    when :func:`foreign_digits`, else ``""``."""
    return " (its digits are not the ASCII digits 0-9)" if foreign_digits(text) else ""

_BY_NAME = {name: cid for cid, name in CLASS_NAMES.items()}


def class_id_of(text: str) -> str | None:
    """The class id (``"02"``) a class is written as, or None when it names none.

    Accepted everywhere a class is read (labels files, ``--goal``, ``--from``): the id
    (``02``), the id without its zero (``2``), the name (``corner-over``, any case, with
    ``_`` or a space for ``-``), or id and name (``02_corner-over``, ``02 corner-over``,
    as the class folders are named); they must agree. An id is ASCII digits ``0``-``9``
    only: other scripts' digits (Arabic-Indic ``٠٢``, full-width ones), which Python's
    ``int`` would read, name no class (:func:`foreign_digits` tells them apart for
    messages).
    """
    t = text.strip().lower()
    if _ascii_digits(t):
        cid = f"{int(t):02d}"
        return cid if cid in CLASS_NAMES else None
    head, sep, rest = t.replace("_", " ", 1).partition(" ")
    if sep and _ascii_digits(head):
        cid = class_id_of(head)
        return cid if cid and class_id_of(rest) == cid else None
    return _BY_NAME.get(t.replace("_", "-").replace(" ", "-"))

CORNERS = ("A", "B", "C", "D")
SIDES = ("AB", "BC", "CD", "DA")

#: Variant strings of each class (SPEC section 3); ``None`` where there is none.
VARIANTS: dict[str, tuple[str | None, ...]] = {
    "01": (None,),
    "02": CORNERS,
    "03": CORNERS,
    "04": SIDES,
    "05": tuple(f"{s}/{c}" for s in SIDES for c in s),
    "06": ("AC", "BD"),
    "07": CORNERS,
    "08": (None,),
    "09": SIDES,
    "10": SIDES,
    "11": SIDES,
    "12": CORNERS,
}

#: A sticker this high above the table (mm) is on cloth held up (a flap being folded):
#: wrinkles stay below 10 mm and a folded layer adds a few. Not seen, it is unknown (on
#: a flap seen edge-on), not evidence of a layer lying on it.
LIFTED_MM = 20.0

#: A flap measured this many degrees past vertical (or short of it) counts as turned
#: past 90 degrees (or not) in full; nearer vertical, in proportion. SPEC's rule changes
#: the class at 90 degrees, and the lean of a flap is measured to a degree or two.
PAST_BAND_DEG = 3.0

#: Pairs of classes that differ only in where a flap lands: while a flap is held up
#: (a fold in progress), the nearest two being such a pair is "cannot tell" (two
#: adjacent corners folded: side by side, 04, or crossing, 05, as the second flap lies
#: down).
LANDING_PAIRS: tuple[frozenset[str], ...] = (frozenset({"04", "05"}),)

