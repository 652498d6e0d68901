"""The simulated database: seeded cloth states of every class, and their records.

Generation is deterministic: state ``k`` of class ``c`` draws from its own generator,
seeded by ``(seed, c, k)``, so a database does not depend on the order it is built in.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..core.classes import LIFTED_MM
from ..core.dgli import cloth_coordinates
from ..core.errors import InvalidValueError
from ..core.fold_graph import fold_edges
from ..core.handedness import back_face_up, corner_turns
from ..core.layout import default_layout, sticker_spreads_mm
from .cloth.states import CLASS_IDS, VARIANTS, ClothState, sample_state

__all__ = [
    "FOLD_BINS_DEG",
    "LIFTED_MM",
    "StateRecords",
    "progress_id",
    "records_from_states",
    "simulate_folds_in_progress",
    "simulate_states",
    "state_id",
]

#: Fold angles (degrees) of the states with a fold in progress, in bins: each bin is a
#: group of its own in the reference set, so that a frame finds a near reference at any
#: point of a fold. 90 degrees is a bin edge: SPEC's rule changes the class there.
FOLD_BINS_DEG: tuple[tuple[float, float], ...] = (
    (10, 50), (50, 90), (90, 130), (130, 160), (160, 178)
)


def state_id(class_id: str, k: int) -> str:
    """Identifier of the k-th state of a class in a database, e.g. ``"02_007"``."""
    return f"{class_id}_{k:03d}"


def progress_id(
    before: tuple[str, str | None],
    after: tuple[str, str | None],
    fold: str,
    bin_deg: tuple[float, float],
    k: int,
) -> str:
    """Identifier (and file name) of a fold in progress: the state made, the one it is
    made from, the fold, the angle bin and the draw, e.g.
    ``"07-C_from_06-BD_A-over_050-090deg_00"``."""

    def key(state: tuple[str, str | None]) -> str:
        return state[0] + (f"-{state[1].replace('/', '-')}" if state[1] else "")

    lo, hi = bin_deg
    return (f"{key(after)}_from_{key(before)}_{fold.replace(' ', '-')}_"
            f"{lo:03.0f}-{hi:03.0f}deg_{k:02d}")


def simulate_states(
    per_class: int, seed: int, *, classes: tuple[str, ...] = CLASS_IDS, **kwargs
) -> list[tuple[str, ClothState]]:
    """Draw ``per_class`` states of each class, cycling through its variants.

    Parameters
    ----------
    per_class : int
        States per class.
    seed : int
        Seed of the whole database.
    classes : tuple of str, keyword-only
        Which classes (default all 12).
    **kwargs
        Passed to :func:`~dgli_vision.sim.cloth.states.sample_state` (``wrinkles``, ...).

    Returns
    -------
    list of (str, ClothState)
        ``(state id, state)`` in class order.
    """
    if per_class < 1:
        raise InvalidValueError(f"per_class must be at least 1, got {per_class}")
    out = []
    for class_id in classes:
        options = VARIANTS[class_id]
        for k in range(per_class):
            rng = np.random.default_rng([seed, int(class_id), k])
            variant = options[k % len(options)]
            out.append((state_id(class_id, k), sample_state(class_id, variant, rng, **kwargs)))
    return out


def simulate_folds_in_progress(
    per_group: int, seed: int, **kwargs
) -> list[tuple[str, ClothState]]:
    """States with a fold in progress: for every fold a robot can make on the table
    (every edge of :func:`~dgli_vision.core.fold_graph.fold_edges` but folds under, which
    cannot turn through the table) and every bin of :data:`FOLD_BINS_DEG`, ``per_group``
    states with that fold turned to an angle drawn in the bin.

    Each state is labelled by SPEC's 90-degree rule; ``params["stage"]`` names the fold
    and the bin (``"rising B over, 50-90 deg"``). State ``k`` of edge ``e`` and bin ``b``
    draws from a generator seeded by ``(seed, 100 + e, b, k)``.

    Returns
    -------
    list of (str, ClothState)
        ``(id, state)``, ids naming the state made, the one it is made from, the fold,
        the bin and the draw: ``"07-C_from_06-BD_A-over_050-090deg_00"``
        (:func:`progress_id`).
    """
    if per_group < 1:
        raise InvalidValueError(f"per_group must be at least 1, got {per_group}")
    out = []
    for e, (before, after, fold) in enumerate(fold_edges()):
        class_id, variant = after
        if "under" in fold:
            continue
        for b, (lo, hi) in enumerate(FOLD_BINS_DEG):
            for k in range(per_group):
                rng = np.random.default_rng([seed, 100 + e, b, k])
                angle = float(rng.uniform(lo, hi))
                state = sample_state(
                    class_id, variant, rng, last_fold=fold, last_fold_deg=angle, **kwargs
                )
                state.params["stage"] += f", {lo:g}-{hi:g} deg"
                out.append((progress_id(before, after, fold, (lo, hi), k), state))
    return out


@dataclass(frozen=True, eq=False)
class StateRecords:
    """The truth of n states as arrays (what references and comparisons need).

    Attributes
    ----------
    ids : tuple of str
    classes : tuple of str
    variants : tuple of (str or None)
    sticker_points : ndarray, shape (n, 16, 3)
        Metres, world frame (z up).
    visible : ndarray of bool, shape (n, 16)
    visible_fraction : ndarray, shape (n, 16)
    coordinates : ndarray, shape (n, 28)
        dGLI coordinates with all stickers known.
    corner_points : ndarray, shape (n, 4, 3)
        Corners A-D, metres.
    boundary : ndarray, shape (n, m, 3)
        Boundary polylines, metres.
    stages : tuple of str
        ``""`` for a state with every fold laid flat, else the fold in progress.
    footprint : ndarray, shape (n,), optional
        Table area each state's cloth covers, as a fraction of the flat napkin's area
        (NaN where not known, as in databases written before it was kept).
    """

    ids: tuple[str, ...]
    classes: tuple[str, ...]
    variants: tuple[str | None, ...]
    sticker_points: NDArray[np.float64]
    visible: NDArray[np.bool_]
    visible_fraction: NDArray[np.float64]
    coordinates: NDArray[np.float64]
    corner_points: NDArray[np.float64]
    boundary: NDArray[np.float64]
    stages: tuple[str, ...] = ()
    footprint: NDArray[np.float64] | None = None

    def __post_init__(self) -> None:
        if not self.stages:
            object.__setattr__(self, "stages", ("",) * len(self.ids))
        if self.footprint is None:
            object.__setattr__(self, "footprint", np.full(len(self.ids), np.nan))

    @property
    def lifted(self) -> NDArray[np.bool_]:
        """Stickers standing more than :data:`LIFTED_MM` above the table, shape (n, 16)."""
        return self.sticker_points[..., 2] > LIFTED_MM * 1e-3

    @property
    def unknown(self) -> NDArray[np.bool_]:
        """Stickers not visible that stand more than :data:`LIFTED_MM` above the table,
        shape (n, 16): on a flap held up, seen edge-on, which no camera can call
        hidden by cloth or not."""
        return ~self.visible & self.lifted

    @property
    def corner_turns(self) -> NDArray[np.float64]:
        """Which face each corner A-D shows seen from above, shape (n, 4): +1 front, -1
        back (on a flap folded over), 0 not told (its stickers seen edge on)."""
        return corner_turns(self.sticker_points[..., :2], default_layout())

    def seen_spreads_mm(self) -> NDArray[np.float64]:
        """Distances between the visible stickers of each pair, mm, shape (n, 120) (NaN
        where either is hidden)."""
        seen = np.where(self.visible[..., None], self.sticker_points * 1e3, np.nan)
        return sticker_spreads_mm(seen)

    def seen_back_faces(self) -> NDArray[np.float64]:
        """Which face each corner shows from above as a camera would tell it, shape
        (n, 4): 1 back, 0 front, NaN where fewer than three of its stickers are visible."""
        points = np.where(self.visible[..., None], self.sticker_points[..., :2], np.nan)
        return back_face_up(corner_turns(points, default_layout()))

    @property
    def past_vertical(self) -> NDArray[np.bool_]:
        """States whose fold in progress has turned past 90 degrees, shape (n,)."""
        return np.array([s.startswith("settling") for s in self.stages], dtype=bool)

    @property
    def folded(self) -> NDArray[np.bool_]:
        """States with every fold laid flat (no fold in progress), shape (n,)."""
        return np.array([not s for s in self.stages], dtype=bool)

    def __len__(self) -> int:
        return len(self.ids)

    def subset(self, index: NDArray) -> StateRecords:
        """The records at ``index`` (integer or boolean array)."""
        idx = np.arange(len(self))[index]
        return StateRecords(
            tuple(self.ids[i] for i in idx),
            tuple(self.classes[i] for i in idx),
            tuple(self.variants[i] for i in idx),
            self.sticker_points[idx],
            self.visible[idx],
            self.visible_fraction[idx],
            self.coordinates[idx],
            self.corner_points[idx],
            self.boundary[idx],
            tuple(self.stages[i] for i in idx),
            self.footprint[idx],
        )

    def hidden_coordinates(self) -> NDArray[np.float64]:
        """Coordinates with NaN for every pair involving a segment with a hidden end."""
        segs = self.sticker_points.reshape(len(self), -1, 2, 3).copy()
        hidden_seg = ~self.visible.reshape(len(self), -1, 2).all(axis=2)
        segs[hidden_seg] = np.nan
        return cloth_coordinates(segs)


def records_from_states(states: list[tuple[str, ClothState]]) -> StateRecords:
    """Collect the truth of ``(id, state)`` pairs into :class:`StateRecords`."""
    points = np.stack([s.sticker_points for _, s in states])
    return StateRecords(
        ids=tuple(i for i, _ in states),
        classes=tuple(s.class_id for _, s in states),
        variants=tuple(s.variant for _, s in states),
        sticker_points=points,
        visible=np.stack([s.visible for _, s in states]),
        visible_fraction=np.stack([s.visible_fraction for _, s in states]),
        coordinates=cloth_coordinates(points.reshape(len(states), -1, 2, 3)),
        corner_points=np.stack([s.corner_points for _, s in states]),
        boundary=np.stack([s.boundary for _, s in states]),
        stages=tuple(str(s.params.get("stage", "")) for _, s in states),
        footprint=np.array([footprint_fraction(s) for _, s in states]),
    )


def footprint_fraction(state: ClothState) -> float:
    """Table area the state's cloth covers, as a fraction of the flat napkin's area."""
    uv = state.mesh.uv
    flat = float(np.ptp(uv[:, 0]) * np.ptp(uv[:, 1]))
    return round(state.mesh.footprint_mm2() / flat, 4)
