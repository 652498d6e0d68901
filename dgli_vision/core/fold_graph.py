"""Which states are one fold apart, derived from the classes' definitions.

Every state (class and variant) is described by the folds it is made of (SPEC section 3):
a corner folded over or under, a strip, a half or a diagonal fold, and for two crossing
flaps which one lies on top (it was folded second). A state is one fold away from another
when its folds are the other's plus one more. That graph is what a folding robot can do
next, and what :mod:`dgli_vision.analysis.track` lets a sequence of frames move along.
"""

from __future__ import annotations

from functools import lru_cache

from .classes import CLASS_IDS, CORNERS, VARIANTS
from .errors import InvalidValueError

__all__ = [
    "StateKey",
    "fold_edges",
    "folds_of",
    "mirror_group",
    "neighbours",
    "state_keys",
    "unfold",
]

#: A state: (class id, variant).
StateKey = tuple[str, "str | None"]


def folds_of(class_id: str, variant: str | None) -> frozenset[str]:
    """The folds a state is made of, as words (``"A over"``, ``"AB half"``...).

    Parameters
    ----------
    class_id : str
    variant : str or None

    Returns
    -------
    frozenset of str
    """
    if variant not in VARIANTS.get(class_id, ()):
        raise InvalidValueError(f"unknown state {class_id}/{variant}")
    if class_id == "01":
        return frozenset()
    if class_id == "02":
        return frozenset({f"{variant} over"})
    if class_id == "03":
        return frozenset({f"{variant} under"})
    if class_id in ("04", "06"):
        return frozenset(f"{c} over" for c in variant)
    if class_id == "05":
        side, top = variant.split("/")
        first = side.replace(top, "")
        return frozenset({f"{first} over", f"{top} over crossing {first}"})
    if class_id == "07":
        return frozenset(f"{c} over" for c in CORNERS if c != variant)
    if class_id == "08":
        return frozenset(f"{c} over" for c in CORNERS)
    word = {"09": "strip over", "10": "strip under", "11": "half", "12": "diagonal"}[class_id]
    return frozenset({f"{variant} {word}"})


@lru_cache(maxsize=1)
def state_keys() -> tuple[StateKey, ...]:
    """Every state (class, variant), in class then variant order."""
    return tuple((c, v) for c in CLASS_IDS for v in VARIANTS[c])


@lru_cache(maxsize=1)
def _by_folds() -> dict[frozenset[str], StateKey]:
    return {folds_of(*key): key for key in state_keys()}


@lru_cache(maxsize=1)
def fold_edges() -> tuple[tuple[StateKey, StateKey, str], ...]:
    """Every (state, state one fold further, the fold), in state order."""
    by_folds = _by_folds()
    edges = []
    for key in state_keys():
        folds = folds_of(*key)
        for fold in sorted(folds):
            before = by_folds.get(folds - {fold})
            if before is not None:
                edges.append((before, key, fold))
    return tuple(sorted(edges, key=lambda e: (state_keys().index(e[0]), state_keys().index(e[1]))))


def neighbours(key: StateKey) -> tuple[StateKey, ...]:
    """States one fold or one unfold away from ``key``."""
    out = [b for a, b, _ in fold_edges() if a == key] + [a for a, b, _ in fold_edges() if b == key]
    return tuple(sorted(set(out), key=state_keys().index))


def unfold(key: StateKey, fold: str) -> StateKey:
    """The state ``key`` was in before ``fold`` (one of its folds) was made.

    Raises
    ------
    InvalidValueError
        When ``fold`` is not one of the state's folds, or taking it away leaves no state
        (the first flap of two crossing ones cannot be unfolded from under the second).
    """
    folds = folds_of(*key)
    if fold not in folds:
        raise InvalidValueError(f"{key[0]}/{key[1]} has no fold {fold!r}")
    before = _by_folds().get(folds - {fold})
    if before is None:
        raise InvalidValueError(f"unfolding {fold!r} from {key[0]}/{key[1]} leaves no state")
    return before


def mirror_group(key: StateKey) -> str:
    """The states that are mirror images of each other through the table plane, as one
    label (``"02/A|03/A"``; a state without a mirror partner keeps ``"12/B"``).

    Mirroring the cloth through the table turns every fold over into one under and
    reverses the order in which layers lie; the dGLI does not change (the linking
    integral changes sign, and so does the derivative's direction). So two states whose
    folds differ only by over / under, or, for two crossing flaps, by which flap lies on
    top, have the same cloth coordinates up to cloth thickness: 02 / 03 by corner,
    09 / 10 by side, and 05 ``XY/X`` / ``XY/Y``.
    """

    def shape(k: StateKey) -> tuple[frozenset[str], bool]:
        words, crossing = set(), False
        for w in folds_of(*k):
            w = w.replace(" over", "").replace(" under", "")
            if " crossing " in w:
                crossing, w = True, w.split(" crossing ")[0]
            words.add(w)
        return frozenset(words), crossing

    mine = shape(key)
    same = [k for k in state_keys() if shape(k) == mine]
    return "|".join(f"{c}/{v or ''}" for c, v in same)
