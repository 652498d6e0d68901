"""The classification pipeline: an RGB-D frame -> stickers -> 3D -> dGLI -> a state.

Each stage is one function of one module; this module chains them and keeps every
intermediate result, which is what a person debugging a real image needs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .classify import Prediction, classify_coordinates
from .dgli import cloth_coordinates
from .errors import DetectionError
from .io import RGBDFrame
from .layout import NapkinLayout, default_layout
from .perception.detect import DetectorParams, StickerDetections, detect_stickers
from .perception.lift import Markers3D, estimate_table_plane, lift_stickers
from .perception.napkin import find_napkin
from .references import ReferenceSet

__all__ = ["ClothObservation", "FrameResult", "classify_frame", "observe"]


@dataclass(frozen=True, eq=False)
class ClothObservation:
    """The cloth as seen: segments in the camera frame and the table normal.

    Attributes
    ----------
    segments : ndarray, shape (8, 2, 3)
        Oriented segments (sticker 2i -> 2i + 1), metres; NaN rows where an end is missing.
    visible : ndarray of bool, shape (16,)
        Stickers located in 3D.
    up : ndarray, shape (3,)
        Table normal, towards the camera (the direction of the dGLI derivative).
    """

    segments: NDArray[np.float64]
    visible: NDArray[np.bool_]
    up: NDArray[np.float64]

    @property
    def segment_visible(self) -> NDArray[np.bool_]:
        """Segments with both ends located, shape (8,)."""
        return self.visible.reshape(-1, 2).all(axis=1)


@dataclass(frozen=True, eq=False)
class FrameResult:
    """Everything the pipeline computed for one frame.

    ``prediction`` is None when too little was seen; ``reason`` then says why.
    """

    detections: StickerDetections
    markers: Markers3D
    observation: ClothObservation
    coordinates: NDArray[np.float64]
    prediction: Prediction | None
    reason: str | None = None


def observe(
    frame: RGBDFrame, layout: NapkinLayout | None = None, params: DetectorParams | None = None
) -> tuple[StickerDetections, Markers3D, ClothObservation]:
    """Detect the stickers, lift them to 3D and estimate the table normal."""
    layout = layout or default_layout()
    try:
        up, offset = estimate_table_plane(frame.depth_mm, frame.intrinsics)
    except ValueError as exc:
        raise DetectionError(f"'{frame.depth_path}': {exc}") from None
    napkin = find_napkin(frame.color, frame.depth_mm, frame.intrinsics, up, offset)
    detections = detect_stickers(
        frame.color, frame.depth_mm, frame.intrinsics, layout, params, napkin=napkin
    )
    markers = lift_stickers(detections, frame.intrinsics)
    visible = markers.found
    segments = markers.points.reshape(-1, 2, 3).copy()
    segments[~visible.reshape(-1, 2).all(axis=1)] = np.nan
    return detections, markers, ClothObservation(segments, visible, up)


def classify_frame(
    frame: RGBDFrame,
    references: ReferenceSet,
    *,
    layout: NapkinLayout | None = None,
    params: DetectorParams | None = None,
) -> FrameResult:
    """Classify one RGB-D frame.

    Returns
    -------
    FrameResult
        With ``prediction`` None and a ``reason`` when too few stickers were seen.
    """
    detections, markers, obs = observe(frame, layout, params)
    coords = cloth_coordinates(obs.segments, obs.up)
    try:
        prediction = classify_coordinates(coords, references, obs.visible)
        reason = None
    except DetectionError as exc:
        n = int(obs.visible.sum())
        prediction, reason = None, f"{n} of {len(obs.visible)} stickers located; {exc}"
    return FrameResult(detections, markers, obs, coords, prediction, reason)
