"""The simulator's truth about a state's corners: where each is, its state, and
whether a robot could grasp it from above (nothing lies over it)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from ..core.classes import CORNERS
from ..core.fold_lines import nominal_folds
from ..core.layout import NapkinLayout
from ..sim.cloth.states import ClothState

__all__ = ["corner_truth"]

#: Cloth within this distance (m, in the table plane) above a corner covers it: a
#: corner peeking out less than a gripper finger from under a flap is not free.
COVER_RADIUS_M = 0.010
#: Cloth nearer than this on the flat napkin (mm) to the corner is the corner's own
#: layer, not a layer over it.
OWN_LAYER_MM = 25.0


def _parts(folds: tuple, uv: NDArray[np.float64]) -> NDArray[np.intp]:
    """The part of each material point: -1 the napkin that stays, else the last fold
    whose flap holds it (what is folded later lies on top)."""
    part = np.full(len(uv), -1)
    for j, f in enumerate(folds):
        part[f.on_flap(uv, 1.0)] = j
    return part


def corner_truth(
    state: ClothState, layout: NapkinLayout
) -> list[tuple[str, bool, NDArray[np.float64]]]:
    """Per corner A-D: its state (from the state's folds), whether it is graspable (a
    flat or folded-over corner with no other layer of cloth over it, from the mesh), and
    its world point (m)."""
    folds = nominal_folds(state.class_id, state.variant, layout)
    tree = cKDTree(state.mesh.xyz[:, :2])
    out = []
    for k, name in enumerate(CORNERS):
        fold = next((f for f in reversed(folds) if name in f.moved_corners), None)
        st = "flat" if fold is None else ("on a flap under" if fold.under else "on a flap over")
        p = state.corner_points[k]
        near = np.asarray(tree.query_ball_point(p[:2], COVER_RADIUS_M), dtype=np.intp)
        other = np.linalg.norm(state.mesh.uv[near] - layout.corner_uv[k], axis=1) > OWN_LAYER_MM
        above = state.mesh.xyz[near, 2] > p[2] + 0.5e-3
        later = _parts(folds, state.mesh.uv[near]) > _parts(folds, layout.corner_uv[k][None])[0]
        covered = bool(np.any(other & above & later))
        out.append((st, st in ("flat", "on a flap over") and not covered, p))
    return out
