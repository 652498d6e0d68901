"""Cloth-state simulator: flat mesh, isometric folds, the 12 states, folding sequences."""

from .fold import fold
from .mesh import ClothMesh, flat_mesh
from .states import CLASS_IDS, CLASS_NAMES, VARIANTS, ClothState, sample_state

__all__ = [
    "CLASS_IDS",
    "CLASS_NAMES",
    "VARIANTS",
    "ClothMesh",
    "ClothState",
    "flat_mesh",
    "fold",
    "sample_state",
]
