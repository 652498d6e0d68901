"""``dgli compare`` and ``dgli sequence``: how well the representations separate the
states of the database and of the three folding sequences."""

from __future__ import annotations

from typing import Any

import click

from .errors import handle_errors
from .options import jobs_option, json_option, overwrite_option, references_option, report_option
from .output import command_line, echo, echo_json, progress_bar


@click.command()
@click.argument("db", type=click.Path())
@report_option("Write the table (Markdown, CSV, JSON), report.html and the heatmaps here.")
@json_option("Print the table as JSON.")
@jobs_option
@overwrite_option
@handle_errors
def compare(
    db: str, report_dir: str | None, as_json: bool, jobs: int | None, overwrite: bool
) -> None:
    """Davies-Bouldin index of dGLI and the baselines on DB and the three sequences.

    Columns: the database labelled by class, the three folding sequences labelled by
    their frames' true class, the database labelled by class and variant, and by class
    and variant with mirror images merged (the grouping comparable to the paper's
    corner-specific classes; see the report). The paper's values, where known, stand in
    the last columns.
    """
    import os
    from pathlib import Path

    from ..analysis.compare import (
        COMPARE_COLUMN_NOTES,
        REPRESENTATIONS,
        compare_datasets,
        dataset_matrices,
        davies_bouldin_table,
        folded_by_class,
        matrix_count,
        paper_columns,
    )
    from ..core.io import guard_outputs
    from ..sim.database_files import read_database

    if report_dir:  # fail before the work, not after it
        guard_outputs(
            [Path(report_dir) / f for f in ("table.json", "table.md", "report.html")],
            overwrite=overwrite,
        )
    records, _ = read_database(db)
    records = folded_by_class(records)  # the paper's states: every fold laid flat
    datasets = compare_datasets(records)
    names = tuple(REPRESENTATIONS)
    with progress_bar(matrix_count(datasets, names), "distances", quiet=as_json) as bar:
        matrices = dataset_matrices(
            datasets, names, jobs=jobs or os.cpu_count() or 1, on_progress=bar.update
        )
    table = davies_bouldin_table(datasets, names, matrices=matrices)
    table["column_notes"] = COMPARE_COLUMN_NOTES
    paper = paper_columns(names)
    table["paper"] = paper
    columns, rows = paper_beside_ours(
        ["representation", *table["columns"], *paper["columns"]],
        [
            [name, *map(_index_text, vals), *map(_paper_text, paper["rows"][name])]
            for name, vals in table["rows"].items()
        ],
    )
    # JSON: null where two groups are not separated (no finite index to give)
    table["rows"] = {
        name: [v if v < _NO_SEPARATION else None for v in vals]
        for name, vals in table["rows"].items()
    }
    _print_compare_table(table, columns, rows, as_json)
    if report_dir:
        _write_compare_report(
            Path(report_dir), table, columns, rows, records, matrices["database"], overwrite
        )


#: Above this a Davies-Bouldin index says two groups' centres coincide (the ratio's
#: denominator is rounding noise): shown as such, not as a number.
_NO_SEPARATION = 1e6


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
    if not value < _NO_SEPARATION:  # inf and NaN too
        return "no separation"
    return f"{value:.3g}"


def _paper_text(value: float | None) -> str:
    """A value of the paper in the same format ("-" where it is not known)."""
    return "-" if value is None else _index_text(value)


def _print_compare_table(table: dict[str, Any], columns: list, rows: list, as_json: bool) -> None:
    """The Davies-Bouldin table on stdout: JSON, or Markdown and the column notes."""
    from ..analysis.compare import COMPARE_COLUMN_NOTES
    from ..analysis.report import markdown_table

    if as_json:
        echo_json(table)
    else:
        echo("Davies-Bouldin index (lower is better)")
        echo(markdown_table(columns, rows), nl=False)
        echo("columns: " + "; ".join(f"{k}: {v}" for k, v in COMPARE_COLUMN_NOTES.items()))
        echo(_NO_SEPARATION_NOTE)
        echo(_PAPER_NOTE)


_PAPER_NOTE = (
    "paper: the paper's Table 1 values kept in docs/table1.md and docs/tracking.md (its "
    "database column groups corner-specific classes: compare with 'by variant, mirrors "
    "merged'); '-' where it gives none or none is recorded."
)

_NO_SEPARATION_NOTE = (
    "no separation: two groups whose centres coincide under that representation (the "
    "index divides by their distance: 0). The corners cannot tell a corner folded over "
    "from the same corner folded under, nor the states of a sequence that move no corner."
)

#: What each heatmap's distance is.
_DISTANCE_CAPTIONS = {
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


def _write_compare_report(
    out: Any,
    table: dict[str, Any],
    columns: list,
    rows: list,
    records: Any,
    matrices: dict[str, Any],
    overwrite: bool,
) -> None:
    """The table (JSON, Markdown with the column notes, CSV), report.html and a heatmap
    of the database's distances under each representation into the folder ``out``."""
    from ..analysis.charts import chart_files, heatmap_figure
    from ..analysis.compare import COMPARE_COLUMN_NOTES
    from ..analysis.html_report import html_chart, html_list, html_page, html_table
    from ..analysis.report import markdown_table
    from ..core.io import csv_table, write_outputs

    notes = "\n".join(f"- **{k}**: {v}" for k, v in COMPARE_COLUMN_NOTES.items())
    pictures = "\n".join(
        f"### {name}\n\n{_DISTANCE_CAPTIONS.get(name, '')}\n\n"
        f"![{name} distances](distances_{name}.png)\n"
        for name in table["rows"]
    )
    command = command_line()
    page = html_page(
        "Davies-Bouldin index (lower is better)",
        [
            html_table(columns, rows),
            f"<p>{_NO_SEPARATION_NOTE}</p><p>{_PAPER_NOTE}</p>",
            "<h2>What each column groups</h2>",
            html_list([f"{k}: {v}" for k, v in COMPARE_COLUMN_NOTES.items()]),
            "<h2>Distances between the database's states, by class</h2>",
            *[
                f"<h3>{name}</h3>" + html_chart(f"distances_{name}", f"{name} distances",
                                                _DISTANCE_CAPTIONS.get(name, ""))
                for name in table["rows"]
            ],
            f"<p class=\"note\">command: <code>{_escape(command)}</code></p>",
        ],
    )
    files: dict[Any, Any] = {
        out / "table.json": table,
        out / "table.md": "# Davies-Bouldin index (lower is better)\n\n"
        + markdown_table(columns, rows)
        + "\n"
        + _NO_SEPARATION_NOTE
        + "\n\n"
        + _PAPER_NOTE
        + "\n\n## What each column groups\n\n"
        + notes
        + "\n\n## Distances between the database's states, by class\n\n"
        + pictures,
        out / "table.csv": csv_table(columns, rows),
        out / "report.html": page,
    }
    for name, mat in matrices.items():
        fig = heatmap_figure(
            mat,
            title=f"{name}: distances, states by class",
            groups=records.classes,
            value_label="distance",
        )
        files.update({out / f: c for f, c in chart_files(f"distances_{name}", fig).items()})
    write_outputs(files, overwrite=overwrite, command=command)
    click.echo(f"report written to {out / 'report.html'}", err=True)


def _escape(text: str) -> str:
    from html import escape

    return escape(text)


@click.command()
@click.argument("name", type=click.Choice(["I", "II", "III"]))
@references_option
@report_option("Write the heatmap and frames here.")
@json_option("Print a JSON object.")
@overwrite_option
@handle_errors
def sequence(
    name: str,
    references_path: str | None,
    report_dir: str | None,
    as_json: bool,
    overwrite: bool,
) -> None:
    """Folding sequence NAME: frame distance matrix and detected state changes.

    The simulator's frames of the sequence, each compared with the references as a
    camera above would see it, then smoothed over time as `dgli track` does.
    """
    from pathlib import Path

    from ..analysis.compare import analyse_sequence, sequence_records
    from ..analysis.track_report import TRACK_REPORT_FILES
    from ..classifier.references import load_references
    from ..core.io import guard_outputs

    if report_dir:  # fail before the work, not after it
        guard_outputs([Path(report_dir) / f for f in TRACK_REPORT_FILES], overwrite=overwrite)
    refs = load_references(references_path)
    records = sequence_records(name)
    result = analyse_sequence(records, refs)
    summary = _sequence_summary(name, len(records), result)
    if as_json:
        echo_json(summary)
    else:
        _print_sequence(summary, result)
    if report_dir:
        _write_sequence_report(report_dir, name, records, result, refs, summary, overwrite)


def _write_sequence_report(
    report_dir: str, name: str, records: Any, result: Any, refs: Any, summary: dict,
    overwrite: bool,
) -> None:
    """The report ``dgli track --report`` writes, of the sequence's frames."""
    from ..analysis.compare import sequence_outcomes
    from ..analysis.track import track_outcomes
    from ..analysis.track_report import timeline_outcome_fields
    from .track import write_timeline_report

    outcomes = sequence_outcomes(name, records, result, refs)
    timeline = track_outcomes(outcomes, refs, labelled=True)
    data = {
        "sequence": summary,
        "n_frames": len(outcomes),
        **timeline.to_json(),
        **timeline_outcome_fields(outcomes, True),
    }
    write_timeline_report(
        report_dir, timeline, outcomes, data, title=f"sequence {name}", labelled=True,
        overwrite=overwrite,
    )


def _sequence_summary(name: str, n_frames: int, result: Any) -> dict[str, Any]:
    """The JSON object of ``dgli sequence`` for its :class:`SequenceAnalysis`."""
    from ..sim.cloth.sequences import SEQUENCES

    return {
        "sequence": name,
        "description": SEQUENCES[name][0],
        "frames": n_frames,
        "truth": list(result.truth),
        "predicted": list(result.predicted),
        "smoothed": list(result.smoothed),
        "true_changes": list(result.true_changes),
        "detected_changes": list(result.detected_changes),
        "frame_accuracy": round(result.frame_accuracy, 4),
        "smoothed_accuracy": round(result.smoothed_accuracy, 4),
    }


def _print_sequence(summary: dict[str, Any], result: Any) -> None:
    """``dgli sequence`` in words: the frames' classes and the state changes."""
    echo(
        f"sequence {summary['sequence']}: {summary['description']} ({summary['frames']} frames)"
    )
    echo(f"  truth:     {' '.join(result.truth)}")
    echo(f"  per frame: {' '.join(result.predicted)}")
    echo(f"  smoothed:  {' '.join(result.smoothed)}")
    echo(
        f"  state changes: true at frames {list(result.true_changes)}, "
        f"detected at {list(result.detected_changes)}; frame accuracy "
        f"{result.frame_accuracy:.0%} per frame, {result.smoothed_accuracy:.0%} smoothed"
    )
