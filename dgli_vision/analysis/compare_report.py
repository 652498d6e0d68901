"""``dgli compare``'s report, built in memory: the Davies-Bouldin table as people read it
(the paper's values beside ours), in Markdown, CSV and HTML, with a heatmap of the
database's distances under each representation."""

from __future__ import annotations

from html import escape
from typing import Any

from numpy.typing import NDArray

from ..core.io import csv_table
from .charts import chart_files, heatmap_figure
from .compare import COMPARE_COLUMN_NOTES, NO_SEPARATION, CompareTable
from .html_report import html_chart, html_list, html_page, html_table
from .report import markdown_table

__all__ = [
    "COMPARE_REPORT_FILES",
    "NO_SEPARATION_NOTE",
    "PAPER_NOTE",
    "compare_report",
    "paper_beside_ours",
    "readable_table",
]

#: The files of ``dgli compare --report`` checked before the work (the heatmaps too).
COMPARE_REPORT_FILES = ("table.json", "table.md", "report.html")

PAPER_NOTE = (
    "paper: the paper's Table 1 values kept in docs/table1.md and docs/tracking.md (its "
    "database column groups corner-specific classes: compare with 'by variant, mirrors "
    "merged'); '-' where it gives none or none is recorded."
)

NO_SEPARATION_NOTE = (
    "no separation: two groups whose centres coincide under that representation (the "
    "index divides by their distance: 0). The corners cannot tell a corner folded over "
    "from the same corner folded under, nor the states of a sequence that move no corner."
)

#: What each heatmap's distance is.
DISTANCE_CAPTIONS = {
    "dgli": "Spearman distance between the states' 28 dGLI coordinates alone, not the "
    "classifier's distance: the classifier adds which stickers are visible, their height "
    "and the napkin's footprint (see dgli+visibility). With the dGLI alone a corner "
    "folded over and under look alike (01, 03 and 10 nearly so).",
    "dgli+visibility": "Spearman distance of the dGLI plus the mean disagreement of "
    "which stickers are visible from above.",
    "edges": "Spearman distance between the 28 minimal distances of segment pairs.",
    "corners": "Spearman distance between the 6 distances of the four corners.",
    "frechet": "Discrete Frechet distance between the boundary polylines, after "
    "centring and the best rotation, metres.",
    "hausdorff": "Hausdorff distance between the boundary polylines, after centring and "
    "the best rotation, metres.",
}

#: Each of the paper's columns and our column it compares with.
_COMPARABLE = {"paper: database": "by variant, mirrors merged", "paper: III": "III"}


def paper_beside_ours(columns: list[str], rows: list[list]) -> tuple[list[str], list[list]]:
    """The table as people read it: each column of the paper right after ours that
    compares with it, those pairs first, then our other columns (the JSON keeps its
    order)."""
    order = [0]
    for theirs, ours in _COMPARABLE.items():
        if theirs in columns and ours in columns:
            order += [columns.index(ours), columns.index(theirs)]
    order += [k for k in range(len(columns)) if k not in order]
    return [columns[k] for k in order], [[row[k] for k in order] for row in rows]


def _index_text(value: float) -> str:
    """A Davies-Bouldin index in one format: three significant digits, or "no
    separation" where two groups' centres coincide."""
    if not value < NO_SEPARATION:  # inf and NaN too
        return "no separation"
    return f"{value:.3g}"


def _paper_text(value: float | None) -> str:
    """A value of the paper in the same format ("-" where it is not known)."""
    return "-" if value is None else _index_text(value)


def readable_table(table: CompareTable) -> tuple[list[str], list[list[str]]]:
    """The header and rows of the table as people read it: ours, and the paper's
    values beside the comparable columns (:func:`paper_beside_ours`)."""
    paper: dict[str, Any] = table.paper  # type: ignore[assignment]
    return paper_beside_ours(
        ["representation", *table.columns, *paper["columns"]],
        [
            [name, *map(_index_text, vals), *map(_paper_text, paper["rows"][name])]
            for name, vals in table.rows.items()
        ],
    )


def compare_report(
    table: CompareTable,
    matrices: dict[str, NDArray],
    classes: list[str],
    *,
    command: str,
) -> dict[str, Any]:
    """The report of ``dgli compare --report``.

    Parameters
    ----------
    table : CompareTable
    matrices : dict of str to ndarray
        The database's distance matrix under each representation (a heatmap each).
    classes : list of str
        The class of each of the database's states (the heatmaps' groups).
    command : str, keyword-only
        The command line, shown on the page.

    Returns
    -------
    dict
        Report file name (relative to the report folder) -> its content: the table
        (``table.json``, ``table.md`` with the column notes, ``table.csv``),
        ``report.html`` and the heatmaps (``distances_NAME.svg`` and ``.png``).
    """
    columns, rows = readable_table(table)
    notes = "\n".join(f"- **{k}**: {v}" for k, v in COMPARE_COLUMN_NOTES.items())
    pictures = "\n".join(
        f"### {name}\n\n{DISTANCE_CAPTIONS.get(name, '')}\n\n"
        f"![{name} distances](distances_{name}.png)\n"
        for name in table.rows
    )
    page = html_page(
        "Davies-Bouldin index (lower is better)",
        [
            html_table(columns, rows),
            f"<p>{NO_SEPARATION_NOTE}</p><p>{PAPER_NOTE}</p>",
            "<h2>What each column groups</h2>",
            html_list([f"{k}: {v}" for k, v in COMPARE_COLUMN_NOTES.items()]),
            "<h2>Distances between the database's states, by class</h2>",
            *[
                f"<h3>{name}</h3>" + html_chart(f"distances_{name}", f"{name} distances",
                                                DISTANCE_CAPTIONS.get(name, ""))
                for name in table.rows
            ],
            f"<p class=\"note\">command: <code>{escape(command)}</code></p>",
        ],
    )
    files: dict[str, Any] = {
        "table.json": table.to_json(),
        "table.md": "# Davies-Bouldin index (lower is better)\n\n"
        + markdown_table(columns, rows)
        + "\n"
        + NO_SEPARATION_NOTE
        + "\n\n"
        + PAPER_NOTE
        + "\n\n## What each column groups\n\n"
        + notes
        + "\n\n## Distances between the database's states, by class\n\n"
        + pictures,
        "table.csv": csv_table(columns, rows),
        "report.html": page,
    }
    for name, mat in matrices.items():
        fig = heatmap_figure(
            mat, title=f"{name}: distances, states by class", groups=classes,
            value_label="distance",
        )
        files.update(chart_files(f"distances_{name}", fig))
    return files
