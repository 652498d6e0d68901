"""dgli_vision: the state of a napkin from one RGB-D frame, by its dGLI cloth coordinates.

The one call from code is :func:`classify_pair`; the command line is ``dgli`` and
``dgli-classify``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

__all__ = ["classify_pair", "plan"]

if TYPE_CHECKING:
    from .classifier.api import classify_pair
    from .planning.api import plan


def __getattr__(name: str) -> Any:
    # Lazy: importing the package (as every command does) stays cheap.
    if name == "classify_pair":
        from .classifier.api import classify_pair

        return classify_pair
    if name == "plan":
        from .planning.api import plan

        return plan
    raise AttributeError(f"module 'dgli_vision' has no attribute {name!r}")
