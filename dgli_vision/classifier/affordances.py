"""What a robot can grasp: where each corner is, what state it is in, and the folds seen.

From a verdict and the evidence the pipeline already has (the stickers located in 3D,
the table plane, which face each corner shows, which stickers stand above the table):

- every state's folds are lines on the flat napkin (:mod:`dgli_vision.core.fold_lines`,
  the middle of the class's sizes), so each sticker lies on the napkin that stays or on
  one flap;
- folding is isometric, so each part (the napkin that stays, each flap) is a rigid
  map from the flat napkin to the camera frame, fitted to its stickers seen (with the
  face it shows: a flap folded over shows its back); a part with no sticker seen is the
  reflection, across its fold line, of the part it lies on;
- a corner is placed by its own stickers (two or more seen), else by the rigid map of
  its flap or of the napkin, and says which.

A corner is graspable from above when it is free and on top: lying flat or on a flap
folded over, with no flap lying over it.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, replace
from functools import lru_cache
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..core.camera import Intrinsics
from ..core.classes import CORNERS, LIFTED_MM
from ..core.fold_lines import NominalFold, nominal_folds, reflect_uv
from ..core.layout import CORNER_STICKERS, NapkinLayout
from ..core.order_stats import median
from .fold_geometry import FoldGeometry, fit_folds

__all__ = [
    "CORNER_STATES",
    "Affordances",
    "CornerAffordance",
    "CornerMap",
    "NapkinMaps",
    "RigidMap",
    "SeenFold",
    "SeenFolds",
    "affordances_of",
    "deferred_affordances",
    "napkin_maps",
]

#: The state of a corner.
CORNER_STATES = ("flat", "on a flap over", "on a flap under", "held up", "unknown")
#: How a corner's point was found.
PLACED_BY = ("stickers", "flap rigid map", "napkin rigid map")

#: A sticker seen farther than this from its part's fitted rigid map (m) is left out of
#: the fit (a misread sticker, or one on a wrinkle); the fit is made again without it.
FIT_TOLERANCE_M = 0.015
#: A point this near a fold line (mm on the flat napkin) counts as on the part that stays:
#: the ends of a diagonal fold are corners on the line itself.
ON_LINE_MM = 1.0
#: A corner lies under a flap when the flap covers its place by more than this (mm,
#: measured on the flat napkin): a corner on the fold line itself is not covered.
COVER_MARGIN_MM = 5.0


@dataclass(frozen=True, eq=False)
class RigidMap:
    """A rigid map from the flat napkin (material metres, z out of the front face) to
    the camera frame: ``x = R @ [u, v, 0] + t``."""

    rotation: NDArray[np.float64]
    translation: NDArray[np.float64]

    def __call__(self, uv_mm: NDArray[np.float64]) -> NDArray[np.float64]:
        """Camera-frame points (k, 3) of material points (k, 2) in mm."""
        uv = np.asarray(uv_mm, dtype=float).reshape(-1, 2)
        src = np.zeros((len(uv), 3))
        src[:, :2] = uv * 1e-3
        return src @ self.rotation.T + self.translation


def _kabsch(src: NDArray, dst: NDArray) -> tuple[NDArray, NDArray]:
    cs, cd, h = _cross_covariance(src, dst)
    u, _, vt = np.linalg.svd(h)
    return _kabsch_rotation(u, vt, cs, cd)


def _cross_covariance(src: NDArray, dst: NDArray) -> tuple[NDArray, NDArray, NDArray]:
    """The means of ``src`` and ``dst`` (k, 3) and their cross-covariance (3, 3), whose
    SVD gives the rotation (:func:`_kabsch_rotation`)."""
    # the means as ndarray.mean takes them (sum, then divide), without its overhead
    cs, cd = np.add.reduce(src, axis=0) / len(src), np.add.reduce(dst, axis=0) / len(dst)
    return cs, cd, (src - cs).T @ (dst - cd)


def _kabsch_rotation(
    u: NDArray, vt: NDArray, cs: NDArray, cd: NDArray
) -> tuple[NDArray, NDArray]:
    """The rotation and translation of :func:`_kabsch` from the SVD of its
    cross-covariance."""
    r = u @ vt
    if _det3(r) < 0:  # a reflection: turn the last axis round (u @ diag(1, 1, -1) @ vt)
        r = (u * np.array([1.0, 1.0, -1.0])) @ vt
    r = r.T
    return r, cd - r @ cs


def _det3(m: NDArray) -> float:
    """Determinant of a 3x3 matrix (here a rotation or a reflection: +1 or -1, whose sign
    is all that is read), without a LAPACK call."""
    (a, b, c), (d, e, f), (g, h, i) = m.tolist()
    return a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g)


#: A rigid map to fit (:func:`fit_map`'s arguments): material points (k, 2) in mm, camera
#: points (k, 3), the table's normal and the face shown.
MapProblem = tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], int]


def fit_map(
    uv_mm: NDArray[np.float64], points: NDArray[np.float64], up: NDArray[np.float64], face: int
) -> RigidMap | None:
    """The rigid map of material points (k, 2) onto camera points (k, 3), with the
    napkin's normal held to ``face * up`` (+1: front face up, -1: back face up), which
    makes two points enough. None with fewer than two points."""
    return fit_maps([(uv_mm, points, up, face)])[0]


def fit_maps(problems: list[MapProblem | None]) -> list[RigidMap | None]:
    """:func:`fit_map` of each problem (None: no map), all at once: each round's SVDs
    are one LAPACK call on their stack (each matrix's result the same as alone, to the
    bit), a frame's five or so fits costing one call instead of five."""
    out: list[RigidMap | None] = [None] * len(problems)
    lift = 0.05  # m: the virtual points along the normal
    active = []
    for i, problem in enumerate(problems):
        if problem is None:
            continue
        uv_mm, points, up, face = problem
        keep = np.isfinite(points).all(axis=1)
        every = bool(keep.all())  # (then no rows to pick)
        active.append([i, np.asarray(uv_mm, dtype=float), points, face * lift * up, keep, every])
    for _ in range(3):
        todo = []
        for fit in active:
            _, uv_all, points, along, keep, every = fit
            n = len(keep) if every else int(np.count_nonzero(keep))
            if n < 2:
                continue
            pts = points if every else points[keep]
            src = np.zeros((2 * n, 3))  # the points on the napkin, then lifted along z
            src[:n, :2] = src[n:, :2] = (uv_all if every else uv_all[keep]) * 1e-3
            src[n:, 2] = lift
            dst = np.concatenate([pts, pts + along], axis=0)
            todo.append((fit, n, pts, src, *_cross_covariance(src, dst)))
        if not todo:
            break
        u, _, vt = np.linalg.svd(np.stack([h for *_, h in todo]))
        active = []
        for (fit, n, pts, src, cs, cd, _), u_i, vt_i in zip(todo, u, vt):
            r, t = _kabsch_rotation(u_i, vt_i, cs, cd)
            out[fit[0]] = RigidMap(r, t)
            # the residuals of the points on the napkin: m(uv) of those points, whose
            # material coordinates are the first n rows of src (their lengths as
            # np.linalg.norm takes them, without its overhead)
            res = src[:n] @ r.T + t - pts
            res = np.sqrt(np.add.reduce(res * res, axis=1))
            worst = int(res.argmax())
            if res[worst] <= FIT_TOLERANCE_M or n <= 2:
                continue
            keep = fit[4]
            keep[np.flatnonzero(keep)[worst]] = False
            fit[5] = False
            active.append(fit)
    return out


@dataclass(frozen=True, eq=False)
class NapkinMaps:
    """The rigid maps of the parts of a folded napkin seen in one frame.

    Attributes
    ----------
    folds : tuple of NominalFold
        The verdict's folds, in the order they are made.
    stay : RigidMap or None
        The napkin that stays (front face up), fitted to its own stickers.
    flaps : tuple of (RigidMap or None)
        Each fold's flap, fitted to its own stickers.
    up : ndarray, shape (3,)
    offset : float
        ``up @ x`` of the table plane, m.
    thickness_m : float
    sticker_part : tuple of int
        The part each sticker lies on (as :meth:`part_of` gives it).
    """

    folds: tuple[NominalFold, ...]
    stay: RigidMap | None
    flaps: tuple[RigidMap | None, ...]
    up: NDArray[np.float64]
    offset: float
    thickness_m: float
    sticker_part: tuple[int, ...] = ()

    def part_of(self, uv_mm: NDArray[np.float64]) -> int:
        """The part a material point (2,) lies on: -1 the napkin that stays, else the
        index of the last fold whose flap holds it."""
        part = -1
        for j, f in enumerate(self.folds):
            if f.on_flap(np.atleast_2d(uv_mm), ON_LINE_MM)[0]:
                part = j
        return part

    def place(
        self, uv_mm: NDArray[np.float64], part: int | None = None
    ) -> tuple[NDArray[np.float64] | None, str]:
        """Where a material point (2,) is in the camera frame, and by which map
        (``"flap rigid map"`` for its own flap's, ``"napkin rigid map"`` otherwise).
        ``part``: the point's :meth:`part_of`, when already known."""
        q = np.asarray(uv_mm, dtype=float)
        j = self.part_of(q) if part is None else part
        if j >= 0 and self.flaps[j] is not None:
            return self.flaps[j](q)[0], PLACED_BY[1]
        if j >= 0:  # the flap is where its mirror image on the napkin is
            base = self.place_stay(reflect_uv(q, self.folds[j])[0])
            if base is None:
                return None, PLACED_BY[2]
            lift = -1.0 if self.folds[j].under else 1.0
            return base + lift * self.thickness_m * self.up, PLACED_BY[2]
        return self.place_stay(q), PLACED_BY[2]

    def place_stay(self, uv_mm: NDArray[np.float64]) -> NDArray[np.float64] | None:
        """A point of the napkin that stays (2,), from its map or, without one, from a
        flap lying on it (the mirror image across that flap's fold line)."""
        q = np.asarray(uv_mm, dtype=float)
        if self.stay is not None:
            return self.stay(q)[0]
        for f, m in zip(self.folds, self.flaps):
            if m is not None and not f.under:
                return m(reflect_uv(q, f))[0] - self.thickness_m * self.up
        return None

    def on_table(self, point: NDArray[np.float64]) -> NDArray[np.float64]:
        """A camera-frame point (3,) moved along ``up`` onto the table plane."""
        return point - (point @ self.up - self.offset) * self.up


def _table_offset(obs: Any) -> float:
    """``up @ x`` of the table plane, from the stickers' heights above it."""
    pts, h = obs.points_m, obs.heights_mm
    if pts is None or h is None:
        return float("nan")
    ok = np.isfinite(h) & np.isfinite(pts).all(axis=1)
    if not ok.any():
        return float("nan")
    return median(pts[ok] @ obs.up - h[ok] * 1e-3)


def _lying(obs: Any) -> NDArray[np.bool_]:
    """Stickers located and lying (not held up), shape (16,)."""
    h = obs.heights_mm if obs.heights_mm is not None else np.zeros(len(obs.visible))
    return obs.visible & ~(h > LIFTED_MM)  # (NaN, not known, is not above: as 0 mm)


def napkin_maps(
    obs: Any, class_id: str, variant: str | None, layout: NapkinLayout
) -> NapkinMaps:
    """The rigid maps of the napkin that stays and of each flap of the state
    ``class_id``/``variant``, fitted to the stickers of ``obs`` (a
    :class:`~dgli_vision.classifier.pipeline.ClothObservation`) lying on each."""
    plan = _plan(class_id, variant, layout)
    problems = _napkin_problems(obs, plan, layout)
    return _napkin_maps(obs, plan, layout, fit_maps(problems))


def _napkin_problems(obs: Any, plan: _Plan, layout: NapkinLayout) -> list[MapProblem | None]:
    """The fits of :func:`napkin_maps`: the napkin that stays, then each flap (None for
    a flap folded under)."""
    uv = np.asarray(layout.sticker_uv, dtype=float)
    pts = obs.points_m if obs.points_m is not None else np.full((len(uv), 3), np.nan)
    lying = _lying(obs)
    part = np.asarray(plan.sticker_part)
    seen = np.where(lying[:, None], pts, np.nan)
    on = part == -1
    problems: list[MapProblem | None] = [(uv[on], seen[on], obs.up, +1)]
    for j, f in enumerate(plan.folds):
        on = part == j
        problems.append(None if f.under else (uv[on], seen[on], obs.up, -1))
    return problems


def _napkin_maps(
    obs: Any, plan: _Plan, layout: NapkinLayout, fits: list[RigidMap | None]
) -> NapkinMaps:
    """:func:`napkin_maps` from the fits of :func:`_napkin_problems`."""
    return NapkinMaps(
        plan.folds, fits[0], tuple(fits[1:]), obs.up, _table_offset(obs),
        layout.thickness_mm * 1e-3, plan.sticker_part,
    )


@dataclass(frozen=True)
class _Plan:
    """What a state's folds say of the flat napkin, the same in every frame: the part
    each sticker and each corner lies on, which corners a flap covers, and for a corner
    at the end of a fold line the stickers of each flap it ends."""

    folds: tuple[NominalFold, ...]
    sticker_part: tuple[int, ...]
    corner_part: tuple[int, ...]
    covered: tuple[bool, ...]
    own_ids: tuple[tuple[int, ...], ...]
    on_line_ids: tuple[tuple[tuple[int, ...], ...], ...]


@lru_cache(maxsize=256)
def _plan(class_id: str, variant: str | None, layout: NapkinLayout) -> _Plan:
    """The :class:`_Plan` of a state, worked out once."""
    folds = nominal_folds(class_id, variant, layout)
    uv = np.asarray(layout.sticker_uv, dtype=float)
    part = np.full(len(uv), -1)
    for j, f in enumerate(folds):
        part[f.on_flap(uv, ON_LINE_MM)] = j  # as part_of, for every sticker at once
    sticker_part = tuple(int(p) for p in part)
    probe = NapkinMaps(folds, None, (), np.zeros(3), 0.0, 0.0, sticker_part)
    corner_part, covered, own_ids, on_line_ids = [], [], [], []
    for k in range(len(CORNERS)):
        corner_uv = np.asarray(layout.corner_uv[k], dtype=float)
        mine = probe.part_of(corner_uv)
        corner_part.append(mine)
        covered.append(_covered(folds, corner_uv, layout))
        own_ids.append(tuple(i for i in CORNER_STICKERS[k] if sticker_part[i] == mine))
        on_line_ids.append(tuple(
            tuple(i for i in CORNER_STICKERS[k] if sticker_part[i] == j)
            for j, f in enumerate(folds)
            if not f.under and abs(float(_signed_mm(corner_uv[None], f)[0])) <= ON_LINE_MM
        ))
    return _Plan(
        folds, sticker_part, tuple(corner_part), tuple(covered), tuple(own_ids),
        tuple(on_line_ids),
    )


@dataclass(frozen=True)
class CornerAffordance:
    """One corner as a robot sees it.

    Attributes
    ----------
    corner : str
        ``"A"`` ... ``"D"``.
    point : tuple of float or None
        Camera frame, metres.
    pixel : tuple of float or None
        Where the point is seen in the image.
    state : str
        One of :data:`CORNER_STATES`.
    graspable : bool
        Free and on top: lying flat or on a flap folded over, with no flap over it.
    placed_by : str or None
        ``"stickers"`` (its own, two or more seen), ``"flap rigid map"`` or
        ``"napkin rigid map"``; None where it could not be placed.
    """

    corner: str
    point: tuple[float, float, float] | None
    pixel: tuple[float, float] | None
    state: str
    graspable: bool
    placed_by: str | None

    def to_json(self) -> dict[str, Any]:
        """The JSON form (``{"point", "pixel", "state", "graspable", "placed_by"}``)."""
        return {
            "point": None if self.point is None else [round(v, 5) for v in self.point],
            "pixel": None if self.pixel is None else [round(v, 1) for v in self.pixel],
            "state": self.state,
            "graspable": self.graspable,
            "placed_by": self.placed_by,
        }


@dataclass(frozen=True)
class SeenFold:
    """One fold of the verdict as a line on the table.

    Attributes
    ----------
    fold : str
        The fold word (``"A over"``, ``"AB half"``...).
    corner, side : str or None
        The corner or the side it moved.
    under : bool
    line : tuple of two 3D points, or None
        Its two ends on the table, camera frame, metres.
    geometry : FoldGeometry or None
        Its sizes on the flat napkin (legs and tip, inset and skew, offset and turn),
        fitted to the stickers (:mod:`dgli_vision.classifier.fold_geometry`).
    """

    fold: str
    corner: str | None
    side: str | None
    under: bool
    line: tuple[tuple[float, float, float], tuple[float, float, float]] | None
    geometry: FoldGeometry | None = None

    def to_json(self) -> dict[str, Any]:
        """The JSON form (``{"fold", "corner" or "side", "under", "line"}`` and the
        geometry's keys: :meth:`FoldGeometry.to_json`)."""
        out: dict[str, Any] = {"fold": self.fold}
        out["corner" if self.corner else "side"] = self.corner or self.side
        out["under"] = self.under
        out["line"] = None if self.line is None else [
            [round(v, 5) for v in p] for p in self.line
        ]
        if self.geometry is not None:
            out.update(self.geometry.to_json())
        return out


class _Deferred:
    """A frame's :class:`Affordances`, worked out by ``work`` when first asked for and
    kept: what :func:`deferred_affordances`' corners and folds share."""

    __slots__ = ("_value", "_work")

    def __init__(self, work: Callable[[], Affordances]) -> None:
        self._work: Callable[[], Affordances] | None = work
        self._value: Affordances | None = None

    def __call__(self) -> Affordances:
        if self._work is not None:
            self._value, self._work = self._work(), None
        return self._value  # type: ignore[return-value]


class CornerMap(Mapping[str, "CornerAffordance"]):
    """Corners by name, read-only, in their order (A-D), as the JSON keys them:
    ``corners["A"]``, ``list(corners)`` the names, ``corners.values()`` the corners.
    Hashable and picklable, as the frozen results that hold it. The corners of
    :func:`deferred_affordances` are worked out when first read."""

    __slots__ = ("_given", "_source")

    def __init__(self, corners: Iterable[CornerAffordance] = ()) -> None:
        object.__setattr__(self, "_given", tuple(corners))
        object.__setattr__(self, "_source", None)

    @classmethod
    def _deferred(cls, source: _Deferred) -> CornerMap:
        out = cls()
        object.__setattr__(out, "_source", source)
        return out

    @property
    def _corners(self) -> tuple[CornerAffordance, ...]:
        if self._source is not None:
            object.__setattr__(self, "_given", tuple(self._source().corners.values()))
            object.__setattr__(self, "_source", None)
        return self._given

    def __getitem__(self, name: str) -> CornerAffordance:
        for c in self._corners:
            if c.corner == name:
                return c
        raise KeyError(name)

    def __iter__(self) -> Iterator[str]:
        return (c.corner for c in self._corners)

    def __len__(self) -> int:
        return len(self._corners)

    def __hash__(self) -> int:
        return hash(self._corners)

    def __setattr__(self, name: str, value: object) -> None:
        raise AttributeError("CornerMap is read-only")

    def __reduce__(self) -> tuple[type[CornerMap], tuple[tuple[CornerAffordance, ...]]]:
        return CornerMap, (self._corners,)

    def __repr__(self) -> str:
        return f"CornerMap({dict(self)!r})"


class SeenFolds(Sequence[SeenFold]):
    """The folds of :func:`deferred_affordances`, read-only, worked out when first
    read: a sequence of :class:`SeenFold` equal to the tuple of the same folds."""

    __slots__ = ("_given", "_source")

    def __init__(self, folds: Iterable[SeenFold] = ()) -> None:
        self._given: tuple[SeenFold, ...] = tuple(folds)
        self._source: _Deferred | None = None

    @classmethod
    def _deferred(cls, source: _Deferred) -> SeenFolds:
        out = cls()
        out._source = source
        return out

    @property
    def _folds(self) -> tuple[SeenFold, ...]:
        if self._source is not None:
            self._given, self._source = tuple(self._source().folds), None
        return self._given

    def __getitem__(self, i: Any) -> Any:
        return self._folds[i]

    def __len__(self) -> int:
        return len(self._folds)

    def __eq__(self, other: object) -> bool:
        if isinstance(other, (SeenFolds, tuple, list)):
            return self._folds == tuple(other)
        return NotImplemented

    def __hash__(self) -> int:
        return hash(self._folds)

    def __reduce__(self) -> tuple[type[SeenFolds], tuple[tuple[SeenFold, ...]]]:
        return SeenFolds, (self._folds,)

    def __repr__(self) -> str:
        return f"SeenFolds({self._folds!r})"


@dataclass(frozen=True)
class Affordances:
    """The corners A-D and the folds seen in one frame.

    ``corners`` is keyed by the corner's name, in the order A-D, as in the JSON:
    ``affordances.corners["A"].point`` (a :class:`CornerMap`).
    """

    corners: CornerMap
    folds: tuple[SeenFold, ...] | SeenFolds

    def to_json(self) -> dict[str, Any]:
        """``{"corners": {"A": {...}, ...}, "folds": [...]}``."""
        return {
            "corners": {name: c.to_json() for name, c in self.corners.items()},
            "folds": [f.to_json() for f in self.folds],
        }


def _held_up(lifted: NDArray[np.float64] | None, ids: tuple[int, ...]) -> bool:
    """Whether any of the stickers ``ids`` stands up (``lifted``: the observation's)."""
    if lifted is None:
        return False
    return any(lifted[i] >= 1.0 for i in ids)  # NaN (not told) is not standing


def _sticker_part(maps: NapkinMaps, i: int, layout: NapkinLayout) -> int:
    """The part sticker ``i`` lies on (kept by :func:`napkin_maps`, else worked out)."""
    if len(maps.sticker_part) == len(layout.sticker_uv):
        return maps.sticker_part[i]
    return maps.part_of(np.asarray(layout.sticker_uv[i], dtype=float))


def _own_fit(
    obs: Any,
    k: int,
    layout: NapkinLayout,
    face: int,
    maps: NapkinMaps | None = None,
    ids: tuple[int, ...] | None = None,
) -> NDArray[np.float64] | None:
    """Corner ``k`` placed by its own stickers seen (two or more; three for a corner
    held up, whose face is not known); with ``maps``, only those on the corner's part
    (a corner on a fold line has stickers on both sides of it): ``ids``, when already
    known."""
    uv, pts = _own_points(obs, k, layout, maps, ids)
    corner_uv = np.asarray(layout.corner_uv[k], dtype=float)
    if face == 0:
        ok = np.isfinite(pts).all(axis=1)
        if ok.sum() < 3:
            return None
        src = np.column_stack([uv[ok] * 1e-3, np.zeros(int(ok.sum()))])
        r, t = _kabsch(src, pts[ok])
        return r @ np.r_[corner_uv * 1e-3, 0.0] + t
    return _placed(fit_map(uv, pts, obs.up, face), corner_uv)


def _placed(m: RigidMap | None, uv_mm: NDArray[np.float64]) -> NDArray[np.float64] | None:
    """The point (3,) where ``m`` takes the material point ``uv_mm``; None without map."""
    return None if m is None else m(uv_mm)[0]


def _own_points(
    obs: Any,
    k: int,
    layout: NapkinLayout,
    maps: NapkinMaps | None = None,
    ids: tuple[int, ...] | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The material places (n, 2) and camera points (n, 3, NaN where not seen) of the
    stickers :func:`_own_fit` places corner ``k`` by."""
    if ids is not None:
        ids = list(ids)
    else:
        ids = list(CORNER_STICKERS[k])
        if maps is not None:
            mine = maps.part_of(np.asarray(layout.corner_uv[k], dtype=float))
            ids = [i for i in ids if _sticker_part(maps, i, layout) == mine]
    pts = obs.points_m[ids] if obs.points_m is not None else np.full((len(ids), 3), np.nan)
    pts = np.where(obs.visible[ids][:, None], pts, np.nan)
    return np.asarray(layout.sticker_uv, dtype=float)[ids], pts


def _on_line_fit(
    obs: Any, k: int, maps: NapkinMaps, layout: NapkinLayout, plan: _Plan | None = None
) -> NDArray[np.float64] | None:
    """A corner at the end of a fold line (a diagonal fold's) placed by its stickers on
    the flap: the fold leaves the points of its line where they were. ``plan``: the
    state's, whose folds are ``maps.folds``."""
    corner_uv = np.asarray(layout.corner_uv[k], dtype=float)[None]
    if plan is not None:
        flaps = [list(ids) for ids in plan.on_line_ids[k]]
    else:
        flaps = [
            [i for i in CORNER_STICKERS[k] if _sticker_part(maps, i, layout) == j]
            for j, f in enumerate(maps.folds)
            if not f.under and abs(float(_signed_mm(corner_uv, f)[0])) <= ON_LINE_MM
        ]
    for ids in flaps:
        pts = obs.points_m[ids] if obs.points_m is not None else None
        if pts is None:
            return None
        pts = np.where(_lying(obs)[ids][:, None], pts, np.nan)
        m = fit_map(np.asarray(layout.sticker_uv, dtype=float)[ids], pts, obs.up, -1)
        if m is not None:
            return m(corner_uv[0])[0]
    return None


def _signed_mm(uv: NDArray[np.float64], f: NominalFold) -> NDArray[np.float64]:
    a, b, c = (np.asarray(x, dtype=float) for x in (f.p0, f.p1, f.flap))
    t = (b - a) / np.linalg.norm(b - a)
    n = np.array([-t[1], t[0]])
    return (uv - a) @ (n if (c - a) @ n >= 0 else -n)


def _covered(folds: tuple[NominalFold, ...], corner_uv: NDArray, layout: NapkinLayout) -> bool:
    """Whether a flap lies over the corner once every fold is made (on the flat napkin's
    plan: the corner's landing place, mirrored across each later fold's line, falls
    inside that fold's flap)."""
    pos, last = np.asarray(corner_uv, dtype=float)[None], -1
    for j, f in enumerate(folds):
        if f.on_flap(pos, ON_LINE_MM)[0]:
            pos, last = reflect_uv(pos, f), j
    size = np.array([layout.width_mm, layout.height_mm])
    for j, f in enumerate(folds):
        if j <= last or f.under:
            continue
        back = reflect_uv(pos, f)
        inside = bool(np.all((back >= -1.0) & (back <= size + 1.0)))
        if inside and f.on_flap(back, COVER_MARGIN_MM)[0]:
            return True
    return False


#: :func:`_corner_of_verdict`'s ``own`` when not worked out beforehand.
_NOT_FITTED = object()


def _corner_state(fold: NominalFold | None, k: int, lifted: NDArray | None) -> str:
    """The state of corner ``k`` given the verdict: held up, or as the part it lies on
    (``fold``: the fold of its flap, None on the napkin that stays)."""
    if _held_up(lifted, CORNER_STICKERS[k]):
        return "held up"
    return "flat" if fold is None else ("on a flap under" if fold.under else "on a flap over")


#: The face a corner's stickers show in each state (0: not known, for a corner held up).
_FACE = {"flat": 1, "on a flap over": -1, "on a flap under": 1}


def _corner_of_verdict(
    obs: Any,
    k: int,
    maps: NapkinMaps,
    layout: NapkinLayout,
    lifted: NDArray | None,
    plan: _Plan | None = None,
    own: Any = _NOT_FITTED,
) -> tuple[str, bool, NDArray | None, str | None]:
    """State, graspable, point and how placed of corner ``k`` given the verdict
    (``plan``: the verdict's, whose folds are ``maps.folds``; ``own``: the corner placed
    by its own stickers, :func:`_own_fit`, when already worked out)."""
    corner_uv = np.asarray(layout.corner_uv[k], dtype=float)
    j = maps.part_of(corner_uv) if plan is None else plan.corner_part[k]
    fold = maps.folds[j] if j >= 0 else None
    state = _corner_state(fold, k, lifted)
    face = _FACE.get(state, 0)
    if own is _NOT_FITTED:
        own = _own_fit(obs, k, layout, face, maps, None if plan is None else plan.own_ids[k])
    point, how = own, PLACED_BY[0]
    if point is None and fold is None and state == "flat":
        point = _on_line_fit(obs, k, maps, layout, plan)
    if point is None and state != "held up":
        point, how = maps.place(corner_uv, j)
    if point is None:
        how = None
    free = state in ("flat", "on a flap over") and not (
        _covered(maps.folds, corner_uv, layout) if plan is None else plan.covered[k]
    )
    return state, bool(free and point is not None), point, how


def _corners_of_evidence(
    obs: Any, layout: NapkinLayout, lifted: NDArray | None
) -> list[tuple[str, bool, NDArray | None, str | None]]:
    """State, graspable, point and how placed of each corner without a verdict: from
    its own stickers alone (the face they show, whether they stand up); the rigid maps
    of the corners lying flat or folded over fitted together (:func:`fit_maps`)."""
    faces: list[int | None] = []
    for k, ids in enumerate(CORNER_STICKERS[: len(CORNERS)]):
        if _held_up(lifted, ids):
            faces.append(0)
            continue
        turn = 0.0 if obs.turns is None else float(obs.turns[k])
        if int(obs.visible[list(ids)].sum()) < 2 or turn == 0:
            faces.append(None)  # unknown
        else:
            faces.append(1 if turn > 0 else -1)
    fits = fit_maps([
        None if not face else (*_own_points(obs, k, layout), obs.up, face)
        for k, face in enumerate(faces)
    ])
    out: list[tuple[str, bool, NDArray | None, str | None]] = []
    for k, (face, m) in enumerate(zip(faces, fits)):
        if face == 0:
            out.append(("held up", False, _own_fit(obs, k, layout, 0), PLACED_BY[0]))
        elif face is None:
            out.append(("unknown", False, None, None))
        else:
            point = _placed(m, np.asarray(layout.corner_uv[k], dtype=float))
            state = "flat" if face > 0 else "on a flap over"
            placed = point is not None
            out.append((state, placed, point, PLACED_BY[0] if placed else None))
    return out


def affordances_of(
    obs: Any,
    class_id: str | None,
    variant: str | None,
    layout: NapkinLayout,
    intrinsics: Intrinsics,
    *,
    frame: Any = None,
) -> Affordances:
    """The corners and folds of one frame.

    Parameters
    ----------
    obs : ClothObservation
        What the pipeline saw (stickers in 3D, table normal, heights, faces).
    class_id, variant : str or None
        The verdict; None when it could not be told (the corners are then judged from
        their own stickers alone, and no fold is given).
    layout : NapkinLayout
    intrinsics : Intrinsics
        To give each point's pixel.
    frame : RGBDFrame, keyword-only, optional
        The frame itself: where the stickers do not fix a half or diagonal fold's
        crease (or a flap under's), the napkin's outline in it does
        (:mod:`~dgli_vision.classifier.fold_outline`).

    Returns
    -------
    Affordances
    """
    lifted = obs.lifted  # worked out from the evidence: once, not per corner
    maps, plan = None, None
    if class_id:
        plan = _plan(class_id, variant, layout)
        maps, own = _verdict_fits(obs, plan, layout, lifted)
        judged = [
            _corner_of_verdict(obs, k, maps, layout, lifted, plan, own[k])
            for k in range(len(CORNERS))
        ]
    else:
        judged = _corners_of_evidence(obs, layout, lifted)
    # every point in front of the camera projected at once (point by point, the same)
    front = [k for k, (_, _, point, _) in enumerate(judged) if point is not None and point[2] > 0]
    pixels: dict[int, tuple[float, float]] = {}
    if front:
        px = intrinsics.project(np.stack([judged[k][2] for k in front]))
        pixels = {k: (float(p[0]), float(p[1])) for k, p in zip(front, px)}
    corners = [
        CornerAffordance(
            name, None if point is None else tuple(point.tolist()), pixels.get(k),
            state, free, how,
        )
        for k, (name, (state, free, point, how)) in enumerate(zip(CORNERS, judged))
    ]
    folds: tuple[SeenFold, ...] = ()
    if maps is not None and plan is not None:
        outline = None
        if frame is not None:
            from .fold_outline import outline_fit

            outline = outline_fit(frame, obs)
        sizes = fit_folds(obs, maps.folds, plan.sticker_part, layout, outline=outline)
        folds = tuple(
            replace(_seen_fold(maps, j, corners), geometry=sizes[j])
            for j in range(len(maps.folds))
        )
    return Affordances(CornerMap(corners), folds)


def deferred_affordances(work: Callable[[], Affordances]) -> Affordances:
    """Affordances worked out by ``work`` only when their corners or folds are first
    read (``work`` runs once; pickling works them out): a frame classified for its
    verdict alone (``evaluate`` without tracking, the benchmarks) never pays for its
    grasp geometry, and one whose JSON gives ``corners`` and ``folds`` gets the same
    ones as :func:`affordances_of` itself.

    Parameters
    ----------
    work : callable
        ``work()`` returns the :class:`Affordances` (e.g. :func:`affordances_of` with its
        arguments bound).

    Returns
    -------
    Affordances
        Whose ``corners`` is a :class:`CornerMap` and ``folds`` a :class:`SeenFolds`.
    """
    source = _Deferred(work)
    return Affordances(CornerMap._deferred(source), SeenFolds._deferred(source))


def _verdict_fits(
    obs: Any, plan: _Plan, layout: NapkinLayout, lifted: NDArray | None
) -> tuple[NapkinMaps, list[Any]]:
    """The napkin's maps (:func:`napkin_maps`) and each corner placed by its own stickers
    (:func:`_own_fit`; :data:`_NOT_FITTED` for a corner held up), their rigid maps
    fitted together (:func:`fit_maps`)."""
    napkin = _napkin_problems(obs, plan, layout)
    problems = list(napkin)
    faces = []
    for k in range(len(CORNERS)):
        j = plan.corner_part[k]
        face = _FACE.get(_corner_state(plan.folds[j] if j >= 0 else None, k, lifted), 0)
        faces.append(face)
        if face != 0:
            uv, pts = _own_points(obs, k, layout, ids=plan.own_ids[k])
            problems.append((uv, pts, obs.up, face))
    fits = fit_maps(problems)
    maps = _napkin_maps(obs, plan, layout, fits[: len(napkin)])
    own: list[Any] = []
    rest = iter(fits[len(napkin):])
    for k, face in enumerate(faces):
        corner_uv = np.asarray(layout.corner_uv[k], dtype=float)
        own.append(_NOT_FITTED if face == 0 else _placed(next(rest), corner_uv))
    return maps, own


def fold_line_3d(
    maps: NapkinMaps, fold: NominalFold
) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
    """The two ends of a fold line on the table (camera frame): the nominal line's ends
    placed on the napkin that stays."""
    ends = [maps.place_stay(np.asarray(p)) for p in (fold.p0, fold.p1)]
    if any(e is None for e in ends):
        return None
    return maps.on_table(ends[0]), maps.on_table(ends[1])


def _seen_fold(maps: NapkinMaps, j: int, corners: list[CornerAffordance]) -> SeenFold:
    """Fold ``j`` as seen: its line through the middle of the moved corner (where it
    lies) and its flat place (perpendicular to the two), ends at the nominal line's."""
    f = maps.folds[j]
    ends = fold_line_3d(maps, f)
    if ends is not None:
        tips = [corners[CORNERS.index(c)].point for c in f.moved_corners]
        flat = maps.place_stay(np.asarray(f.flap))
        if flat is not None and all(t is not None for t in tips):
            tip = maps.on_table(np.mean(np.asarray(tips, dtype=float), axis=0))
            ends = bisector_through(tip, maps.on_table(flat), ends, maps.up)
    line = None if ends is None else tuple(tuple(e.tolist()) for e in ends)
    return SeenFold(f.word, f.corner, f.side, f.under, line)


def bisector_through(
    a: NDArray[np.float64],
    b: NDArray[np.float64],
    ends: tuple[NDArray[np.float64], NDArray[np.float64]],
    up: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The perpendicular bisector of ``a`` -> ``b`` in the table plane, as the segment
    between the projections of ``ends`` onto it (``ends`` unchanged when a and b meet)."""
    d = b - a
    # (the lengths as np.linalg.norm takes a vector's, sqrt(x . x), without its overhead)
    if math.sqrt(d.dot(d)) < 1e-6:
        return ends
    mid = 0.5 * (a + b)
    (u0, u1, u2), (d0, d1, d2) = np.asarray(up, dtype=float).tolist(), d.tolist()
    along = np.array([u1 * d2 - u2 * d1, u2 * d0 - u0 * d2, u0 * d1 - u1 * d0])  # up x d
    along /= math.sqrt(along.dot(along))
    return tuple(mid + ((e - mid) @ along) * along for e in ends)  # type: ignore[return-value]
