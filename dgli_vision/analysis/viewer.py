"""The live viewer: each classified frame logged to Rerun (``dgli
watch --rerun``, ``dgli track --rerun``), to an ``.rrd`` file or to a viewer it spawns.

What is logged, by entity path (docs/live.md has the table):

- ``world``: the camera's frame (x right, y down, z forward), or the robot's base frame
  when an extrinsics transform is given (then ``world/camera`` carries it);
- ``world/camera/image``: the colour image, with ``found`` (the stickers located, by id)
  and ``missing`` (where a missing sticker would be: grey hidden by cloth, orange
  unknown, ``6?``) as 2D points on it, and the 2D segments;
- ``world/camera/stickers``, ``world/camera/segments``: the stickers in 3D and the 8
  segments as arrows (sticker 2i to 2i + 1);
- ``world/camera/table``: the table plane as a translucent square under the napkin, and
  ``world/camera/table/up`` its normal;
- ``world/camera/corners``: the corners A-D (green: graspable);
- ``world/camera/plan/grasp``, ``.../place``, ``.../fold_line``: the first step of the
  plan to ``goal`` where there is one;
- ``state/confidence``, ``state/class``, ``state/smoothed``: the frame's confidence, its
  class and the smoothed class as numbers over time (NaN: cannot tell), and
  ``state/log`` one line per frame (with the reason when it cannot tell).

Two timelines: ``frame`` (the stream's frame number) and ``time`` (seconds of the
source's own clock, where it has one).

The Rerun SDK is the ``viewer`` extra (``pip install 'dgli_vision[viewer]'``).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ..core.errors import MissingExtraError, OutputError, OverwriteError

if TYPE_CHECKING:
    from ..classifier.pipeline import FrameResult
    from ..core.extrinsics import Extrinsics
    from ..core.fold_graph import StateKey
    from ..core.frame import RGBDFrame
    from ..planning.plan import Plan

__all__ = ["APPLICATION_ID", "RerunLog", "class_number", "log_timeline"]

#: The Rerun application id of dgli_vision's recordings.
APPLICATION_ID = "dgli_vision"
#: Colours (RGB): a sticker found, one hidden by cloth, one unknown; the segments; the
#: grasp, the place and the fold line; a graspable corner and one that is not.
FOUND = (255, 255, 255)
HIDDEN = (160, 160, 160)
UNKNOWN = (255, 140, 0)
SEGMENT = (0, 200, 255)
GRASP = (255, 120, 0)
PLACE = (0, 200, 230)
FOLD = (255, 255, 0)
GRASPABLE = (60, 200, 60)
NOT_GRASPABLE = (150, 150, 150)
#: The colour image is logged as JPEG of this quality (a raw 1280x720 frame is 2.7 MB).
JPEG_QUALITY = 90
#: Half the side of the table square drawn under the napkin, metres.
TABLE_HALF_M = 0.3


def _rerun() -> Any:
    try:
        import rerun
    except ImportError:
        raise MissingExtraError(
            "the live viewer (--rerun) needs the 'viewer' extra (the Rerun SDK): pip "
            "install 'dgli_vision[viewer]'"
        ) from None
    return rerun


def class_number(key: StateKey | None) -> float:
    """A state's class as a number for the plots (``("02", "B")`` -> 2.0); NaN for
    "cannot tell" and for a state outside the twelve."""
    if key is None or not str(key[0]).isdigit():
        return float("nan")
    return float(int(key[0]))


def _state_text(key: StateKey | None) -> str:
    from ..core.classes import CLASS_NAMES

    if key is None:
        return "cannot tell"
    name = CLASS_NAMES.get(key[0], "(no known state)")
    return f"{key[0]} {name}" + (f" {key[1]}" if key[1] else "")


def _finite(points: Any) -> NDArray[np.bool_]:
    return np.isfinite(np.asarray(points, dtype=np.float64)).all(axis=-1)


class RerunLog:
    """A Rerun recording of classified frames.

    Parameters
    ----------
    target : str or None
        An ``.rrd`` file to write (refused when it exists, unless ``overwrite``); None
        (or ``""``): spawn a Rerun viewer and stream to it, as ``rerun.spawn()`` does.
    overwrite : bool, keyword-only
        Replace an existing ``target``.
    extrinsics : Extrinsics, keyword-only, optional
        The camera-to-base transform: ``world`` is then the robot's base frame.
    name : str, keyword-only
        The recording's name (shown in the viewer).

    Raises
    ------
    MissingExtraError
        The Rerun SDK is not installed.
    OverwriteError, OutputError
        ``target`` exists (without ``overwrite``) or cannot be written.
    """

    def __init__(
        self,
        target: str | None,
        *,
        overwrite: bool = False,
        extrinsics: Extrinsics | None = None,
        name: str = "dgli",
    ) -> None:
        rr = _rerun()
        self.rr = rr
        self.path = Path(target) if target else None
        if self.path is not None:
            if self.path.exists() and not overwrite:
                raise OverwriteError(
                    f"'{self.path}' exists; choose another file or add --overwrite"
                )
            if not self.path.parent.is_dir():
                raise OutputError(f"cannot write '{self.path}': no folder '{self.path.parent}'")
        self.rec = rr.RecordingStream(APPLICATION_ID, recording_id=None)
        if self.path is not None:
            self.rec.save(str(self.path))
        else:
            self.rec.spawn()
        self.rec.send_recording_name(name)
        self._pinhole_logged = False
        self._static(extrinsics)

    def _static(self, extrinsics: Extrinsics | None) -> None:
        """The frames: ``world`` (camera or base) and the camera in it."""
        rr = self.rr
        if extrinsics is None:
            self.rec.log("world", rr.ViewCoordinates.RDF, static=True)
            return
        self.rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        m = np.asarray(extrinsics.matrix, dtype=np.float64)
        self.rec.log(
            "world/camera",
            rr.Transform3D(translation=m[:3, 3], mat3x3=m[:3, :3]),
            static=True,
        )

    def frame(
        self,
        index: int,
        time: float | None,
        *,
        state: StateKey | None,
        smoothed: StateKey | None,
        confidence: float | None,
        note: str | None = None,
        frame: RGBDFrame | None = None,
        result: FrameResult | None = None,
        corners: dict[str, Any] | None = None,
        plan: Plan | None = None,
        centroids: Any = None,
    ) -> None:
        """Log one frame.

        Parameters
        ----------
        index : int
            The frame's number (the ``frame`` timeline).
        time : float or None
            Seconds on the source's clock (the ``time`` timeline).
        state, smoothed : (class, variant) or None
            The frame's own state (None: cannot tell) and the smoothed one.
        confidence : float or None
        note : str, optional
            Why there is no state.
        frame, result : RGBDFrame, FrameResult, keyword-only, optional
            The frame and its classification (all that is drawn: image, stickers found
            and missing, 3D stickers, segments, table, corners).
        corners : dict, keyword-only, optional
            The corners' JSON (``dgli classify --json``), when there is no ``result``.
        plan : Plan, keyword-only, optional
            A plan from this frame: its first step's grasp, place and fold line.
        centroids : array (16, 2), keyword-only, optional
            The stickers found in pixels (NaN where not), when there is no ``result``.
        """
        rr = self.rr
        self.rec.set_time("frame", sequence=int(index))
        if time is not None:
            self.rec.set_time("time", duration=float(time))
        self._log_state(index, state, smoothed, confidence, note)
        if frame is not None:
            self._log_image(frame)
        if result is not None:
            self._log_result(result, frame)
            aff = getattr(result, "affordances", None)
            corners = aff.to_json()["corners"] if aff is not None else corners
        elif centroids is not None and frame is not None:
            self._log_found(np.asarray(centroids, dtype=np.float64))
        if corners is not None:
            self._log_corners(corners)
        if plan is not None and plan.steps:
            self._log_plan(plan)
        else:
            self.rec.log("world/camera/plan", rr.Clear(recursive=True))

    def _log_state(
        self, index: int, state: StateKey | None, smoothed: StateKey | None,
        confidence: float | None, note: str | None,
    ) -> None:
        rr = self.rr
        conf = float("nan") if confidence is None else float(confidence)
        self.rec.log("state/confidence", rr.Scalars(conf))
        self.rec.log("state/class", rr.Scalars(class_number(state)))
        self.rec.log("state/smoothed", rr.Scalars(class_number(smoothed)))
        text = f"frame {index}: {_state_text(state)}"
        if confidence is not None:
            text += f", confidence {confidence:.2f}"
        text += f"; smoothed {_state_text(smoothed)}"
        if state is None and note:
            text += f" ({note})"
        level = rr.TextLogLevel.INFO if state is not None else rr.TextLogLevel.WARN
        self.rec.log("state/log", rr.TextLog(text, level=level))

    def _log_image(self, frame: RGBDFrame) -> None:
        rr = self.rr
        k = frame.intrinsics
        if not self._pinhole_logged:
            self.rec.log(
                "world/camera/image",
                rr.Pinhole(
                    focal_length=[k.fx, k.fy], principal_point=[k.cx, k.cy],
                    resolution=[k.width, k.height],
                    camera_xyz=rr.ViewCoordinates.RDF,
                ),
                static=True,
            )
            self._pinhole_logged = True
        self.rec.log(
            "world/camera/image",
            rr.Image(np.ascontiguousarray(frame.color)).compress(jpeg_quality=JPEG_QUALITY),
        )

    def _log_found(self, centroids: NDArray[np.float64]) -> None:
        rr = self.rr
        seen = _finite(centroids)
        ids = np.flatnonzero(seen)
        self.rec.log(
            "world/camera/image/found",
            rr.Points2D(centroids[seen], labels=[str(i) for i in ids], class_ids=ids,
                        colors=[FOUND] * len(ids), radii=4.0, show_labels=True),
        )

    def _log_result(self, result: FrameResult, frame: RGBDFrame | None) -> None:
        """The stickers found and missing, the 3D stickers and segments, the table."""
        from .overlay import overlay_evidence

        rr = self.rr
        centroids = np.asarray(result.detections.centroids, dtype=np.float64)
        if frame is not None:
            self._log_found(centroids)
            self._log_missing(result, overlay_evidence(result))
            ends = centroids.reshape(8, 2, 2)
            ok = _finite(ends).all(axis=1)
            self.rec.log(
                "world/camera/image/segments",
                rr.Arrows2D(origins=ends[ok, 0], vectors=ends[ok, 1] - ends[ok, 0],
                            colors=[SEGMENT] * int(ok.sum()),
                            labels=[f"segment {i}" for i in np.flatnonzero(ok)]),
            )
        pts = np.asarray(result.markers.points, dtype=np.float64)
        seen = _finite(pts)
        self.rec.log(
            "world/camera/stickers",
            rr.Points3D(pts[seen], labels=[str(i) for i in np.flatnonzero(seen)],
                        radii=0.006, colors=[FOUND] * int(seen.sum())),
        )
        seg = np.asarray(result.observation.segments, dtype=np.float64)
        ok = _finite(seg).all(axis=1)
        self.rec.log(
            "world/camera/segments",
            rr.Arrows3D(origins=seg[ok, 0], vectors=seg[ok, 1] - seg[ok, 0],
                        colors=[SEGMENT] * int(ok.sum()),
                        labels=[f"segment {i}" for i in np.flatnonzero(ok)]),
        )
        self._log_table(result, pts[seen])

    def _log_missing(self, result: FrameResult, evidence: Any) -> None:
        rr = self.rr
        if evidence is None:
            self.rec.log("world/camera/image/missing", rr.Clear(recursive=False))
            return
        pred = np.asarray(evidence.predicted_px, dtype=np.float64)
        show = [
            k for k in range(len(pred))
            if np.isfinite(pred[k]).all() and (evidence.hidden[k] or evidence.reasons[k])
        ]
        labels = [
            f"{k}? hidden" if evidence.hidden[k] else f"{k}? {evidence.reasons[k]}"
            for k in show
        ]
        colours = [HIDDEN if evidence.hidden[k] else UNKNOWN for k in show]
        self.rec.log(
            "world/camera/image/missing",
            rr.Points2D(pred[show] if show else np.zeros((0, 2)), labels=labels,
                        colors=colours, radii=9.0, show_labels=True),
        )

    def _log_table(self, result: FrameResult, stickers: NDArray[np.float64]) -> None:
        """The table plane: a translucent square centred under the stickers, and its
        normal (from the plane's point nearest the stickers' centre)."""
        rr = self.rr
        obs = result.observation
        up = np.asarray(obs.up, dtype=np.float64)
        heights = None if obs.heights_mm is None else np.asarray(obs.heights_mm, dtype=float)
        if not len(stickers) or heights is None:
            return
        pts = np.asarray(result.markers.points, dtype=np.float64)
        ok = _finite(pts) & np.isfinite(heights)
        if not ok.any():
            return
        offset = float(np.median(pts[ok] @ up - heights[ok] * 1e-3))
        centre = stickers.mean(axis=0)
        centre = centre - (centre @ up - offset) * up
        a = np.cross(up, [1.0, 0.0, 0.0] if abs(up[0]) < 0.9 else [0.0, 1.0, 0.0])
        a /= np.linalg.norm(a)
        b = np.cross(up, a)
        h = TABLE_HALF_M
        quad = [centre + h * (sa * a + sb * b) for sa, sb in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
        self.rec.log(
            "world/camera/table",
            rr.Mesh3D(vertex_positions=quad, triangle_indices=[[0, 1, 2], [0, 2, 3]],
                      albedo_factor=[0.55, 0.45, 0.35, 0.35]),
        )
        self.rec.log(
            "world/camera/table/up",
            rr.Arrows3D(origins=[centre], vectors=[0.1 * up], colors=[(120, 120, 255)],
                        labels=["table normal"]),
        )

    def _log_corners(self, corners: dict[str, Any]) -> None:
        rr = self.rr
        names = [n for n, c in corners.items() if c.get("point") is not None]
        if not names:
            self.rec.log("world/camera/corners", rr.Clear(recursive=False))
            return
        self.rec.log(
            "world/camera/corners",
            rr.Points3D(
                [corners[n]["point"] for n in names],
                labels=[f"{n}" + (" graspable" if corners[n].get("graspable") else "")
                        for n in names],
                colors=[GRASPABLE if corners[n].get("graspable") else NOT_GRASPABLE
                        for n in names],
                radii=0.01,
            ),
        )

    def _log_plan(self, plan: Plan) -> None:
        """The plan's first step: grasp, place and fold line (camera frame)."""
        rr = self.rr
        step = plan.steps[0]
        what = step.corner or step.side or ""
        if step.grasp_point is not None:
            self.rec.log("world/camera/plan/grasp", rr.Points3D(
                [step.grasp_point], labels=[f"grasp {what} ({step.fold})"], colors=[GRASP],
                radii=0.012))
        if step.place_point is not None:
            self.rec.log("world/camera/plan/place", rr.Points3D(
                [step.place_point], labels=[f"place {what}"], colors=[PLACE], radii=0.012))
        if step.fold_line is not None:
            self.rec.log("world/camera/plan/fold_line", rr.LineStrips3D(
                [list(step.fold_line)], colors=[FOLD], labels=["fold line"]))

    def close(self) -> None:
        """Flush what was logged and let the file (or the viewer) go."""
        self.rec.flush()
        self.rec.disconnect()


def log_timeline(
    log: RerunLog, timeline: Any, outcomes: list[Any], frames: Any = None
) -> int:
    """A tracked recording logged frame by frame (``dgli track --rerun``): each frame's
    own state, confidence and reason, the smoothed state, its colour image with the
    stickers found, and its corners in 3D.

    Parameters
    ----------
    log : RerunLog
    timeline : Timeline
        :func:`~dgli_vision.analysis.track.track_outcomes`'s timeline.
    outcomes : list of PairOutcome
        The frames' own answers, in the timeline's order.
    frames : iterable, optional
        The recording's frames again (each with ``load()``), in the same order: their
        colour images (a frame that cannot be read again is logged without one).

    Returns
    -------
    int
        The frames logged with their image.
    """
    from ..core.errors import DgliError

    images = iter(frames) if frames is not None else iter(())
    shown = 0
    for f, o in zip(timeline.frames, outcomes):
        pair = next(images, None)
        frame = None
        if pair is not None:
            try:
                frame = pair.load()
            except (DgliError, OSError):
                frame = None
        state = None if f.raw_class is None else (f.raw_class, f.raw_variant)
        centroids = np.array(o.centroids, dtype=np.float64) if o.centroids else None
        log.frame(
            f.index, f.time, state=state, smoothed=(f.smoothed_class, f.smoothed_variant),
            confidence=f.confidence, note=f.note, frame=frame, corners=f.corners,
            centroids=centroids if centroids is not None and centroids.shape == (16, 2)
            else None,
        )
        shown += frame is not None
    return shown
