"""Each fold's geometry in millimetres, fitted to the stickers seen in 3D.

Folding is an isometry: a flap is the napkin mirrored across its crease. So with the
napkin that stays placed on the table by a rigid map ``S`` (material mm -> table
plane), every sticker seen on flap ``j`` lies at ``S(reflect_j(m))``, ``m`` its
material position and ``reflect_j`` the mirror across the crease, a line on the flat
napkin. One least-squares fit (Gauss-Newton, in the table plane) finds ``S`` and every
crease at once from all the stickers seen lying down: those of the napkin that stays fix
``S``; each flap's fix its crease (one sticker is enough once ``S`` is fixed: the
crease is the perpendicular bisector of the sticker's material place and where it lies).
Without two stickers seen on the napkin that stays, ``S`` is fixed only by three or more
flaps (each flap's map must be a pure mirror, with no slide along its crease: four
corners folded to the centre).

The sizes (legs and tip, inset and skew, offset and turn:
:mod:`dgli_vision.core.fold_measure`) follow from each crease, with a standard
deviation from the fit's covariance (the residuals of the stickers seen, pooled with a
floor for how well a sticker is located). A fold whose crease no sticker seen fixes
(a flap folded under, whose stickers are hidden; a half or diagonal fold that hides the
napkin beneath; a flap held up) has ``None`` sizes and a ``why``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from functools import lru_cache
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..core.classes import LIFTED_MM
from ..core.fold_lines import NominalFold
from ..core.fold_measure import Crease, fold_kind, fold_measures
from ..core.layout import NapkinLayout

__all__ = [
    "FoldGeometry",
    "empty_geometry",
    "fit_folds",
    "geometry_from_crease",
    "initial_flaps",
    "mirror_crease_fit",
    "plane_basis",
    "rigid_fit_2d",
    "rotation_2d",
    "solve_flaps",
]

#: How well a sticker lying on the napkin is placed in the table plane (mm, one
#: coordinate): the floor of the fit's noise, pooled with the residuals.
STICKER_SD_MM = 2.0
#: Weight of :data:`STICKER_SD_MM` against the residuals, in degrees of freedom.
PRIOR_DOF = 4.0
#: The reported standard deviations are the fit's, times this: the fit's covariance
#: leaves out how the cloth bends near its crease and wrinkles (calibrated on renders,
#: see docs/folds.md).
SD_SCALE = 1.5
#: A sticker farther than this from where the fit puts it (mm) is left out and the fit
#: made again (a misread sticker, or one a flap half covers).
OUTLIER_MM = 12.0
#: A crease less sure than this (the sd of its line at the napkin's edge, mm) is not
#: reported: the stickers seen do not fix it.
MAX_SD_MM = 25.0


@dataclass(frozen=True)
class FoldGeometry:
    """One fold's sizes on the flat napkin, as measured.

    Attributes
    ----------
    word : str
        The fold word.
    kind : str
        ``"corner"``, ``"side"`` or ``"diagonal"``.
    values : dict
        ``legs_mm`` (edge -> mm) and ``tip_mm`` ([u, v]); ``inset_mm`` and
        ``skew_deg``; or ``offset_mm`` and ``turn_deg``. None where not fixed.
    sd : dict
        The standard deviation of each value (``legs_sd_mm``, ``tip_sd_mm``: the RMS
        distance, ...); None where not fixed.
    crease : Crease or None
        The fitted crease on the flat napkin.
    stickers : int
        Stickers of the flap the fit used.
    rms_mm : float or None
        RMS distance of the stickers used from where the fit puts them.
    why : str or None
        Why the sizes are None.
    """

    word: str
    kind: str
    values: dict[str, Any]
    sd: dict[str, Any]
    crease: Crease | None = None
    stickers: int = 0
    rms_mm: float | None = None
    why: str | None = None
    source: str = "stickers"
    crease_ends: list[list[float]] | None = None

    def to_json(self) -> dict[str, Any]:
        """The fold's JSON keys: the values, each with its ``_sd`` twin, ``crease_mm``
        (two points of the crease on the napkin's outline), ``geometry_from``,
        ``geometry_stickers``, ``geometry_rms_mm`` and ``why``."""
        out: dict[str, Any] = {}
        for key, value in self.values.items():
            out[key] = _round(value)
            sd_key = key.replace("_mm", "_sd_mm").replace("_deg", "_sd_deg")
            out[sd_key] = _round(self.sd.get(sd_key))
        out["crease_mm"] = _round(self.crease_ends)
        out["geometry_from"] = self.source
        out["geometry_stickers"] = self.stickers
        out["geometry_rms_mm"] = _round(self.rms_mm)
        out["why"] = self.why
        return out


def _round(v: Any, nd: int = 1) -> Any:
    if v is None:
        return None
    if isinstance(v, dict):
        return {k: _round(x, nd) for k, x in v.items()}
    if isinstance(v, (list, tuple, np.ndarray)):
        return [_round(x, nd) for x in v]
    f = float(v)
    return round(f, nd) if math.isfinite(f) else None


def empty_geometry(word: str, why: str) -> FoldGeometry:
    """The geometry of fold ``word`` that could not be measured: its kind's keys, each
    None, and ``why`` (what :mod:`~dgli_vision.labelling.fold_mesh` also gives)."""
    kind, _ = fold_kind(word)
    if kind == "corner":
        keys = ("legs_mm", "tip_mm")
    elif kind == "side":
        keys = ("inset_mm", "skew_deg")
    else:
        keys = ("offset_mm", "turn_deg")
    values = {k: None for k in keys}
    if kind == "corner":
        from ..core.fold_measure import leg_edges

        values["legs_mm"] = {e: None for e in leg_edges(word.split(" ")[0])}
    return FoldGeometry(word, kind, values, {}, why=why)


def _measure_vector(word: str, crease: Crease, layout: NapkinLayout) -> tuple[dict, list]:
    m = fold_measures(word, crease, layout)
    flat: list[float] = []
    for v in m.values():
        if isinstance(v, dict):
            flat += [math.nan if x is None else float(x) for x in v.values()]
        elif isinstance(v, list):
            flat += [float(x) for x in v]
        else:
            flat.append(math.nan if v is None else float(v))
    return m, flat


def geometry_from_crease(
    word: str,
    crease: Crease,
    layout: NapkinLayout,
    cov: NDArray[np.float64] | None = None,
    *,
    stickers: int = 0,
    rms_mm: float | None = None,
    source: str = "stickers",
) -> FoldGeometry:
    """The :class:`FoldGeometry` of a crease ``n . x = c`` with the covariance ``cov``
    (2 x 2, of its normal angle in radians and its offset c in mm; None: exact)."""
    kind, _ = fold_kind(word)
    m, base = _measure_vector(word, crease, layout)
    sd_flat = [0.0] * len(base)
    if cov is not None:
        (px, py), (tx, ty) = crease.point, crease.direction
        alpha = math.atan2(tx, -ty)  # the normal (-ty, tx)
        c = -ty * px + tx * py
        _, d_a = _measure_vector(word, Crease.from_normal(alpha + 1e-4, c), layout)
        _, d_c = _measure_vector(word, Crease.from_normal(alpha, c + 1e-2), layout)
        (caa, cac), (_, ccc) = cov.tolist()
        sd_flat = []
        for b, va, vc in zip(base, d_a, d_c):
            ga, gc = (va - b) / 1e-4, (vc - b) / 1e-2
            var = ga * ga * caa + 2.0 * ga * gc * cac + gc * gc * ccc
            sd_flat.append(SD_SCALE * math.sqrt(var) if var > 0 else 0.0)
    sd: dict[str, Any] = {}
    k = 0
    for key, v in m.items():
        sd_key = key.replace("_mm", "_sd_mm").replace("_deg", "_sd_deg")
        if isinstance(v, dict):
            sd[sd_key] = {e: (None if v[e] is None else sd_flat[k + i]) for i, e in enumerate(v)}
            k += len(v)
        elif isinstance(v, list):
            sd[sd_key] = math.hypot(sd_flat[k], sd_flat[k + 1])
            k += 2
        else:
            sd[sd_key] = None if v is None else sd_flat[k]
            k += 1
    ends = crease.ends_in(layout)
    return FoldGeometry(word, kind, m, sd, crease, stickers, rms_mm, None, source, ends)


def plane_basis(up: NDArray[np.float64]) -> NDArray[np.float64]:
    """Two unit vectors (2, 3) spanning the table plane, with e1 x e2 = up."""
    u0, u1, u2 = (float(v) for v in up)
    a = (1.0, 0.0, 0.0) if abs(u0) < 0.9 else (0.0, 1.0, 0.0)
    d = a[0] * u0 + a[1] * u1 + a[2] * u2
    e = (a[0] - d * u0, a[1] - d * u1, a[2] - d * u2)
    norm = math.sqrt(e[0] ** 2 + e[1] ** 2 + e[2] ** 2)
    e = (e[0] / norm, e[1] / norm, e[2] / norm)
    f = (u1 * e[2] - u2 * e[1], u2 * e[0] - u0 * e[2], u0 * e[1] - u1 * e[0])  # up x e1
    return np.array([e, f])


def mirror_crease_fit(m: NDArray, q: NDArray) -> tuple[float, float] | None:
    """The crease (normal angle, offset) whose mirror takes material points ``m`` (k, 2)
    nearest to ``q``: the perpendicular bisector for one point, else the best
    reflection's axis (closed form) and the mean of the bisectors' offsets."""
    if len(m) == 0:
        return None
    if len(m) == 1:
        dx, dy = float(q[0, 0] - m[0, 0]), float(q[0, 1] - m[0, 1])
        if math.hypot(dx, dy) < 1e-6:
            return None
        alpha = math.atan2(dy, dx)
        mid = 0.5 * (m[0] + q[0])
        return alpha, float(math.cos(alpha) * mid[0] + math.sin(alpha) * mid[1])
    mc, qc = m - m.mean(axis=0), q - q.mean(axis=0)
    a = float(np.sum(qc[:, 0] * mc[:, 0] - qc[:, 1] * mc[:, 1]))
    b = float(np.sum(qc[:, 0] * mc[:, 1] + qc[:, 1] * mc[:, 0]))
    alpha = 0.5 * math.atan2(b, a) + 0.5 * math.pi  # the normal of the best axis
    n = np.array([math.cos(alpha), math.sin(alpha)])
    return alpha, float(np.mean((m + q) @ n) * 0.5)


def rigid_fit_2d(m: NDArray, p: NDArray) -> tuple[float, NDArray]:
    """The rotation angle and translation of the proper rigid map nearest to taking
    ``m`` (k, 2) onto ``p`` (k >= 2)."""
    # (the means and sums as ndarray.mean and np.sum take them, without their overhead)
    m_mean = np.add.reduce(m, axis=0) / len(m)
    p_mean = np.add.reduce(p, axis=0) / len(p)
    mc, pc = m - m_mean, p - p_mean
    a = float(np.add.reduce(mc[:, 0] * pc[:, 0] + mc[:, 1] * pc[:, 1]))
    b = float(np.add.reduce(mc[:, 0] * pc[:, 1] - mc[:, 1] * pc[:, 0]))
    th = math.atan2(b, a)
    r = np.array([[math.cos(th), -math.sin(th)], [math.sin(th), math.cos(th)]])
    return th, p_mean - r @ m_mean


def rotation_2d(th: float) -> tuple[NDArray, NDArray]:
    """The 2D rotation by ``th`` (radians) and its derivative in ``th``, (2, 2) each."""
    c, s = math.cos(th), math.sin(th)
    return np.array([[c, -s], [s, c]]), np.array([[-s, -c], [c, -s]])


def solve_flaps(
    m: NDArray, p: NDArray, g: NDArray, x: NDArray, k: int
) -> tuple[NDArray, NDArray, NDArray]:
    """Gauss-Newton on x = (theta, tau_u, tau_v, alpha_1, c_1, ...): material points
    ``m`` (N, 2) seen at ``p`` (N, 2) in the table plane, each on part ``g`` (-1 the
    napkin that stays, j the j-th flap). Returns x, J^T J and the residuals (N, 2)."""
    n_pts, n_par = len(m), 3 + 2 * k
    on_flap = g >= 0
    gi = np.where(on_flap, g, 0)
    rows = np.arange(n_pts)
    jac = np.zeros((n_pts, 2, n_par))
    jac[:, 0, 1] = 1.0
    jac[:, 1, 2] = 1.0
    flap_rows, flap_g = rows[on_flap], gi[on_flap]
    col_a, col_c = 3 + 2 * flap_g, 4 + 2 * flap_g
    has_flaps = len(flap_rows) > 0
    c_mask = np.where(on_flap, 1.0, 0.0)
    n = np.empty((n_pts, 2))  # each point's crease normal (0 on the napkin that stays)
    nt = np.empty((n_pts, 2))  # and its direction
    for _ in range(5):
        rot, drot = rotation_2d(x[0])
        alpha, c = x[3::2], x[4::2]
        n[:, 0] = np.cos(alpha[gi])
        n[:, 1] = np.sin(alpha[gi])
        n *= c_mask[:, None]
        s = np.add.reduce(m * n, axis=1) - c[gi] * c_mask
        ref = m - 2.0 * s[:, None] * n
        res = ref @ rot.T + x[1:3] - p
        jac[:, :, 0] = ref @ drot.T
        if has_flaps:
            np.negative(n[:, 1], out=nt[:, 0])
            nt[:, 1] = n[:, 0]
            along = np.add.reduce(m * nt, axis=1)
            d_a = (-2.0 * along[:, None] * n - 2.0 * s[:, None] * nt) @ rot.T
            d_c = 2.0 * n @ rot.T
            jac[flap_rows, :, col_a] = d_a[flap_rows]
            jac[flap_rows, :, col_c] = d_c[flap_rows]
        jm = jac.reshape(2 * n_pts, n_par)
        jtj = jm.T @ jm
        rhs = -(jm.T @ res.reshape(-1))
        try:
            step = np.linalg.solve(jtj, rhs)
        except np.linalg.LinAlgError:
            step = np.linalg.lstsq(jtj, rhs, rcond=None)[0]
        x = x + step
        # (the residuals and J^T J of the last pass stand for the solution's: the
        # last step is below a hundredth of a mm)
        if float(np.maximum.reduce(np.abs(step))) < 1e-5:
            break
    return x, jtj, res


def fit_folds(
    obs: Any,
    folds: tuple[NominalFold, ...],
    sticker_part: tuple[int, ...],
    layout: NapkinLayout,
    *,
    outline: Callable[..., Any] | None = None,
) -> tuple[FoldGeometry, ...]:
    """The geometry of each of the verdict's folds, fitted to the stickers of ``obs``
    (a :class:`~dgli_vision.classifier.pipeline.ClothObservation`) lying on the table
    (see the module's description); where they do not fix a half fold's, a diagonal
    fold's or a flap folded under's crease, fitted to the napkin's outline in
    ``outline`` (:mod:`dgli_vision.classifier.fold_outline`).

    Parameters
    ----------
    obs : ClothObservation
    folds : tuple of NominalFold
        The verdict's folds (their nominal lines tell which stickers lie on which flap).
    sticker_part : tuple of int
        The part each sticker lies on: -1 the napkin that stays, else the fold's index.
    layout : NapkinLayout
    outline : callable, keyword-only, optional
        The outline fit of the frame (:func:`~dgli_vision.classifier.fold_outline.outline_fit`):
        called as ``outline(obs, fold, j, part, lying, layout)`` only when a fold needs
        it, it gives the fold's geometry, why not (a string), or None where the frame
        cannot be read; None: the stickers only.

    Returns
    -------
    tuple of FoldGeometry
        One per fold, in the order of ``folds``.
    """
    if not folds:
        return ()
    n = len(layout.sticker_uv)
    pts = obs.points_m if obs.points_m is not None else np.full((n, 3), np.nan)
    h = obs.heights_mm if obs.heights_mm is not None else np.zeros(n)
    seen = np.asarray(obs.visible, dtype=bool) & np.isfinite(pts).all(axis=1)
    lifted = seen & (h > LIFTED_MM)  # (NaN, not known, is not above: as 0 mm)
    lying = seen & ~lifted
    part = np.asarray(sticker_part) if len(sticker_part) == n else np.full(n, -1)
    n_stay = int(np.count_nonzero(lying & (part == -1)))
    active: list[int] = []
    why: dict[int, str] = {}
    big = 0
    for j, f in enumerate(folds):
        mine = part == j
        count = int(np.count_nonzero(mine & lying))
        if f.under:
            why[j] = "the flap lies under the napkin: none of its stickers can be seen"
        elif count == 0:
            held = bool(np.any(mine & lifted))
            why[j] = (
                "the flap is held up: its stickers stand above the table" if held
                else "none of the flap's stickers is seen"
            )
        else:
            active.append(j)
            big += count >= 2
    fixed = n_stay >= 2 or (n_stay == 1 and big >= 1) or big >= 3
    if active and not fixed:
        seen_stay = "no sticker" if n_stay == 0 else "only one sticker"
        reason = (
            f"{seen_stay} seen on the napkin under the flap (two are needed to place it, "
            "or three flaps seen): the crease is not fixed"
        )
        why.update({j: reason for j in active})
        active = []
    results: dict[int, FoldGeometry] = {}
    if active:
        basis = plane_basis(obs.up)
        p2 = (np.nan_to_num(pts) @ basis.T) * 1e3
        fitted = np.zeros(len(folds) + 1, dtype=bool)  # part -> in the fit ([-1]: stays)
        fitted[active] = fitted[-1] = True
        use = lying & fitted[part]
        results = _fit(p2, part, use, active, folds, layout)
    out = [
        results.get(j)
        or empty_geometry(f.word, why.get(j, "the stickers seen do not fix the crease"))
        for j, f in enumerate(folds)
    ]
    if outline is not None and len(folds) == 1:
        # (one fold: the outline is its edge and the napkin's, no other flap's)
        out = [_from_outline(obs, folds[0], 0, part, lying, layout, outline, out[0])]
    return tuple(out)


def _from_outline(obs, fold, j, part, lying, layout, outline, g: FoldGeometry) -> FoldGeometry:
    """``g``, or where its stickers left it unfixed, the crease from the napkin's outline
    (a half or diagonal fold, a flap under: a state's one fold, whose edge the outline
    shows);
    the stickers' why kept, and the outline's added, where neither fixes it."""
    if g.why is None or (fold_kind(fold.word)[0] == "corner" and not fold.under):
        return g
    got = outline(obs, fold, j, part, lying, layout)
    if got is None:
        return replace(g, why=f"{g.why}; nor does the outline: it is not measured")
    if isinstance(got, str):
        return replace(g, why=f"{g.why}; {got}")
    return got


def _fit(
    p2: NDArray,
    part: NDArray,
    use: NDArray[np.bool_],
    active: list[int],
    folds: tuple[NominalFold, ...],
    layout: NapkinLayout,
) -> dict[int, FoldGeometry]:
    """The joint fit of the napkin that stays and the creases of the folds ``active``
    to the stickers ``use``, leaving out up to two outliers."""
    uv = np.asarray(layout.sticker_uv, dtype=float)
    lut = np.full(len(folds) + 1, -1)  # part -> flap index in the fit (lut[-1]: -1)
    lut[active] = np.arange(len(active))
    use = use.copy()
    bend = 0.25 * math.pi * layout.thickness_mm  # the fold's bend takes cloth: see below
    for attempt in range(3):
        ids = np.flatnonzero(use)
        g = lut[part[ids]]
        m, p = uv[ids], p2[ids]
        x = initial_flaps(m, p, g, [folds[j] for j in active])
        x, jtj, res = solve_flaps(m, p, g, x, len(active))
        d = np.hypot(res[:, 0], res[:, 1])
        worst = int(np.argmax(d))
        if d[worst] <= OUTLIER_MM or attempt == 2:
            break
        same = np.count_nonzero(g == g[worst])
        if same <= (2 if g[worst] < 0 else 1):
            break
        use[ids[worst]] = False
    dof = max(2 * len(m) - len(x), 0)
    var = (float(np.add.reduce(d * d)) + PRIOR_DOF * STICKER_SD_MM**2) / (dof + PRIOR_DOF)
    try:
        cov = var * np.linalg.inv(jtj)
    except np.linalg.LinAlgError:
        return {}
    out: dict[int, FoldGeometry] = {}
    for j, fold_index in enumerate(active):
        word = folds[fold_index].word
        a, c = float(x[3 + 2 * j]), float(x[4 + 2 * j])
        mine = g == j
        # The cloth bends round its own thickness at the crease, so a flap lands short
        # of its mirror image by about pi / 2 thicknesses: the mirror's axis lies a
        # quarter turn's worth (pi / 4 thicknesses) inside the flap. Move it back.
        # (means as np.mean takes them, the sum over the count, without its overhead)
        count = int(np.count_nonzero(mine))
        side = float(np.add.reduce(m[mine] @ np.array([math.cos(a), math.sin(a)]) - c) / count)
        c -= math.copysign(bend, side)
        block = cov[3 + 2 * j : 5 + 2 * j, 3 + 2 * j : 5 + 2 * j]
        crease = Crease.from_normal(a, c)
        rms = math.sqrt(np.add.reduce(d[mine] ** 2) / count)
        if not np.all(np.isfinite(block)) or _edge_sd(crease, block, layout) > MAX_SD_MM:
            out[fold_index] = empty_geometry(word, "the stickers seen do not fix the crease")
            continue
        out[fold_index] = geometry_from_crease(
            word, crease, layout, block, stickers=int(np.count_nonzero(mine)), rms_mm=rms
        )
    return out


def _edge_sd(crease: Crease, cov: NDArray, layout: NapkinLayout) -> float:
    """The largest sd (mm) of the crease's place at its two ends on the napkin."""
    ends = crease.ends_in(layout)
    if ends is None:
        return math.inf
    (tx, ty) = crease.direction
    worst = 0.0
    for ex, ey in ends:
        # the line n . x = c: at a point e of it, d(n . e)/d alpha = t . e, and -1 for c
        g0, g1 = ex * tx + ey * ty, -1.0
        v = g0 * g0 * cov[0, 0] + 2 * g0 * g1 * cov[0, 1] + g1 * g1 * cov[1, 1]
        worst = max(worst, math.sqrt(max(float(v), 0.0)))
    return worst


@lru_cache(maxsize=256)
def _nominal_normal(f: NominalFold) -> tuple[float, float]:
    """A nominal fold's crease as (normal angle, offset)."""
    (x0, y0), (x1, y1) = f.p0, f.p1
    alpha = math.atan2(x1 - x0, -(y1 - y0))  # the normal (-ty, tx) of t = p1 - p0
    return alpha, math.cos(alpha) * x0 + math.sin(alpha) * y0


def initial_flaps(m: NDArray, p: NDArray, g: NDArray, folds: list[NominalFold]) -> NDArray:
    """The first guess of (theta, tau, alpha_j, c_j): the napkin that stays from its
    own stickers (two or more), else from the flap with most stickers mirrored back
    across its nominal crease; each crease by :func:`mirror_crease_fit` on that."""
    stay = g < 0
    if np.count_nonzero(stay) >= 2:
        th, tau = rigid_fit_2d(m[stay], p[stay])
    else:
        j = int(np.argmax(np.bincount(g[~stay], minlength=len(folds))))
        mine = g == j
        a, c = _nominal_normal(folds[j])
        n = np.array([math.cos(a), math.sin(a)])
        mm = m[mine] - 2.0 * (m[mine] @ n - c)[:, None] * n
        mm, pp = np.concatenate([mm, m[stay]]), np.concatenate([p[mine], p[stay]])
        if len(mm) >= 2:
            th, tau = rigid_fit_2d(mm, pp)
        else:
            th, tau = 0.0, pp[0] - mm[0]
    rot, _ = rotation_2d(th)
    q = (p - tau) @ rot  # back onto the flat napkin
    x = [th, float(tau[0]), float(tau[1])]
    # every flap's best mirror at once (as mirror_crease_fit, by sums over each flap)
    k = len(folds)
    on = ~stay
    gf, mf, qf = g[on], m[on], q[on]
    cnt = np.bincount(gf, minlength=k).astype(float)
    cols = np.column_stack([
        mf, qf, qf[:, 0] * mf[:, 0], qf[:, 1] * mf[:, 1], qf[:, 0] * mf[:, 1], qf[:, 1] * mf[:, 0],
    ])
    sums = np.stack([np.bincount(gf, weights=col, minlength=k) for col in cols.T], axis=1)
    for j in range(k):
        n_j = cnt[j]
        smx, smy, sqx, sqy, xx, yy, xy, yx = sums[j].tolist()
        if n_j == 0:
            x += list(_nominal_normal(folds[j]))
            continue
        if n_j == 1:
            dx, dy = sqx - smx, sqy - smy
            if math.hypot(dx, dy) < 1e-6:
                x += list(_nominal_normal(folds[j]))
                continue
            alpha = math.atan2(dy, dx)
        else:
            a = (xx - sqx * smx / n_j) - (yy - sqy * smy / n_j)
            b = (xy - sqx * smy / n_j) + (yx - sqy * smx / n_j)
            alpha = 0.5 * math.atan2(b, a) + 0.5 * math.pi
        c = ((smx + sqx) * math.cos(alpha) + (smy + sqy) * math.sin(alpha)) / (2.0 * n_j)
        x += [alpha, c]
    return np.asarray(x, dtype=float)
