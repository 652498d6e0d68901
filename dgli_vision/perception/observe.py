"""The perception's whole path for one frame, in its stages' order: :func:`observe`.

One frame context is worked out once (the table plane, the napkin found, the search
frame of its stickers, the frame's white regions) and every stage after reads it; each
stage adds its result to the one :class:`Observation` (the stage order is
:mod:`dgli_vision.perception`'s). The parameters of every stage come from one tree
(:class:`~.params.PipelineParams`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from ..core.classes import LIFTED_MM, PAST_BAND_DEG
from ..core.errors import DetectionError
from ..core.frame import RGBDFrame
from ..core.layout import NapkinLayout, default_layout, sticker_spreads_mm
from .agreement import BareRaised, bare_table_raised, edge_on_heights
from .detect import (
    DetectorParams,
    StickerDetections,
    first_search,
    search_frame,
    washed_out_search,
)
from .evidence import StickerEvidence, assess_stickers, drop_inconsistent
from .flaps import flap_angles
from .footprint import ClothRegions, Footprint, cloth_regions, measure_footprint
from .handedness import back_face_up, image_turns
from .lift import Markers3D, estimate_table_plane, lift_stickers
from .napkin import NapkinView, find_napkin
from .params import PipelineParams, TipParams, params_of
from .partial import confirm_at_place, confirm_partly_hidden
from .rigid import RigidFit
from .scale import NapkinRuler, measure_napkin
from .tips import corner_tips_and_pose

__all__ = ["Observation", "StageClock", "observe"]


@dataclass(frozen=True, eq=False, kw_only=True)
class Observation:
    """The cloth as seen: segments in the camera frame and the table normal (each
    stage's result, added by :func:`observe` in the stages' order).

    Attributes
    ----------
    segments : ndarray, shape (8, 2, 3)
        Oriented segments (sticker 2i -> 2i + 1), metres; NaN rows where an end is missing.
    visible : ndarray of bool, shape (16,)
        Stickers located in 3D.
    up : ndarray, shape (3,)
        Table normal, towards the camera (the direction of the dGLI derivative).
    evidence : StickerEvidence or None
        Which missing stickers are hidden by cloth and which are unknown, and why.
    heights_mm : ndarray, shape (16,), optional
        Height of each located sticker above the table plane, mm (NaN where missing).
    flap_deg : ndarray, shape (16,), optional
        For a sticker possibly on a flap held up, how far that flap has turned from flat
        (degrees, from the lean of the raised cloth); NaN where not measured.
    flap_height_mm : ndarray, shape (16,), optional
        For such a sticker, how high it stands on its flap (from the flap's fold line and
        angle), mm; NaN where not measured.
    ruler : NapkinRuler, optional
        The napkin's measured scale and rigidity (distances of same-corner stickers,
        before any sticker is dropped); None with too few stickers located.
    footprint : Footprint, optional
    objects : ndarray of bool, optional
        Objects above the table (not napkin), on a grid of ``objects_stride`` pixels.
    objects_stride : int
    points_m : ndarray, shape (16, 3), optional
        The located stickers in the camera frame, metres (NaN where missing).
    turns : ndarray, shape (4,), optional
        Which face each corner A-D shows the camera: +1 front, -1 back, 0 not told
        (:func:`~dgli_vision.perception.handedness.image_turns`).
    tips : ndarray, shape (4,), optional
        For each corner A-D, the share of its tip's flat place seen as bare table (NaN
        not told: :func:`~dgli_vision.perception.tips.corner_tips`).
    edge_on_mm : ndarray, shape (n,), optional
        Heights above the table (mm) of the blobs seen edge-on in colour
        (:func:`~dgli_vision.perception.agreement.edge_on_heights`).
    bare_raised : BareRaised, optional
        Cloth held up in depth over what colour shows as bare table
        (:func:`~dgli_vision.perception.agreement.bare_table_raised`): colour and depth
        of different instants.
    napkin : NapkinView, optional
        The napkin as stage 1 found it (its white, the box around its cloth, its masks),
        for a later look at the same frame (the channel-order check).
    pose : RigidFit, optional
        The rigid fit of the napkin that stays (its stickers lying flat, front face up)
        that told the corners' tips, when one was made: a later stage of the same frame
        (:func:`~dgli_vision.perception.tips.settled_stickers`) reads it, not fitting
        it again.
    """

    segments: NDArray[np.float64]
    visible: NDArray[np.bool_]
    up: NDArray[np.float64]
    evidence: StickerEvidence | None = None
    heights_mm: NDArray[np.float64] | None = None
    flap_deg: NDArray[np.float64] | None = None
    flap_height_mm: NDArray[np.float64] | None = None
    ruler: NapkinRuler | None = None
    footprint: Footprint | None = None
    turns: NDArray[np.float64] | None = None
    points_m: NDArray[np.float64] | None = None
    objects: NDArray[np.bool_] | None = None
    objects_stride: int = 8
    tips: NDArray[np.float64] | None = None
    edge_on_mm: NDArray[np.float64] | None = None
    bare_raised: BareRaised | None = None
    napkin: NapkinView | None = None
    pose: RigidFit | None = None

    @property
    def spread_mm(self) -> NDArray[np.float64] | None:
        """3D distance between the stickers of each pair seen, mm, shape (120,), taken
        to the napkin's printed scale when its ruler measured one (NaN where either
        sticker is not seen)."""
        if self.points_m is None:
            return None
        scale = self.ruler.scale if self.ruler is not None else 1.0
        seen = np.where(self.visible[:, None], self.points_m, np.nan)
        return sticker_spreads_mm(seen * 1e3 / scale)

    @property
    def back(self) -> NDArray[np.float64] | None:
        """1 for a corner showing its back face, 0 its front, NaN not told, shape (4,)."""
        return None if self.turns is None else back_face_up(self.turns)

    @property
    def lifted(self) -> NDArray[np.float64] | None:
        """1 for a sticker standing more than ``LIFTED_MM`` above the table, 0 for one on
        it, NaN where not known, shape (16,). A missing sticker that may have gone up
        with a flap held up steeply counts as standing, unless its place may also lie
        under an object and its flap's lean was not measured (then the raised cloth may
        be the object's doing)."""
        if self.heights_mm is None:
            return None
        out = np.where(self.visible, (self.heights_mm > LIFTED_MM).astype(float), np.nan)
        if self.evidence is not None:
            held = self.evidence.held_up
            if self.flap_deg is not None:
                told = ~self.evidence.near_object | np.isfinite(self.flap_deg)
            else:
                told = ~self.evidence.near_object
            out[held & told] = 1.0
        return out

    @property
    def matched_heights_mm(self) -> NDArray[np.float64] | None:
        """Heights to compare with the references: those of the stickers seen, and for
        stickers held up out of sight, the height their flap gives them (mm, NaN where
        neither is known), shape (16,)."""
        if self.heights_mm is None:
            return None
        if self.flap_height_mm is None:
            return np.where(self.visible, self.heights_mm, np.nan)
        return np.where(self.visible, self.heights_mm, self.flap_height_mm)

    @property
    def past_vertical(self) -> NDArray[np.float64] | None:
        """For each sticker on a flap held up whose lean was measured: 1 when the flap
        has turned past 90 degrees, 0 when not (in proportion within
        ``PAST_BAND_DEG`` of vertical); NaN for the others, shape (16,)."""
        if self.flap_deg is None:
            return None
        return np.clip(0.5 + (self.flap_deg - 90.0) / (2 * PAST_BAND_DEG), 0.0, 1.0)

    @property
    def unknown(self) -> NDArray[np.bool_]:
        """Stickers neither seen nor evidence of a fold, shape (16,)."""
        if self.evidence is None:
            return np.zeros(len(self.visible), dtype=bool)
        return self.evidence.unknown

    @property
    def segment_visible(self) -> NDArray[np.bool_]:
        """Segments with both ends located, shape (8,)."""
        return self.visible.reshape(-1, 2).all(axis=1)


class StageClock:
    """The time each stage of the pipeline took, ms, in the order they ran.

    ``lap(name)`` charges the time since the last lap (or since the clock was made) to
    ``name``. ``time.perf_counter`` costs well under a microsecond.
    """

    def __init__(self) -> None:
        self.ms: dict[str, float] = {}
        self._last = time.perf_counter()

    def lap(self, name: str) -> None:
        """Charge the time since the last lap to stage ``name``."""
        now = time.perf_counter()
        self.ms[name] = self.ms.get(name, 0.0) + (now - self._last) * 1e3
        self._last = now


def observe(
    frame: RGBDFrame,
    layout: NapkinLayout | None = None,
    params: PipelineParams | DetectorParams | None = None,
    *,
    colours: dict[str, tuple[int, int, int]] | None = None,
    clock: StageClock | None = None,
    into: type[Observation] = Observation,
) -> tuple[StickerDetections, Markers3D, Observation]:
    """Find the table and the napkin, detect the stickers, lift them to 3D, and judge
    the missing ones (hidden by cloth or unknown), each stage with its parameters of
    ``params`` (:class:`~dgli_vision.perception.params.PipelineParams`; a
    ``DetectorParams`` alone: the defaults with it). ``clock`` keeps each stage's time;
    ``into`` is the observation's class (the classifier's adds what it weighs).

    Each stage runs once, in the order of the package's doc, and adds its result; the
    table plane, the napkin (its white, masks and box) and the search frame are worked
    out once and read by every stage after them.

    Raises
    ------
    DetectionError
        No table plane in the depth image (naming the file).
    """
    layout = layout or default_layout()
    tree = params_of(params)
    clock = clock or StageClock()
    try:
        up, offset = estimate_table_plane(frame.depth_mm, frame.intrinsics)
    except ValueError as exc:
        raise DetectionError(f"'{frame.depth_path}': {exc}") from None
    clock.lap("table plane")
    napkin = find_napkin(frame.color, frame.depth_mm, frame.intrinsics, up, offset, tree.napkin)
    clock.lap("napkin")
    search = search_frame(
        frame.color, frame.depth_mm, frame.intrinsics, layout, napkin, tree.detector,
        colours=colours,
    )
    detections = first_search(search)
    clock.lap("search")
    regions = cloth_regions(frame.color, napkin.white_rgb, tree.regions, tree.napkin)
    clock.lap("cloth regions")
    detections = washed_out_search(search, detections, regions=regions)
    clock.lap("second search")
    lifted = lift_stickers(detections, frame.intrinsics)
    markers, dropped = drop_inconsistent(lifted, layout, tree.evidence)
    ruler = _ruler(lifted, markers, dropped, layout)
    located = np.where(markers.found[:, None], detections.centroids, np.nan)
    turns = image_turns(located, layout)
    clock.lap("lift")
    evidence = assess_stickers(
        markers, frame.intrinsics, layout, napkin.masks(), dropped=dropped,
        foreshortening=detections.foreshortening, up=up,
        pale_colours=detections.pale_colours, turns=turns, params=tree.evidence,
    )
    detections, markers, evidence = confirm_partly_hidden(
        frame.color, napkin.lut, detections, markers, evidence, frame.intrinsics,
        (up, offset), layout, tree.detector, tree.partial, colours=colours,
    )
    detections, markers, evidence = confirm_at_place(
        frame.color, frame.depth_mm, napkin, (detections, markers, evidence),
        frame.intrinsics, layout, tree.detector, tree.partial, colours=colours,
    )
    clock.lap("evidence")
    visible = markers.found
    segments = markers.points.reshape(-1, 2, 3).copy()
    segments[~visible.reshape(-1, 2).all(axis=1)] = np.nan
    heights = (markers.points @ up - offset) * 1e3
    flap_deg, flap_height = flap_angles(
        frame.depth_mm, frame.intrinsics, up, offset, napkin, markers.points, heights,
        evidence, napkin_side_mm=min(layout.width_mm, layout.height_mm), lying_mm=LIFTED_MM,
        params=tree.flaps,
    )
    clock.lap("flaps")
    footprint = measure_footprint(
        frame.color, frame.intrinsics, up, offset, napkin, detections.centroids,
        layout.width_mm * layout.height_mm, tree.footprint, tree.napkin, regions=regions,
        shade=tree.shade,
    )
    clock.lap("footprint")
    tips, pose = _tips(
        frame, layout, napkin, markers, heights, evidence, turns, up, footprint, regions,
        tree.tips,
    )
    clock.lap("tips")
    return detections, markers, into(
        pose=pose,
        segments=segments, visible=visible, up=up, evidence=evidence, heights_mm=heights,
        flap_deg=flap_deg, flap_height_mm=flap_height, ruler=ruler, footprint=footprint,
        turns=turns, points_m=markers.points, objects=napkin.occluder,
        objects_stride=napkin.stride, tips=tips,
        edge_on_mm=edge_on_heights(detections, napkin.masks(), frame.intrinsics.fx),
        bare_raised=bare_table_raised(frame.color, napkin.masks()), napkin=napkin,
    )


def _tips(
    frame: RGBDFrame,
    layout: NapkinLayout,
    napkin: NapkinView,
    markers: Markers3D,
    heights: NDArray[np.float64],
    evidence: StickerEvidence,
    turns: NDArray[np.float64],
    up: NDArray[np.float64],
    footprint: Footprint | None,
    regions: ClothRegions | None,
    params: TipParams,
) -> tuple[NDArray[np.float64] | None, RigidFit | None]:
    """:func:`~dgli_vision.perception.tips.corner_tips_and_pose` of the frame: what is
    not table is the napkin's measured cloth and any other white region (a flap apart
    from it)."""
    if footprint is None or footprint.cells is None or regions is None:
        return None, None
    cloth = footprint.cells | (regions.labels > 0)
    return corner_tips_and_pose(
        markers.points, heights, evidence.unknown, evidence.held_up, turns, layout,
        frame.intrinsics, up, cloth, regions.cell_px, napkin.occluder, napkin.stride, params,
    )


def _ruler(
    lifted: Markers3D, kept: Markers3D, dropped: NDArray[np.bool_], layout: NapkinLayout
) -> NapkinRuler | None:
    """The napkin's scale from every sticker located, its corners' rigidity without the
    detections found where the napkin cannot be (a coloured object on the table taken
    for a sticker stretches no lens; a wrong depth scale moves every sticker, so the
    scale keeps them all)."""
    ruler = measure_napkin(lifted, layout)
    if ruler is None or not dropped.any():
        return ruler
    without = measure_napkin(kept, layout)
    return replace(ruler, worst_against_scale=without.worst_against_scale if without else 0.0)
