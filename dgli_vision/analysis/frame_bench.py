"""The per-frame bench: every frame of a varied set, not the median of a few samples.

The set is rendered in memory: one frame per class under every capture condition
(``dgli render --conditions``; ``vga`` is another camera's intrinsics), plus the frames
of a folding sequence with a gripper holding the corner it folds (folds in progress).
Each frame is classified ``repeats`` times on one core and its best time kept; the
stages' times come from the pipeline's own clock (``FrameResult.timings_ms``), so a
regression shows where it is. Nothing here prints.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ..classifier.references import ReferenceSet
from ..core.classes import CLASS_IDS
from ..core.frame import RGBDFrame
from ..sim.condition_names import CONDITION_NAMES

__all__ = [
    "AnchorBench",
    "AnchorTime",
    "FrameBench",
    "FrameTime",
    "aruco_detector",
    "bench_files",
    "bench_frames",
    "bench_set",
    "bench_vs_aruco",
]

#: The sequence rendered with a gripper for the frames of folds in progress.
SEQUENCE = "II"


@dataclass(frozen=True)
class FrameTime:
    """One frame's best time and its stages' times (ms)."""

    condition: str
    name: str
    total_ms: float
    stages_ms: dict[str, float]


@dataclass(frozen=True)
class FrameBench:
    """Every frame's times, with their summaries."""

    frames: tuple[FrameTime, ...]

    def summary(self, condition: str | None = None) -> tuple[float, float, float]:
        """Median, 90th percentile and largest time of the frames (of one condition), ms."""
        t = np.array(
            [f.total_ms for f in self.frames if condition in (None, f.condition)], dtype=float
        )
        return float(np.median(t)), float(np.percentile(t, 90)), float(t.max())

    def stage_summary(self) -> dict[str, tuple[float, float]]:
        """Median and 90th percentile of each stage's time over the frames, ms, in the
        order the stages run."""
        names: list[str] = []
        for f in self.frames:
            names += [s for s in f.stages_ms if s not in names]
        out = {}
        for s in names:
            t = np.array([f.stages_ms.get(s, 0.0) for f in self.frames])
            out[s] = (float(np.median(t)), float(np.percentile(t, 90)))
        return out

    def conditions(self) -> list[str]:
        """The conditions of the set, in order."""
        seen: list[str] = []
        for f in self.frames:
            if f.condition not in seen:
                seen.append(f.condition)
        return seen

    def slowest(self, k: int = 5) -> list[FrameTime]:
        """The ``k`` slowest frames."""
        return sorted(self.frames, key=lambda f: -f.total_ms)[:k]


def bench_set(
    seed: int,
    *,
    per_condition: int = 12,
    sequence_frames: int = 12,
    conditions: Sequence[str] = (),
) -> Iterator[tuple[str, str, RGBDFrame]]:
    """The frames of the bench, rendered in memory: (condition, name, frame).

    Parameters
    ----------
    seed : int
    per_condition : int, keyword-only
        Frames per condition, one class after another (12: one of each class).
    sequence_frames : int, keyword-only
        Frames of the folding sequence with a gripper (0: none; a sequence has at least
        2, so 1 gives 2).
    conditions : sequence of str, keyword-only
        The capture conditions after ``clean`` (default: every one the renderer knows).
    """
    from ..sim.dataset import render_sample, render_sequence

    for condition in ("clean", *(conditions or CONDITION_NAMES)):
        names = () if condition == "clean" else (condition,)
        for k in range(per_condition):
            class_id = CLASS_IDS[k % len(CLASS_IDS)]
            s = render_sample(class_id, k // len(CLASS_IDS), seed, conditions=names)
            r = s.result
            yield condition, s.name, RGBDFrame(r.color, r.depth_mm, r.intrinsics, s.name, s.name)
    if sequence_frames:
        for s in render_sequence(SEQUENCE, max(2, sequence_frames), seed,
                                 conditions=("grasp",)):
            r = s.result
            yield (
                f"sequence {SEQUENCE} held",
                s.name,
                RGBDFrame(r.color, r.depth_mm, r.intrinsics, s.name, s.name),
            )


def bench_frames(
    frames: Iterator[tuple[str, str, RGBDFrame]], references: ReferenceSet, *, repeats: int = 3
) -> FrameBench:
    """Classify each frame ``repeats`` times and keep its best time.

    Parameters
    ----------
    frames : iterable of (condition, name, RGBDFrame)
    references : ReferenceSet
    repeats : int, keyword-only

    Returns
    -------
    FrameBench
    """
    from ..classifier.pipeline import classify_frame

    out = []
    for condition, name, frame in frames:
        best, stages = np.inf, {}
        for _ in range(max(repeats, 1)):
            t0 = time.perf_counter()
            result = classify_frame(frame, references)
            dt = (time.perf_counter() - t0) * 1e3
            if dt < best:
                best, stages = dt, dict(result.timings_ms)
        out.append(FrameTime(condition, name, best, stages))
    return FrameBench(tuple(out))


def bench_files(
    frames: Sequence[tuple[str, str, RGBDFrame]],
    references: ReferenceSet,
    folder: str | Path,
    *,
    repeats: int = 3,
) -> NDArray[np.float64]:
    """Each frame's best time from its files: written as PNG pairs (as ``dgli render``
    writes them) into ``folder``, then read (:func:`~dgli_vision.sources.frames.read_frame`,
    which decodes the two images concurrently) and classified, ``repeats`` times.

    Returns
    -------
    ndarray
        The best time of each frame, ms, in order.
    """
    from ..classifier.pipeline import classify_frame
    from ..core.io import write_png
    from ..sources.frames import read_frame

    root = Path(folder)
    out = []
    for k, (_, _, frame) in enumerate(frames):
        color, depth = root / f"{k:04d}_color.png", root / f"{k:04d}_depth.png"
        write_png(color, np.ascontiguousarray(frame.color[..., ::-1]))
        write_png(depth, frame.depth_mm)
        best = np.inf
        for _ in range(max(repeats, 1)):
            t0 = time.perf_counter()
            classify_frame(read_frame(color, depth, frame.intrinsics), references)
            best = min(best, (time.perf_counter() - t0) * 1e3)
        out.append(best)
    return np.array(out)


@dataclass(frozen=True)
class AnchorTime:
    """One frame's best time (ms) with ours and with the anchor (ArUco), measured in
    turn; ``anchor_spread`` is the anchor's slowest over its best time on this frame;
    ``ours_cpu_ms`` and ``anchor_cpu_ms`` the best processor time of the thread
    (``time.thread_time``), which other processes taking the core do not inflate."""

    condition: str
    name: str
    ours_ms: float
    anchor_ms: float
    anchor_spread: float
    ours_cpu_ms: float = float("nan")
    anchor_cpu_ms: float = float("nan")

    @property
    def ratio(self) -> float:
        """Ours over the anchor on this frame."""
        return self.ours_ms / max(self.anchor_ms, 1e-9)


@dataclass(frozen=True)
class AnchorBench:
    """Every frame's time against the anchor's, with their summaries."""

    frames: tuple[AnchorTime, ...]

    def _of(self, condition: str | None) -> list[AnchorTime]:
        return [f for f in self.frames if condition in (None, f.condition)]

    def ratios(
        self, condition: str | None = None, *, cpu: bool = False
    ) -> tuple[float, float, float]:
        """Median of ours over median of the anchor's, and the 90th percentile and
        largest of the per-frame ratios (of one condition, or of every frame); ``cpu``:
        of the processor times."""
        fs = self._of(condition)
        o = np.array([f.ours_cpu_ms if cpu else f.ours_ms for f in fs])
        a = np.array([f.anchor_cpu_ms if cpu else f.anchor_ms for f in fs])
        per = o / np.maximum(a, 1e-9)
        return (
            float(np.median(o) / np.median(a)), float(np.percentile(per, 90)),
            float(per.max()),
        )

    def medians_ms(self, condition: str | None = None) -> tuple[float, float]:
        """Median time of ours and of the anchor, ms."""
        fs = self._of(condition)
        return (
            float(np.median([f.ours_ms for f in fs])),
            float(np.median([f.anchor_ms for f in fs])),
        )

    def anchor_spread(self) -> float:
        """The median over frames of the anchor's slowest over best time: about 1 on a
        quiet machine; well above (say 1.3) when other work took the core."""
        return float(np.median([f.anchor_spread for f in self.frames]))

    def conditions(self) -> list[str]:
        """The conditions of the set, in order."""
        seen: list[str] = []
        for f in self.frames:
            if f.condition not in seen:
                seen.append(f.condition)
        return seen


def aruco_detector() -> Callable[[NDArray[np.uint8]], object]:
    """The anchor: OpenCV's ArUco detector with its defaults on the 4x4 dictionary of 50
    markers, as a function of a grey image (it only looks for markers)."""
    import cv2

    detector = cv2.aruco.ArucoDetector(
        cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_50),
        cv2.aruco.DetectorParameters(),
    )
    return detector.detectMarkers


def bench_vs_aruco(
    frames: Iterator[tuple[str, str, RGBDFrame]], references: ReferenceSet, *, repeats: int = 3
) -> AnchorBench:
    """Each frame classified as :func:`~dgli_vision.classifier.api.classify_pair` does
    on arrays (references loaded), and looked at by ArUco's detector
    (:func:`aruco_detector`, on the frame's grey image), in turn, ``repeats`` times each;
    each one's best time is kept, in wall time and in the thread's processor time.
    Interleaving frame by frame makes a busy machine slow both alike; the ratios are the
    figure (on a very busy machine, those of the processor times: a short call fits
    between other processes' turns more often than a long one does).

    Parameters
    ----------
    frames : iterable of (condition, name, RGBDFrame)
    references : ReferenceSet
    repeats : int, keyword-only

    Returns
    -------
    AnchorBench
    """
    import cv2

    from ..classifier.api import classify_pair

    detect = aruco_detector()

    def ours(frame: RGBDFrame) -> None:
        classify_pair(frame.color, frame.depth_mm, frame.intrinsics, references)

    out = []
    for condition, name, frame in frames:
        grey = cv2.cvtColor(np.ascontiguousarray(frame.color), cv2.COLOR_RGB2GRAY)
        t_ours, t_anchor, c_ours, c_anchor = [], [], [], []
        for _ in range(max(repeats, 1)):
            t0, c0 = time.perf_counter(), time.thread_time()
            ours(frame)
            t1, c1 = time.perf_counter(), time.thread_time()
            detect(grey)
            t2, c2 = time.perf_counter(), time.thread_time()
            t_ours.append(t1 - t0)
            t_anchor.append(t2 - t1)
            c_ours.append(c1 - c0)
            c_anchor.append(c2 - c1)
        out.append(
            AnchorTime(
                condition, name, min(t_ours) * 1e3, min(t_anchor) * 1e3,
                max(t_anchor) / max(min(t_anchor), 1e-12), min(c_ours) * 1e3,
                min(c_anchor) * 1e3,
            )
        )
    return AnchorBench(tuple(out))
