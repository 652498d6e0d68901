"""How far a flap held up has turned: the lean of the raised cloth, from depth alone.

A flap turns about its fold line. A point of it at distance ``s`` from the fold line
stands ``s sin(theta)`` above the table and lies ``-s cos(theta)`` from the fold line
towards the rest of the napkin. So across the raised cloth, the horizontal position
towards the napkin changes with height at the rate ``-cot(theta)``: the top of a flap at
80 degrees leans out, at 100 degrees it leans in. The slope is fitted over every depth
sample of the raised cloth, so it needs no sticker: it tells the two sides of vertical
apart exactly where a flap seen edge-on shows none (SPEC's rule changes the class at 90
degrees).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from ..core.camera import Intrinsics
from ..core.order_stats import median
from .evidence import StickerEvidence
from .napkin import NapkinView
from .params import FlapParams

__all__ = ["FlapParams", "flap_angles"]


def _line(x: NDArray, h: NDArray, p: FlapParams) -> tuple[float, float]:
    """Robust fit ``x = slope * h + at_table``: (slope, at_table), NaN when the samples
    cannot give one."""
    if len(x) < p.min_samples or np.ptp(h) < p.min_height_span_mm:
        return float("nan"), float("nan")
    beta, c = np.polyfit(h, x, 1)
    res = np.abs(x - (beta * h + c))
    mad = median(res) + 1e-6
    keep = res <= p.outlier_mads * 1.4826 * mad + 1.0
    if keep.all():  # no outlier: the second fit would be the first
        return float(beta), float(c)
    if keep.sum() >= p.min_samples and np.ptp(h[keep]) >= p.min_height_span_mm:
        beta, c = np.polyfit(h[keep], x[keep], 1)
    return float(beta), float(c)


def _plane_normal(cloud: NDArray[np.float64]) -> NDArray[np.float64] | None:
    """Unit normal of the least-squares plane of ``cloud`` (n, 3); None below 3 points."""
    if len(cloud) < 3:
        return None
    _, _, vt = np.linalg.svd(cloud - cloud.mean(axis=0), full_matrices=False)
    return vt[-1]


def _across_fold(
    normal: NDArray[np.float64] | None, up: NDArray[np.float64], inwards: NDArray[np.float64]
) -> NDArray[np.float64] | None:
    """The horizontal unit vector across the fold line of a flap whose plane has
    ``normal`` (:func:`_plane_normal`), pointing the way of ``inwards`` (from the flap's
    flat place to the napkin lying on the table); None when the flap lies too flat to
    tell its fold line (or has no plane).

    The flap's plane holds the fold line, which is horizontal; so the horizontal part of
    the plane's normal runs across it.
    """
    if normal is None:
        return None
    across = normal - (normal @ up) * up
    norm = float(np.linalg.norm(across))
    if norm < 0.2:  # the flap is within 12 degrees of flat
        return None
    across /= norm
    return across if across @ inwards >= 0 else -across


def flap_angles(
    depth_mm: NDArray[np.uint16],
    intrinsics: Intrinsics,
    up: NDArray[np.float64],
    offset_m: float,
    napkin: NapkinView | None,
    points: NDArray[np.float64],
    heights_mm: NDArray[np.float64],
    evidence: StickerEvidence | None,
    *,
    napkin_side_mm: float,
    lying_mm: float,
    params: FlapParams | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The angle (degrees from flat) of the flap each sticker held up is on, and how
    high the sticker stands on it.

    Parameters
    ----------
    depth_mm : ndarray of uint16, shape (H, W)
    intrinsics : Intrinsics
    up : ndarray, shape (3,)
        Table normal towards the camera.
    offset_m : float
        ``up @ x`` of the table plane, metres.
    napkin : NapkinView or None
        Its ``raised`` mask (parts of cloth held up) and ``raised_px`` /
        ``raised_height_mm`` (every pixel of them, with its height) give the raised
        cloth.
    points : ndarray, shape (16, 3)
        Located stickers, camera frame, NaN where missing.
    heights_mm : ndarray, shape (16,)
        Their heights above the table.
    evidence : StickerEvidence or None
        Which missing stickers may be on cloth held up (:data:`HELD_UP`), and where they
        would lie flat.
    napkin_side_mm : float, keyword-only
        The napkin's shorter side.
    lying_mm : float, keyword-only
        A sticker lower than this lies on the table (it gives the napkin's inside).
    params : FlapParams, keyword-only, optional

    Returns
    -------
    angle_deg : ndarray, shape (16,)
        Degrees in (0, 180) for a sticker held up whose flap's lean could be measured;
        NaN for every other.
    height_mm : ndarray, shape (16,)
        Where the sticker's flat place is known: its distance from the fold line (where
        the fitted flap meets the table) times ``sin(angle)``, mm; NaN otherwise. A half
        fold's edge stands nearly twice as high as a strip's at the same angle.
    """
    p = params or FlapParams()
    angle = np.full(len(points), np.nan)
    height = np.full(len(points), np.nan)
    held, inside = _held_and_inside(napkin, evidence, points, heights_mm, lying_mm)
    if held is None or napkin is None or evidence is None:
        return angle, height
    cloth = _RaisedCloth.of(napkin, depth_mm, intrinsics, p)
    flat_px = evidence.predicted_px
    rays = intrinsics.deproject(flat_px, np.ones(len(flat_px)))  # z = 1
    flat = rays * (offset_m / (rays @ up))[:, None]  # where each would lie on the table
    reach = p.reach * napkin_side_mm * 1e-3
    for sid in np.flatnonzero(held):
        found = cloth.flap_of(flat[sid], up, reach)
        if found is None:
            continue
        mine, anchor, part, offsets = found
        fit = _lean(offsets, cloth.heights_mm[mine], up, inside - anchor, p, cloth.normal_of(part))
        if fit is None:
            continue
        beta, hinge = fit  # beta = -cot(angle); hinge: x at the table
        angle[sid] = 90.0 + float(np.degrees(np.arctan(beta)))
        if np.isfinite(flat[sid]).all() and hinge > 0:
            # the sticker turns about the fold line, ``hinge`` away
            height[sid] = hinge * np.sin(np.radians(angle[sid]))
    return angle, height


def _held_and_inside(
    napkin: NapkinView | None,
    evidence: StickerEvidence | None,
    points: NDArray[np.float64],
    heights_mm: NDArray[np.float64],
    lying_mm: float,
) -> tuple[NDArray[np.bool_] | None, NDArray[np.float64]]:
    """The stickers possibly held up (None when there is nothing to measure: none, no
    raised cloth, or fewer than three stickers lying on the table), and the mean of
    those lying (a point inside the napkin)."""
    nowhere = np.full(3, np.nan)
    if evidence is None or napkin is None or napkin.raised is None:
        return None, nowhere
    held = evidence.held_up
    lying = np.isfinite(heights_mm) & (heights_mm < lying_mm)
    if not held.any() or not napkin.raised.any() or lying.sum() < 3:
        return None, nowhere
    if napkin.raised_px is None or not len(napkin.raised_px):
        return None, nowhere
    return held, points[lying].mean(axis=0)


@dataclass(frozen=True, eq=False)
class _RaisedCloth:
    """The raised cloth's pixels (evenly thinned to about ``max_pixels``) as points:
    ``cloud`` (n, 3) camera frame, ``heights_mm`` (n,) above the table, ``label`` (n,)
    the connected part of ``NapkinView.raised`` each lies in, ``sizes`` the parts'."""

    cloud: NDArray[np.float64]
    heights_mm: NDArray[np.float64]
    label: NDArray[np.intp]
    sizes: NDArray[np.intp]
    _normals: dict[int, NDArray[np.float64] | None] = field(default_factory=dict)

    def normal_of(self, part: int) -> NDArray[np.float64] | None:
        """The plane normal of raised part ``part`` (:func:`_plane_normal`), found once
        however many stickers lie on it."""
        if part not in self._normals:
            self._normals[part] = _plane_normal(self.cloud[self.label == part])
        return self._normals[part]

    @classmethod
    def of(
        cls,
        napkin: NapkinView,
        depth_mm: NDArray[np.uint16],
        intrinsics: Intrinsics,
        p: FlapParams,
    ) -> _RaisedCloth:
        import cv2

        assert napkin.raised is not None and napkin.raised_px is not None
        assert napkin.raised_height_mm is not None
        s = napkin.stride
        n_parts, parts = cv2.connectedComponents(napkin.raised.astype(np.uint8), connectivity=8)
        every = max(1, len(napkin.raised_px) // p.max_pixels)
        xy = napkin.raised_px[::every]
        h = napkin.raised_height_mm[::every].astype(np.float64)
        d = depth_mm[xy[:, 1], xy[:, 0]].astype(np.float64) * 1e-3
        cloud = intrinsics.deproject(xy.astype(np.float64), d)
        label = parts[xy[:, 1] // s, xy[:, 0] // s]
        return cls(cloud, h, label, np.bincount(label, minlength=n_parts))

    def flap_of(
        self, anchor: NDArray[np.float64], up: NDArray[np.float64], reach: float
    ) -> tuple[NDArray[np.bool_], NDArray[np.float64], int, NDArray[np.float64]] | None:
        """The points (mask) of the raised part nearest the flat place ``anchor`` (3,)
        within ``reach`` (m, horizontally), the anchor, the part and the points'
        horizontal offsets from the anchor (n, 3); with no place (NaN), the largest part
        and its mean. None when no raised cloth comes within reach."""
        if np.isfinite(anchor).all():
            away = _horizontal(self.cloud - anchor, up)
            # their lengths, summed as np.linalg.norm sums them
            gap = np.sqrt((away[:, 0] * away[:, 0] + away[:, 1] * away[:, 1]) + away[:, 2] ** 2)
            near = gap < reach
            if not near.any():
                return None
            part = self.label[near][np.argmin(gap[near])]
            mine = self.label == part
            return mine, anchor, int(part), away[mine]
        # nowhere to put it: the largest raised part
        part = int(np.argmax(self.sizes[1:])) + 1
        mine = self.label == part
        anchor = self.cloud[mine].mean(axis=0)
        return mine, anchor, part, _horizontal(self.cloud[mine] - anchor, up)


def _horizontal(v: NDArray, up: NDArray) -> NDArray:
    return v - np.outer(v @ up, up) if v.ndim == 2 else v - (v @ up) * up


def _lean(
    offsets: NDArray[np.float64],
    h: NDArray[np.float64],
    up: NDArray[np.float64],
    inwards: NDArray[np.float64],
    p: FlapParams,
    normal: NDArray[np.float64] | None,
) -> tuple[float, float] | None:
    """The flap's points, at horizontal ``offsets`` (n, 3) from an anchor and heights
    ``h`` (n,), with plane ``normal``: the slope ``-cot(angle)`` of their horizontal
    position across the fold line (mm from the anchor, towards ``inwards``) against
    height, and that position at the table; None when the flap lies too flat or too
    few samples give a slope."""
    towards = _across_fold(normal, up, inwards)
    if towards is None:
        return None
    x = offsets @ towards * 1e3
    beta, hinge = _line(x, h, p)
    if not np.isfinite(beta):
        return None
    return beta, hinge
