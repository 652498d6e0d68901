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
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ..classifier.references import ReferenceSet
from ..core.classes import CLASS_IDS
from ..sim.condition_names import CONDITION_NAMES
from ..sources.frames import RGBDFrame

__all__ = ["FrameBench", "FrameTime", "bench_files", "bench_frames", "bench_set"]

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


def bench_set(seed: int, *, per_condition: int = 12, sequence_frames: int = 12) -> Iterator[
    tuple[str, str, RGBDFrame]
]:
    """The frames of the bench, rendered in memory: (condition, name, frame).

    Parameters
    ----------
    seed : int
    per_condition : int, keyword-only
        Frames per condition, one class after another (12: one of each class).
    sequence_frames : int, keyword-only
        Frames of the folding sequence with a gripper (0: none; a sequence has at least
        2, so 1 gives 2).
    """
    from ..sim.dataset import render_sample, render_sequence

    for condition in ("clean", *CONDITION_NAMES):
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
