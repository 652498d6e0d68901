"""dgli_vision: the state of a napkin from one RGB-D frame, by its dGLI cloth coordinates.

The one call from code is :func:`classify_pair`; the command line is ``dgli`` and
``dgli-classify``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

__all__ = ["classify_pair"]

if TYPE_CHECKING:
    from .classifier.api import classify_pair


def __getattr__(name: str) -> Any:
    # Lazy: importing the package (as every command does) stays cheap.
    if name == "classify_pair":
        from .classifier.api import classify_pair

        return classify_pair
    raise AttributeError(f"module 'dgli_vision' has no attribute {name!r}")
