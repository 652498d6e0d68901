"""Physics cloth: a MuJoCo flex-cloth napkin that carries out a plan's motion.

The isometric folds of :mod:`dgli_vision.sim.cloth` do what a plan says by construction;
this package folds a napkin that drags, sags and slips. :mod:`.model` builds the MuJoCo
model (the napkin's size from the layout, its mass, stiffness and friction in
:class:`~.model.ClothMaterial`), :mod:`.grippers` moves simulated grippers along a plan
step's path per hand and lets the cloth settle, and :mod:`.export` turns the cloth's
vertices back into a :class:`~dgli_vision.sim.cloth.states.ClothState` the project's
renderer draws and the classifier reads. MuJoCo is the optional ``physics`` extra
(``pip install dgli_vision[physics]``); :func:`require_mujoco` names it when missing.
"""

from __future__ import annotations

from typing import Any

from ...core.errors import MissingExtraError

__all__ = ["require_mujoco"]


def require_mujoco() -> Any:
    """The ``mujoco`` module.

    Raises
    ------
    MissingExtraError
        MuJoCo is not installed (the message names the extra).
    """
    try:
        import mujoco
    except ImportError:
        raise MissingExtraError(
            "physics cloth needs MuJoCo: pip install 'dgli_vision[physics]'"
        ) from None
    return mujoco
