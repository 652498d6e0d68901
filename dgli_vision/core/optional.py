"""The optional packages some commands need, imported where they are used: a missing one
is a one-line :class:`~dgli_vision.core.errors.MissingExtraError` naming the extra that
installs it, not a traceback.

Classifying needs none of them: ``pip install dgli_vision`` (the README's first
command) installs what classifying needs and nothing more; Open3D (about 0.9 GB with
what it brings) is the ``sim`` extra, for the renderer, the simulator's meshes and
``dgli label``.
"""

from __future__ import annotations

from types import ModuleType

from .errors import MissingExtraError

__all__ = ["open3d"]


def open3d(what: str = "rendering and cloth meshes") -> ModuleType:
    """The ``open3d`` module.

    Parameters
    ----------
    what : str
        What needs it, for the message.

    Raises
    ------
    MissingExtraError
        Open3D is not installed.
    """
    try:
        import open3d as o3d
    except ImportError:
        raise MissingExtraError(
            f"{what} needs Open3D, the 'sim' extra: pip install 'dgli_vision[sim]' "
            "(scripts/setup.sh --test installs it)"
        ) from None
    return o3d
