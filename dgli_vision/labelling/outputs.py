"""The files of ``dgli label``: per episode JSON lines, CSV and a timeline picture, and a
summary over all episodes."""

from __future__ import annotations

import json
from collections import Counter
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..core.classes import CLASS_IDS, CLASS_NAMES
from ..core.io import csv_table
from .label import EpisodeFailure, EpisodeLabels

__all__ = ["CSV_COLUMNS", "episode_files", "episode_names", "summary_of", "summary_of_entries"]

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
    lines = "".join(json.dumps(f.to_json()) + "\n" for f in ep.frames)
    return {
        out / f"{name}.jsonl": lines,
        out / f"{name}.csv": _csv(ep),
        out / f"{name}_timeline.png": timeline_picture(ep, f"dgli label: {ep.path}"),
    }


def summary_of(results: Sequence[EpisodeLabels | EpisodeFailure]) -> dict[str, Any]:
    """Over all episodes: frames, frames with a verdict, the smoothed states' frame
    counts, state changes and the episodes that failed."""
    entries = [
        {"path": r.path, "error": r.error}
        if isinstance(r, EpisodeFailure)
        else {"path": r.path, "result": r.to_json()}
        for r in results
    ]
    return summary_of_entries(entries)


def summary_of_entries(entries: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """:func:`summary_of` from the episodes' records as ``dgli label -o`` keeps them in
    results.jsonl: ``{"path", "result": the episode's JSON object}`` or ``{"path",
    "error"}``."""
    done = [e["result"] for e in entries if "result" in e]
    states: Counter[str] = Counter()
    for ep in done:
        for f in ep["frames"]:
            s = f["smoothed"]
            states[s["class"] + (f" {s['variant']}" if s["variant"] else "")] += 1
    goals = [ep["goal"] for ep in done if ep.get("goal")]
    goal = {}
    if goals:
        goal = {"goal": {
            "episodes": len(goals),
            "softgym_success": sum(g["softgym"]["success"] for g in goals),
            "dgli_success": sum(g["dgli"]["success"] is True for g in goals),
            "dgli_cannot_tell": sum(g["dgli"]["success"] is None for g in goals),
        }}
    return {
        "episodes": len(entries),
        "labelled": len(done),
        "frames": sum(len(ep["frames"]) for ep in done),
        "frames_with_class": sum(f["class"] is not None for ep in done for f in ep["frames"]),
        "changes": sum(len(ep["changes"]) for ep in done),
        "smoothed_states": dict(sorted(states.items())),
        "failed": [{"path": e["path"], "error": e["error"]} for e in entries if "error" in e],
        **goal,
    }
