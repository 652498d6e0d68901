"""The report of a state timeline: what ``dgli track --report DIR`` and ``dgli sequence
--report DIR`` write, built in memory (the CLI writes the files).

The same files for both: the timeline (``timeline.json``, ``timeline.csv``, the chart
``timeline.svg`` and ``.png``), the frames' distance heatmap (``distances.svg`` and
``.png``), ``report.md`` and
``report.html`` (the summary, the three outcomes when the frames are labelled, the
timeline, and a gallery of the wrong and "cannot tell" frames with their overlays and
reasons, under ``overlays/``: each gallery picture is a thumbnail of the napkin
(``overlays/thumbs/``, cropped to the stickers and large enough to read) linking to the
whole overlay).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..core.classes import CLASS_IDS, CLASS_NAMES
from ..core.io import csv_table
from .charts import chart_files, heatmap_figure, timeline_figure
from .evaluate import coordinate_matrix, outcome_counts, outcome_fields, outcomes_text
from .evaluation_report import heatmap_sample, overlay_name, pair_overlays, sample_distance_matrix
from .html_report import (
    cannot_tell_text,
    html_chart,
    html_list,
    html_page,
    outcomes_html,
)
from .report import markdown_table
from .track import TIMELINE_COLUMNS, Timeline, timeline_rows

__all__ = [
    "GALLERY_MAX",
    "THUMB_WIDTH",
    "TRACK_REPORT_FILES",
    "overlay_thumbnail",
    "thumb_name",
    "timeline_json",
    "timeline_outcome_fields",
    "track_report",
]

#: Most frames of each kind (wrong, "cannot tell") drawn as overlays, evenly spread in
#: time: a long recording's report stays a bounded size (the others are listed).
GALLERY_MAX = 48
#: A thumbnail's width in pixels (shown at this width in the report's gallery).
THUMB_WIDTH = 480

#: The files of every timeline report (besides the overlays and a track's results.jsonl).
TRACK_REPORT_FILES = (
    "timeline.json",
    "timeline.csv",
    "timeline.png",
    "timeline.svg",
    "distances.png",
    "distances.svg",
    "report.md",
    "report.html",
)


def _name(c: str | None) -> str:
    return f"{c} {CLASS_NAMES.get(c, '')}".strip() if c else "none"


def _state(cls: str, variant: str | None) -> str:
    return _name(cls) + (f" {variant}" if variant else "")


def timeline_outcome_fields(outcomes: Sequence[Any], labelled: bool) -> dict[str, Any]:
    """``"outcomes"``, ``"coverage"`` and ``"accuracy_answered"`` of the frames' own
    answers when they are labelled (:func:`~dgli_vision.analysis.evaluate.outcome_fields`);
    nothing without labels."""
    return outcome_fields(outcome_counts(outcomes)) if labelled else {}


def timeline_json(
    head: dict[str, Any], timeline: Timeline, outcomes: Sequence[Any], labelled: bool
) -> dict[str, Any]:
    """The JSON of ``dgli track --json`` (and ``timeline.json``; docs/json.md): ``head``
    (what was read: ``folder`` and ``recording``, or ``sequence``), ``n_frames``, the
    timeline's frames, changes, gaps and score, and the frames' own outcomes when
    ``labelled``."""
    return {
        **head,
        "n_frames": len(outcomes),
        **timeline.to_json(),
        **timeline_outcome_fields(outcomes, labelled),
    }


def _distances(outcomes: Sequence[Any], timeline: Timeline) -> tuple[Any, str] | None:
    """The heatmap of the frames' dGLI distances (a sample of frames evenly spread in
    time when there are many; a Matplotlib figure), with frame ticks and the smoothed
    states' boundaries, and the words that say what it shows; None without frames."""
    shown = heatmap_sample(["frames"] * len(outcomes))  # evenly spread in time
    if len(shown) < 2:
        return None
    part = "" if len(shown) == len(outcomes) else f" ({len(shown)} of {len(outcomes)} frames)"
    image = heatmap_figure(
        sample_distance_matrix(coordinate_matrix([outcomes[k] for k in shown])),
        title="frames: Spearman distance of the dGLI alone" + part,
        groups=[timeline.frames[k].smoothed_class for k in shown],
        value_label="1 - rho",
        ticks=shown,
        group_label="smoothed state",
        missing="no distance: the two share fewer than 3 measured coordinates",
    )
    note = (
        "Spearman distance (1 - rho) between the frames' 28 dGLI coordinates alone, "
        f"frames in time order{part}; lines mark where the smoothed state changes. It is "
        "not the classifier's distance, which also weighs which stickers are seen, their "
        "height and the napkin's footprint: states the dGLI alone cannot tell apart (a "
        "corner folded over or under) look alike here."
    )
    return image, note


def _not_right(outcomes: Sequence[Any], labelled: bool) -> tuple[list, list]:
    """The frames answered wrong (labelled recordings only) and "cannot tell"."""
    wrong = [o for o in outcomes if labelled and o.predicted is not None and not o.correct]
    told = [o for o in outcomes if o.error is None and o.predicted is None]
    return wrong, told


def _summary_lines(data: dict[str, Any], timeline: Timeline, labelled: bool) -> list[str]:
    """The summary as plain lines (Markdown and HTML both list them)."""
    frames = timeline.frames
    first = next((f for f in frames if not f.gap), None)
    lines = [
        f"frames: {len(frames)}"
        + (f"; starts as {_state(first.smoothed_class, first.smoothed_variant)}" if first
           else "; no frame could be classified"),
        *[f"frame {t}: {_state(*a)} -> {_state(*b)}" for t, a, b in timeline.changes],
        f"gaps (not read or too little evidence): {sum(f.gap for f in frames)}",
    ]
    if labelled and "outcomes" in data:
        lines.append("each frame's own answer: " + outcomes_text(data["outcomes"], "frames"))
    sc = timeline.score
    if sc is not None:
        lines.append(
            f"frame accuracy {sc.raw_accuracy:.0%} per frame, {sc.smoothed_accuracy:.0%} "
            f"smoothed; state changes true at {list(sc.true_changes)}, found at "
            f"{list(sc.found_changes)} (precision {sc.precision:.2f}, recall {sc.recall:.2f})"
        )
    if data.get("command"):
        lines.append(f"command: {data['command']}")
    return lines


def _caption(o: Any, index: int) -> str:
    truth = f"true {_name(o.pair.label)}; " if o.pair.label else ""
    if o.predicted is None:
        return f"frame {index} ({o.pair.color}): {truth}{cannot_tell_text(o.reason)}"
    return f"frame {index} ({o.pair.color}): {truth}answered {_name(o.predicted)}"


def _markdown(
    title: str, lines: list[str], galleries: dict[str, list], overlays: dict, heat: str | None
) -> str:
    md = [f"# {title}", "", *[f"- {line}" for line in lines], "", "## Timeline", "",
          "![timeline](timeline.png)", ""]
    for section, items in galleries.items():
        md += [f"## {section} ({len(items)})", ""]
        rows = [
            [k, o.pair.color, _name(o.pair.label) if o.pair.label else "",
             _name(o.predicted) if o.predicted else "cannot tell", o.reason or "",
             f"[overlay]({overlay_name(o)})" if overlay_name(o) in overlays else ""]
            for k, o in items
        ]
        md += [markdown_table(["frame", "colour image", "true", "answer", "why", "overlay"],
                              rows) if rows else "None.\n"]
    if heat:
        md += ["## Distances between the frames", "", heat, "", "![distances](distances.png)", ""]
    return "\n".join(md) + "\n"


def _html(
    title: str,
    lines: list[str],
    counts: dict | None,
    galleries: dict[str, list],
    overlays: dict,
    heat: str | None,
) -> str:
    body = [html_list(lines)]
    if counts is not None:
        body.append(outcomes_html(counts["outcomes"], counts["coverage"],
                                  counts["accuracy_answered"]))
    body += [
        "<h2>Timeline</h2>",
        html_chart("timeline", "timeline",
                   "Line: the smoothed state; dot: the frame's own answer; ring: no answer "
                   "(cannot tell or not read); green: the true state."),
    ]
    for section, items in galleries.items():
        shown = [
            (overlay_name(o), _caption(o, k)) for k, o in items if overlay_name(o) in overlays
        ]
        body.append(_thumb_gallery(section, shown, overlays))
        rest = [_caption(o, k) for k, o in items if overlay_name(o) not in overlays]
        if rest:
            body.append(
                f"<p>Without an overlay (beyond the {GALLERY_MAX} drawn, evenly spread in "
                "time, or an image that cannot be read again):</p>" + html_list(rest)
            )
    if heat:
        body += ["<h2>Distances between the frames</h2>", html_chart("distances",
                                                                     "distances", heat)]
    return html_page(title, body)


def thumb_name(name: str) -> str:
    """The thumbnail of an overlay's report file: ``overlays/thumbs/<name>``."""
    head, _, tail = name.rpartition("/")
    return f"{head}/thumbs/{tail}" if head else f"thumbs/{tail}"


def overlay_thumbnail(
    color: NDArray[np.uint8], centroids: Any, evidence: Any = None, width: int = THUMB_WIDTH
) -> NDArray[np.uint8]:
    """A gallery's small picture of a frame: its colour image cropped to the napkin (the
    stickers found, with a margin of half their spread, at least a third of the image),
    scaled to ``width`` pixels, with the stickers, segments and missing stickers drawn
    at that size (large enough to read; the caption is the gallery's text).

    Parameters
    ----------
    color : ndarray of uint8, shape (H, W, 3)
        RGB.
    centroids : array, shape (16, 2)
        The stickers found (NaN where not); empty: the whole image.
    evidence : OverlayEvidence, optional
        Where the missing stickers lie, and the objects over the napkin.
    width : int

    Returns
    -------
    ndarray of uint8
        BGR, ready to write.
    """
    import cv2

    from .overlay import overlay_image

    h, w = color.shape[:2]
    pts = np.full((16, 2), np.nan)
    if len(centroids):
        pts = np.asarray(centroids, dtype=np.float64).reshape(-1, 2)
    x0, y0, x1, y1 = 0, 0, w, h
    seen = pts[np.isfinite(pts).all(axis=1)]
    if len(seen) >= 2:
        lo, hi = seen.min(axis=0), seen.max(axis=0)
        half = np.maximum((hi - lo) * 0.5 + (hi - lo).max() * 0.5, [w / 6, h / 6])
        mid = (lo + hi) / 2
        x0, y0 = (int(max(0, v)) for v in mid - half)
        x1, y1 = int(min(w, mid[0] + half[0])), int(min(h, mid[1] + half[1]))
    k = width / max(1, x1 - x0)
    size = (width, max(1, int(round((y1 - y0) * k))))
    crop = cv2.resize(np.ascontiguousarray(color[y0:y1, x0:x1]), size,
                      interpolation=cv2.INTER_AREA if k < 1 else cv2.INTER_CUBIC)
    shift = np.array([x0, y0], dtype=float)
    if evidence is not None:
        from dataclasses import replace

        objects = evidence.objects
        if objects is not None:
            st = evidence.stride
            objects = objects[y0 // st : -(-y1 // st), x0 // st : -(-x1 // st)]
        evidence = replace(evidence, predicted_px=(evidence.predicted_px - shift) * k,
                           objects=objects)
    return overlay_image(crop, (pts - shift) * k, "", evidence=evidence, show_legend=False)


def _thumb_gallery(title: str, items: list[tuple[str, str]], overlays: dict) -> str:
    """A gallery whose pictures are the overlays' thumbnails, each linking to its whole
    overlay (the thumbnail's own file when it has none)."""
    from html import escape

    head = f"<h2>{escape(title)} ({len(items)})</h2>"
    if not items:
        return head + "<p>None.</p>"
    figures = []
    for src, caption in items:
        thumb = thumb_name(src) if thumb_name(src) in overlays else src
        figures.append(
            f'<figure style="width:{THUMB_WIDTH}px"><a href="{escape(src)}"><img '
            f'src="{escape(thumb)}" alt="overlay"></a><figcaption>{escape(caption)}'
            "</figcaption></figure>"
        )
    return head + "".join(figures)


def track_report(
    timeline: Timeline,
    outcomes: Sequence[Any],
    data: dict[str, Any],
    *,
    title: str,
    labelled: bool,
    read_color: Callable[[str], NDArray[np.uint8]] | None = None,
    classify: Callable[[Any], Any] | None = None,
) -> dict[str, Any]:
    """All files of a timeline report: name -> JSON-ready dict, CSV/Markdown/HTML text or
    BGR image.

    Parameters
    ----------
    timeline : Timeline
    outcomes : sequence of PairOutcome
        The frames' own answers, in frame order (with their coordinates).
    data : dict
        The JSON object of the timeline (``timeline.json``; with ``"outcomes"`` when
        labelled, :func:`timeline_outcome_fields`, and ``"command"``).
    title : str, keyword-only
    labelled : bool, keyword-only
        The frames' labels are true states.
    read_color : callable, keyword-only, optional
        ``read_color(path)`` -> RGB image, for the overlays (None: no overlays).
    classify : callable, keyword-only, optional
        ``classify(frame) -> FrameResult``: each frame drawn is read whole and classified
        again, so that its overlay shows where the missing stickers lie (hidden or
        unknown, and why) and the objects over the napkin.
    """
    files: dict[str, Any] = {
        "timeline.csv": csv_table(TIMELINE_COLUMNS, timeline_rows(timeline)),
        **chart_files("timeline", timeline_figure(
            CLASS_IDS,
            [f.smoothed_class for f in timeline.frames],
            [f.raw_class for f in timeline.frames],
            truth=[f.label or "" for f in timeline.frames] if labelled else None,
            names=CLASS_NAMES,
            title=title,
        )),
    }
    data = dict(data)
    heat = _distances(outcomes, timeline)
    if heat is not None:
        files.update(chart_files("distances", heat[0]))
        shown = len(heatmap_sample(["frames"] * len(outcomes)))
        data["distances_png"] = {"frames_shown": shown, "frames": len(outcomes)}
    files["timeline.json"] = data
    wrong, told = _not_right(outcomes, labelled)
    index = {id(o): k for k, o in enumerate(outcomes)}
    drawn = [group[k] for group in (wrong, told)
             for k in heatmap_sample(["frames"] * len(group), GALLERY_MAX)]
    thumbs: dict[str, NDArray[np.uint8]] = {}

    def thumb(o: Any, color: NDArray[np.uint8], evidence: Any) -> None:
        thumbs[thumb_name(overlay_name(o))] = overlay_thumbnail(color, o.centroids, evidence)

    overlays = pair_overlays(
        drawn, read_color, classify=classify, on_drawn=thumb
    ) if read_color else {}
    overlays.update(thumbs)
    files.update(overlays)
    galleries = {
        "Wrong": [(index[id(o)], o) for o in wrong],
        "Cannot tell": [(index[id(o)], o) for o in told],
    }
    if not labelled:
        del galleries["Wrong"]
    lines = _summary_lines(data, timeline, labelled)
    counts = {k: data[k] for k in ("outcomes", "coverage", "accuracy_answered")} if (
        labelled and "outcomes" in data) else None
    note = heat[1] if heat else None
    files["report.md"] = _markdown(title, lines, galleries, overlays, note)
    files["report.html"] = _html(title, lines, counts, galleries, overlays, note)
    return files

