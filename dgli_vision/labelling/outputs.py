"""The files of ``dgli label``: per episode JSON lines, CSV and a timeline chart (SVG and
PNG), and a summary over all episodes (``summary.json`` and ``report.html``)."""

from __future__ import annotations

import json
from collections import Counter
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ..core.classes import CLASS_IDS, CLASS_NAMES
from ..core.io import csv_table
from .label import EpisodeLabels

__all__ = [
    "CSV_COLUMNS",
    "episode_files",
    "episode_names",
    "label_html",
    "summary_of_entries",
    "timeline_files",
]

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


def timeline_files(ep: EpisodeLabels, name: str, title: str) -> dict[str, Any]:
    """The episode's timeline as ``NAME_timeline.svg`` (for the page) and ``.png``:
    frames across, classes down, drawn by Matplotlib
    (:func:`~dgli_vision.analysis.charts.timeline_figure`, as ``dgli track``'s).

    The figure is dropped and collected here: ``dgli label`` writes an episode's files
    where a stop signal waits, and a figure left to the garbage collector would run its
    weak-reference callbacks wherever the signal then comes."""
    import gc

    from ..analysis.charts import chart_files, timeline_figure

    fig = timeline_figure(
        CLASS_IDS,
        [f.smoothed_class for f in ep.frames],
        [f.class_id for f in ep.frames],
        names=CLASS_NAMES,
        title=title,
    )
    files = chart_files(f"{name}_timeline", fig)
    fig.clear()
    del fig
    gc.collect()
    return files


def episode_files(out: Path, name: str, ep: EpisodeLabels) -> dict[Path, Any]:
    """``NAME.jsonl`` (one frame a line), ``NAME.csv`` and ``NAME_timeline.svg`` and
    ``.png``."""
    lines = "".join(json.dumps(f.to_json()) + "\n" for f in ep.frames)
    charts = timeline_files(ep, name, f"dgli label: {ep.path}")
    return {
        out / f"{name}.jsonl": lines,
        out / f"{name}.csv": _csv(ep),
        **{out / k: v for k, v in charts.items()},
    }


def _state(s: dict[str, Any]) -> str:
    return s["class"] + (f" {s['variant']}" if s.get("variant") else "")


def label_html(entries: Sequence[dict[str, Any]], summary: dict[str, Any], title: str) -> str:
    """``report.html`` of a ``dgli label -o`` run: the summary first, a table of the
    episodes, then each episode's timeline (its SVG, linking to the PNG) and its files.

    Parameters
    ----------
    entries : sequence of dict
        The episodes' records as results.jsonl keeps them: ``{"episode", "path",
        "result"}`` or ``{"episode", "path", "error"}``.
    summary : dict
        :func:`summary_of_entries` of them.
    title : str
    """
    from html import escape

    from ..analysis.html_report import html_chart, html_list, html_page, html_table
    from ..core.words import counted

    done = [e for e in entries if "result" in e]
    head = [
        f"{summary['labelled']} of {counted(summary['episodes'], 'episode')} labelled, "
        f"{counted(summary['frames'], 'frame')} ({summary['frames_with_class']} with a "
        f"class), {counted(summary['changes'], 'state change')}",
        *(f"failed: {f['path']}: {f['error']}" for f in summary["failed"]),
    ]
    rows = []
    for e in done:
        ep = e["result"]
        frames = ep["frames"]
        rows.append((
            e["episode"], len(frames), sum(f["class"] is not None for f in frames),
            _state(frames[0]["smoothed"]) if frames else "-",
            _state(frames[-1]["smoothed"]) if frames else "-", len(ep["changes"]),
        ))
    body = [html_list(head)]
    if rows:
        body.append(html_table(
            ("episode", "frames", "with a class", "starts as", "ends as", "state changes"),
            rows,
        ))
    for e in done:
        name = e["episode"]
        files = ", ".join(
            f'<a href="{escape(name)}{ext}">{escape(name)}{ext}</a>' for ext in (".jsonl", ".csv")
        )
        body += [
            f"<h2>{escape(name)}</h2>",
            f'<p class="note">{escape(e["path"])}; the frames: {files}</p>',
            html_chart(f"{name}_timeline", f"timeline of {name}",
                       "frames across, states down; the line is the smoothed state"),
        ]
    return html_page(title, body)


def summary_of_entries(entries: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """Over all episodes: frames, frames with a verdict, the smoothed states' frame
    counts, state changes and the episodes that failed, from the episodes' records as
    ``dgli label -o`` keeps them in results.jsonl: ``{"path", "result": the episode's
    JSON object}`` or ``{"path", "error"}``."""
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
