"""The evaluation report: what ``dgli evaluate --report DIR`` writes, built in memory.

:func:`build_report` returns file names with their content (text or image arrays); the
CLI hands them to :mod:`dgli_vision.core.io` to write. Nothing here touches the disk.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..core.classes import CLASS_NAMES
from ..core.distance import average_ranks
from ..core.errors import InvalidValueError
from ..core.io import csv_table
from .charts import chart_files, confusion_figure, heatmap_figure, risk_coverage_figure
from .evaluate import SPLIT_COLUMNS, EvaluationResult, coordinate_matrix, counts_text
from .html_report import evaluation_html, risk_coverage
from .overlay import overlay_image
from .report import markdown_table

__all__ = [
    "HEATMAP_MAX",
    "REPORT_FILES",
    "build_report",
    "heatmap_sample",
    "overlay_name",
    "pair_overlays",
    "sample_distance_matrix",
]

#: The files of every report (besides ``results.jsonl`` and the overlays of
#: misclassified pairs, named after them).
REPORT_FILES = (
    "report.md",
    "report.html",
    "summary.json",
    "confusion.csv",
    "per_class.csv",
    "confusion.png",
    "confusion.svg",
    "distances.png",
    "distances.svg",
    "risk_coverage.png",
    "risk_coverage.svg",
)

#: Most samples a distance heatmap shows. All pairs of n samples cost n^2 in time and
#: memory (20,000 pairs: 3 GB and minutes), and a 600-pixel picture cannot show more
#: than a few hundred rows anyway: beyond this, a sample per class is drawn.
HEATMAP_MAX = 300


def heatmap_sample(groups: Sequence[str], limit: int = HEATMAP_MAX) -> list[int]:
    """Indices of at most ``limit`` items, the same number from every group where the
    groups allow (a group smaller than its share gives all it has, the rest is shared by
    the others), evenly spread within each group, in input order.

    Parameters
    ----------
    groups : sequence of str
        Each item's group (e.g. its true class); items of a group need not be consecutive.
    limit : int
        At least 1.

    Returns
    -------
    list of int
        All indices when there are at most ``limit`` items.
    """
    if limit < 1:
        raise InvalidValueError(f"limit must be at least 1, got {limit}")
    n = len(groups)
    if n <= limit:
        return list(range(n))
    members: dict[str, list[int]] = {}
    for k, g in enumerate(groups):
        members.setdefault(g, []).append(k)
    sizes = sorted(len(m) for m in members.values())
    per_group, left, others = 0, limit, len(sizes)
    for size in sizes:  # water-filling: the largest share every remaining group can take
        share = left // others
        if size > share:
            per_group = share
            break
        left -= size
        others -= 1
    else:
        per_group = sizes[-1]
    chosen = []
    for m in members.values():
        take = min(len(m), max(per_group, 1))
        picks = np.unique(np.linspace(0, len(m) - 1, take).round().astype(int))
        chosen += [m[p] for p in picks]
    return sorted(chosen)


def _unit_ranks(x: NDArray[np.float64]) -> NDArray[np.float64]:
    """Average ranks of each row, centred and scaled to unit norm (a row of equal values
    becomes zeros: it correlates with nothing)."""
    r = average_ranks(x)
    r -= r.mean(axis=1, keepdims=True)
    norm = np.linalg.norm(r, axis=1, keepdims=True)
    return np.divide(r, norm, out=np.zeros_like(r), where=norm > 0)


def sample_distance_matrix(coords: NDArray[np.float64], *, min_common: int = 3) -> NDArray:
    """Spearman distances (n, n) between samples, ignoring missing coordinates pairwise
    (:func:`~dgli_vision.core.distance.spearman_distance` with ``omit_nan``), NaN where two
    samples share fewer than ``min_common`` coordinates.

    Samples are grouped by which coordinates they have: for each two groups, every
    sample is ranked once over the coordinates both groups have, and the block of
    distances is one matrix product (samples usually fall into a few groups).
    """
    x = np.asarray(coords, dtype=np.float64)
    n = len(x)
    out = np.full((n, n), np.nan)
    if n == 0:
        return out
    present = ~np.isnan(x)
    patterns, inverse = np.unique(present, axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    members = [np.flatnonzero(inverse == p) for p in range(len(patterns))]
    for p, rows_p in enumerate(members):
        for q in range(p, len(patterns)):
            common = patterns[p] & patterns[q]
            if common.sum() < min_common:
                continue
            rows_q = members[q]
            rp = _unit_ranks(x[np.ix_(rows_p, common)])
            rq = rp if q == p else _unit_ranks(x[np.ix_(rows_q, common)])
            block = np.clip(1.0 - rp @ rq.T, 0.0, 2.0)
            out[np.ix_(rows_p, rows_q)] = block
            out[np.ix_(rows_q, rows_p)] = block.T
    diagonal = np.where(present.sum(axis=1) >= min_common, 0.0, np.nan)
    out[np.arange(n), np.arange(n)] = diagonal
    return out


def _stem(color_path: str) -> str:
    return Path(color_path).name.replace("_color.png", "").replace(".png", "")


def _name(c: str | None) -> str:
    return f"{c} {CLASS_NAMES.get(c, '')}".strip() if c else "none"


@dataclass(frozen=True)
class _Tables:
    """The confusion and per-class tables, as the CSV files and the Markdown show them."""

    cols: list[str]
    confusion_rows: list[list]
    per_class_header: list[str]
    per_class_rows: list[list]


@dataclass(frozen=True)
class _Heatmap:
    """The distance heatmap of the evaluated samples (None for fewer than two) and the
    words that say which samples it shows."""

    files: dict[str, Any] | None
    note: str


def _tables(result: EvaluationResult) -> _Tables:
    labels = result.labels
    pc_rows = [
        [c, CLASS_NAMES.get(c, ""), v["precision"], v["recall"], v["f1"], v["support"]]
        for c, v in result.per_class.items()
    ]
    return _Tables(
        cols=[*labels, *SPLIT_COLUMNS],
        confusion_rows=[[lab, *row] for lab, row in zip(labels, result.confusion_split())],
        per_class_header=["class", "name", "precision", "recall", "f1", "support"],
        per_class_rows=pc_rows,
    )


def _distance_heatmap(result: EvaluationResult) -> _Heatmap:
    """Spearman distances between the samples, ordered by true class (a sample per class
    when there are more than :data:`HEATMAP_MAX`)."""
    outs = result.outcomes
    order = sorted(range(len(outs)), key=lambda k: (outs[k].pair.label, outs[k].pair.color))
    shown = [order[k] for k in heatmap_sample([outs[k].pair.label for k in order])]
    note = (
        f"all {len(outs):,} samples"
        if len(shown) == len(outs)
        else f"{len(shown):,} of {len(outs):,} samples, the same number from each true class "
        "(all of a smaller class), evenly spread in each"
    )
    if len(shown) < 2:
        return _Heatmap(None, note)
    fig = heatmap_figure(
        sample_distance_matrix(coordinate_matrix([outs[k] for k in shown])),
        title="Spearman distance of dGLI, samples by true class"
        + ("" if len(shown) == len(outs) else f" ({len(shown)} of {len(outs)})"),
        groups=[outs[k].pair.label for k in shown],
        value_label="1 - rho",
        group_label="true class",
        missing="no distance: the two share fewer than 3 measured coordinates (stickers "
        "hidden in both)",
    )
    return _Heatmap(chart_files("distances", fig), note)


def _misclassified(result: EvaluationResult) -> list[Any]:
    """The outcomes given a class that is not their label."""
    return [o for o in result.outcomes if o.predicted is not None and not o.correct]


def overlay_name(outcome: Any) -> str:
    """The report file name of a pair's overlay: ``overlays/<stem>_overlay.png``."""
    return f"overlays/{_stem(outcome.pair.color)}_overlay.png"


def pair_overlays(
    outcomes: list[Any], read_color: Any, *, classify: Any = None, on_drawn: Any = None
) -> dict[str, NDArray[np.uint8]]:
    """The overlay image of every pair given (a wrong class: the verdict and the
    runner-up; "cannot tell": the reason), by report file name (:func:`overlay_name`).

    With ``classify`` (``classify(frame) -> FrameResult``, the run's own classifier), each
    pair is read whole and classified again, so that its overlay also shows where each
    missing sticker would be, hidden by cloth or unknown with its reason, and the
    objects over the napkin. A pair that cannot be read again that way (a frame of a
    bag) is drawn from its colour image and its stickers found; one whose colour image
    cannot be read either (a file gone since) gets none. ``on_drawn(outcome, colour,
    evidence)`` is called for each pair drawn (a report's thumbnails).
    """

    files = {}
    for o in outcomes:
        color, evidence = _colour_and_evidence(o.pair, read_color, classify)
        if color is None:
            continue
        if on_drawn is not None:
            on_drawn(o, color, evidence)
        if o.predicted is None:
            files[overlay_name(o)] = overlay_image(
                color, np.array(o.centroids), o.reason or "no class",
                detail=f"true {_name(o.pair.label)}" if o.pair.label else "",
                evidence=evidence,
            )
            continue
        verdict = f"predicted {_name(o.predicted)} ({o.distance:.3f}); true {_name(o.pair.label)}"
        files[overlay_name(o)] = overlay_image(
            color,
            np.array(o.centroids),
            verdict,
            detail=f"runner-up {_name(o.runner_up)} ({o.runner_up_distance or float('nan'):.3f})",
            evidence=evidence,
        )
    return files


def _ranked_answers(outcomes: list[Any]) -> tuple[list[tuple[float, float, bool]], int]:
    """Every answer given as (confidence, margin to the runner-up, right), and the
    pairs read: the risk-coverage curve one answer at a time."""
    read = [o for o in outcomes if o.error is None]
    ranked = [
        (float(o.confidence),
         float((o.runner_up_distance or 0.0) - (o.distance or 0.0)), bool(o.correct))
        for o in read if o.predicted is not None and o.confidence is not None
    ]
    return ranked, len(read)


def _colour_and_evidence(pair: Any, read_color: Any, classify: Any) -> tuple[Any, Any]:
    """A pair's colour image and, with ``classify``, its overlay evidence (None where
    it cannot be had)."""
    from ..core.errors import DgliError
    from .overlay import overlay_evidence

    if classify is not None and hasattr(pair, "load"):
        try:
            frame = pair.load()
            return frame.color, overlay_evidence(classify(frame))
        except (DgliError, OSError):
            pass
    try:
        return read_color(pair.color), None
    except (DgliError, OSError):
        return None, None


def _markdown_summary(result: EvaluationResult, meta: dict[str, Any], tables: _Tables) -> list:
    """The report's header lines, the confusion and the per-class tables."""
    return [
        "# dgli evaluate report",
        "",
        f"- pairs: **{result.n}**: {counts_text(result.outcome_counts)}",
        f"- answers: {result.outcomes_text()}",
        f"- class accuracy: **{result.accuracy:.2%}**; "
        f"variant accuracy: **{result.variant_accuracy_text()}**",
        f"- time: {result.seconds:.1f} s with {meta.get('jobs', 1)} worker(s)",
        f"- command: `{meta.get('command', '')}`",
        f"- references: `{meta.get('references', '')}` "
        f"(sha256 `{meta.get('references_sha256', '')}`)",
        f"- dgli_vision {meta.get('package_version', '')}",
        "",
        "## Confusion (rows: true class, columns: predicted)",
        "",
        markdown_table(
            ["true \\ predicted", *tables.cols],
            [[_name(lab), *row] for lab, row in zip(result.labels, result.confusion_split())],
        ),
        "![confusion matrix](confusion.png)",
        "",
        "## Per class",
        "",
        markdown_table(tables.per_class_header, tables.per_class_rows),
    ]


def _markdown_misclassified(wrong: list[Any]) -> list[str]:
    """The section listing the misclassified pairs with their overlays."""
    md = ["## Misclassified pairs", ""]
    if not wrong:
        return [*md, "None.\n"]
    header = [
        "colour image",
        "true",
        "predicted",
        "distance",
        "runner-up",
        "runner-up distance",
        "overlay",
    ]
    rows = [
        [
            o.pair.color,
            f"{_name(o.pair.label)} {o.pair.variant or ''}".strip(),
            f"{_name(o.predicted)} {o.predicted_variant or ''}".strip(),
            round(o.distance or 0, 4),
            _name(o.runner_up),
            round(o.runner_up_distance or 0, 4),
            f"[overlay](overlays/{_stem(o.pair.color)}_overlay.png)",
        ]
        for o in wrong
    ]
    return [*md, markdown_table(header, rows)]


def _markdown_failures(result: EvaluationResult) -> list[str]:
    """The sections listing the pairs answered "cannot tell" (an answer, with its
    reason) and the pairs that could not be read."""
    told = [o for o in result.outcomes if o.error is None and o.predicted is None]
    unread = [o for o in result.outcomes if o.error is not None]
    md = ["## Cannot tell", ""]
    if told:
        rows = [
            [
                o.pair.color, _name(o.pair.label), o.reason or "",
                f"[overlay](overlays/{_stem(o.pair.color)}_overlay.png)",
            ]
            for o in told
        ]
        md += [markdown_table(["colour image", "true", "why", "overlay"], rows)]
    else:
        md += ["None.\n"]
    md += ["## Not read", ""]
    if not unread:
        return [*md, "None.\n"]
    rows = [[o.pair.color, o.pair.depth, o.error or ""] for o in unread]
    return [*md, markdown_table(["colour image", "depth image", "error"], rows)]


def _markdown_skipped(meta: dict[str, Any]) -> list[str]:
    """The label rows ``--lenient`` skipped (no section when there are none)."""
    if not meta.get("skipped"):
        return []
    return [
        "## Label rows skipped (--lenient)",
        "",
        *[f"- {message}" for message in meta["skipped"]],
        "",
    ]


def _markdown_distances(heatmap: _Heatmap) -> list[str]:
    """The section showing the distance heatmap (none without it)."""
    if heatmap.files is None:
        return []
    return [
        "## Distances between evaluated samples",
        "",
        f"Spearman distance of the dGLI coordinates alone between {heatmap.note}, "
        "ordered by true class (not the classifier's distance, which also weighs the "
        "stickers seen, their height and the napkin's footprint).",
        "",
        "![distance matrix](distances.png)",
        "",
    ]


def build_report(
    result: EvaluationResult, meta: dict[str, Any], read_color: Any, *, classify: Any = None
) -> dict[str, str | dict | NDArray[np.uint8]]:
    """All report files: name -> Markdown/CSV text, JSON-ready dict, or BGR image.

    Parameters
    ----------
    result : EvaluationResult
    meta : dict
        ``command``, ``references``, ``references_sha256``, ``package_version``, ``jobs``.
    read_color : callable
        ``read_color(path) -> RGB array``, used for the overlays of misclassified pairs.
    classify : callable, keyword-only, optional
        ``classify(frame) -> FrameResult``: the overlays then show each missing sticker
        and the objects over the napkin too (:func:`pair_overlays`).

    Returns
    -------
    dict
        Report file name (relative to the report folder) -> its content.
    """
    tables = _tables(result)
    files: dict[str, Any] = {"summary.json": {**result.to_json(), **meta}}
    files["confusion.csv"] = csv_table(["true \\ predicted", *tables.cols], tables.confusion_rows)
    files["per_class.csv"] = csv_table(tables.per_class_header, tables.per_class_rows)
    files.update(chart_files("confusion", confusion_figure(
        np.array(result.confusion), result.labels, names=CLASS_NAMES, title="confusion"
    )))
    curve = risk_coverage(result.outcomes)
    if curve:
        files.update(chart_files("risk_coverage", risk_coverage_figure(
            curve, *_ranked_answers(result.outcomes))))
    heatmap = _distance_heatmap(result)
    if heatmap.files is not None:
        files.update(heatmap.files)
    wrong = _misclassified(result)
    told = [o for o in result.outcomes if o.error is None and o.predicted is None]
    files.update(pair_overlays(wrong + told, read_color, classify=classify))
    md = [
        *_markdown_summary(result, meta, tables),
        *(["## Risk and coverage", "", "Each point: the answers at or above one confidence "
           "threshold (across: the share of the pairs read answered; up: the share of "
           "those answers right).", "", "![risk-coverage curve](risk_coverage.png)", ""]
          if curve else []),
        *_markdown_misclassified(wrong),
        *_markdown_failures(result),
        *_markdown_skipped(meta),
        *_markdown_distances(heatmap),
    ]
    files["report.md"] = "\n".join(md)
    note = None
    if heatmap.files is not None:
        note = (
            f"Spearman distance (1 - rho) of the dGLI coordinates alone between "
            f"{heatmap.note}, ordered by true class; not the classifier's distance, which "
            "also weighs the stickers seen, their height and the napkin's footprint."
        )
    files["report.html"] = evaluation_html(result, meta, overlay_name, _name, note,
                                           risk_chart=bool(curve))
    return files
