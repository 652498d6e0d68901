"""dgli_vision: the state of a napkin from one RGB-D frame, by its dGLI cloth coordinates.

The calls from code are :func:`classify_pair` (the state of one frame), :func:`plan`
(the next folds towards a goal) and :func:`verify` (did a fold work?); the command line
is ``dgli`` and ``dgli-classify``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

__all__ = ["classify_pair", "plan", "verify"]

if TYPE_CHECKING:
    from .classifier.api import classify_pair
    from .planning.api import plan, verify


def __getattr__(name: str) -> Any:
    # Lazy: importing the package (as every command does) stays cheap.
    if name == "classify_pair":
        from .classifier.api import classify_pair

        return classify_pair
    if name == "plan":
        from .planning.api import plan

        return plan
    if name == "verify":
        from .planning.api import verify

        return verify
    raise AttributeError(f"module 'dgli_vision' has no attribute {name!r}")
