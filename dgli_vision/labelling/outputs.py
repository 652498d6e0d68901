"""The files of ``dgli label``: per episode JSON lines, CSV and a timeline picture, and a
summary over all episodes."""

from __future__ import annotations

import json
from collections import Counter
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..analysis.evaluate import json_ready
from ..core.classes import CLASS_IDS, CLASS_NAMES
from ..core.io import csv_table
from .label import EpisodeFailure, EpisodeLabels

__all__ = ["CSV_COLUMNS", "episode_files", "episode_names", "summary_of"]

#: Columns of an episode's CSV file.
CSV_COLUMNS = (
    "frame",
    "class",
    "variant",
    "fold_in_progress",
    "past_90",
    "confidence",
    "distance",
    "smoothed_class",
    "smoothed_variant",
    "note",
    "omnigibson_folded",
    "omnigibson_unfolded",
)


def episode_names(paths: Sequence[str]) -> list[str]:
    """A distinct file-name stem for each episode (its name, numbered when repeated)."""
    seen: Counter[str] = Counter()
    out = []
    for p in paths:
        stem = Path(p).stem or "episode"
        seen[stem] += 1
        out.append(stem if seen[stem] == 1 else f"{stem}_{seen[stem]}")
    return out


def _csv(ep: EpisodeLabels) -> str:
    def cell(v: object) -> object:
        return "" if v is None else v

    rows = [
        tuple(
            cell(v)
            for v in (
                f.index,
                f.class_id,
                f.variant,
                f.progress["fold"] if f.progress else None,
                f.progress["past_90"] if f.progress else None,
                f.confidence,
                f.distance,
                f.smoothed_class,
                f.smoothed_variant,
                f.note,
                f.omnigibson[0] if f.omnigibson else None,
                f.omnigibson[1] if f.omnigibson else None,
            )
        )
        for f in ep.frames
    ]
    return csv_table(CSV_COLUMNS, rows)


def timeline_picture(ep: EpisodeLabels, title: str) -> np.ndarray:
    """The episode's timeline: frames across, classes down (BGR)."""
    from ..analysis.report import timeline_image

    return timeline_image(
        CLASS_IDS,
        [f.smoothed_class for f in ep.frames],
        [f.class_id for f in ep.frames],
        names=CLASS_NAMES,
        title=title,
    )


def episode_files(out: Path, name: str, ep: EpisodeLabels) -> dict[Path, Any]:
    """``NAME.jsonl`` (one frame a line), ``NAME.csv`` and ``NAME_timeline.png``."""
    lines = "".join(json.dumps(json_ready(f.to_dict())) + "\n" for f in ep.frames)
    return {
        out / f"{name}.jsonl": lines,
        out / f"{name}.csv": _csv(ep),
        out / f"{name}_timeline.png": timeline_picture(ep, f"dgli label: {ep.path}"),
    }


def summary_of(results: Sequence[EpisodeLabels | EpisodeFailure]) -> dict[str, Any]:
    """Over all episodes: frames, frames with a verdict, the smoothed states' frame
    counts, state changes and the episodes that failed."""
    done = [r for r in results if isinstance(r, EpisodeLabels)]
    states: Counter[str] = Counter()
    for ep in done:
        for f in ep.frames:
            key = f.smoothed_class + (f" {f.smoothed_variant}" if f.smoothed_variant else "")
            states[key] += 1
    n_frames = sum(len(ep.frames) for ep in done)
    answered = sum(f.class_id is not None for ep in done for f in ep.frames)
    return {
        "episodes": len(results),
        "labelled": len(done),
        "frames": n_frames,
        "frames_with_class": answered,
        "changes": sum(len(ep.changes) for ep in done),
        "smoothed_states": dict(sorted(states.items())),
        "failed": [
            {"path": r.path, "error": r.error}
            for r in results
            if isinstance(r, EpisodeFailure)
        ],
    }
