"""Words for people: a count with its noun in the right number ("1 step", "2 steps")."""

from __future__ import annotations

__all__ = ["counted"]


def counted(n: int, noun: str, plural: str | None = None) -> str:
    """``n`` and ``noun``, singular for one and plural otherwise: ``counted(1, "pair")``
    is ``"1 pair"``, ``counted(3, "pair")`` ``"3 pairs"``.

    Parameters
    ----------
    n : int
    noun : str
        The singular.
    plural : str, optional
        The plural where it is not ``noun + "s"`` (``"episodes"`` is, ``"classes"`` not).
    """
    return f"{n} {noun if n == 1 else plural or noun + 's'}"
