"""The evaluation report: what ``dgli evaluate --report DIR`` writes, built in memory.

:func:`build_report` returns file names with their content (text or image arrays); the
CLI hands them to :mod:`dgli_vision.io` to write. Nothing here touches the disk.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .classes import CLASS_NAMES
from .distance import average_ranks
from .evaluate import EvaluationResult, coordinate_matrix
from .report import confusion_image, csv_table, heatmap_image, markdown_table, overlay_image

__all__ = [
    "HEATMAP_MAX",
    "REPORT_FILES",
    "build_report",
    "heatmap_sample",
    "sample_distance_matrix",
]

#: The files of every report (besides ``results.jsonl`` and the overlays of
#: misclassified pairs, named after them).
REPORT_FILES = (
    "report.md",
    "summary.json",
    "confusion.csv",
    "per_class.csv",
    "confusion.png",
    "distances.png",
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
        raise ValueError(f"limit must be at least 1, got {limit}")
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
    (:func:`~dgli_vision.distance.spearman_distance` with ``omit_nan``), NaN where two
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


def build_report(
    result: EvaluationResult, meta: dict[str, Any], read_color: Any
) -> dict[str, str | dict | NDArray[np.uint8]]:
    """All report files: name -> Markdown/CSV text, JSON-ready dict, or BGR image.

    Parameters
    ----------
    result : EvaluationResult
    meta : dict
        ``command``, ``references``, ``references_sha256``, ``package_version``, ``jobs``.
    read_color : callable
        ``read_color(path) -> RGB array``, used for the overlays of misclassified pairs.
    """
    files: dict[str, Any] = {}
    labels = result.labels
    cols = [*labels, "none"]
    summary = {**result.to_dict(), **meta}
    files["summary.json"] = summary
    conf_rows = [[lab, *row] for lab, row in zip(labels, result.confusion)]
    files["confusion.csv"] = csv_table(["true \\ predicted", *cols], conf_rows)
    pc_rows = [
        [c, CLASS_NAMES.get(c, ""), v["precision"], v["recall"], v["f1"], v["support"]]
        for c, v in result.per_class.items()
    ]
    pc_header = ["class", "name", "precision", "recall", "f1", "support"]
    files["per_class.csv"] = csv_table(pc_header, pc_rows)
    files["confusion.png"] = confusion_image(
        np.array(result.confusion), labels, names=CLASS_NAMES, title="confusion"
    )
    outs = result.outcomes
    order = sorted(range(len(outs)), key=lambda k: (outs[k].pair.label, outs[k].pair.color))
    shown = [order[k] for k in heatmap_sample([outs[k].pair.label for k in order])]
    heatmap_note = (
        f"all {len(outs):,} samples"
        if len(shown) == len(outs)
        else f"{len(shown):,} of {len(outs):,} samples, the same number from each true class "
        "(all of a smaller class), evenly spread in each"
    )
    if len(shown) >= 2:
        files["distances.png"] = heatmap_image(
            sample_distance_matrix(coordinate_matrix([outs[k] for k in shown])),
            title="Spearman distance of dGLI, samples by true class"
            + ("" if len(shown) == len(outs) else f" ({len(shown)} of {len(outs)})"),
            groups=[outs[k].pair.label for k in shown],
            value_label="1 - rho",
        )
    wrong = [o for o in outs if o.predicted is not None and not o.correct]
    for o in wrong:
        stem = _stem(o.pair.color)
        verdict = f"predicted {_name(o.predicted)} ({o.distance:.3f}); true {_name(o.pair.label)}"
        files[f"overlays/{stem}_overlay.png"] = overlay_image(
            read_color(o.pair.color),
            np.array(o.centroids),
            verdict,
            detail=f"runner-up {_name(o.runner_up)} ({o.runner_up_distance or float('nan'):.3f})",
        )
    md = [
        "# dgli evaluate report",
        "",
        f"- pairs: **{result.n}**, classified: **{result.classified}**, "
        f"failures: **{len(result.failures)}**",
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
            ["true \\ predicted", *cols],
            [[_name(lab), *row] for lab, row in zip(labels, result.confusion)],
        ),
        "![confusion matrix](confusion.png)",
        "",
        "## Per class",
        "",
        markdown_table(pc_header, pc_rows),
        "## Misclassified pairs",
        "",
    ]
    if wrong:
        md.append(
            markdown_table(
                [
                    "colour image",
                    "true",
                    "predicted",
                    "distance",
                    "runner-up",
                    "runner-up distance",
                    "overlay",
                ],
                [
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
                ],
            )
        )
    else:
        md.append("None.\n")
    md += ["## Failures (not read, or no class given)", ""]
    if result.failures:
        md.append(
            markdown_table(
                ["colour image", "depth image", "error"],
                [[f["color"], f["depth"], f["error"]] for f in result.failures],
            )
        )
    else:
        md.append("None.\n")
    if meta.get("skipped"):
        md += ["## Label rows skipped (--lenient)", ""]
        md += [f"- {message}" for message in meta["skipped"]]
        md.append("")
    if "distances.png" in files:
        md += [
            "## Distances between evaluated samples",
            "",
            f"Spearman distance of the dGLI coordinates between {heatmap_note}, "
            "ordered by true class.",
            "",
            "![distance matrix](distances.png)",
            "",
        ]
    files["report.md"] = "\n".join(md)
    return files
