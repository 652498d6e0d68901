"""``dgli compare`` and ``dgli sequence``: how well the representations separate the
states of the database and of the three folding sequences."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import click

from .errors import handle_errors
from .options import jobs_option, json_option, overwrite_option, references_option, report_option
from .output import command_line, echo, echo_json, progress_bar

if TYPE_CHECKING:
    from ..analysis.compare import CompareTable, SequenceAnalysis


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

    from ..analysis.compare import compare_count, compare_database
    from ..analysis.compare_report import COMPARE_REPORT_FILES, compare_report
    from ..core.io import guard_outputs, write_outputs
    from ..sim.database_files import read_database

    if report_dir:  # fail before the work, not after it
        guard_outputs([Path(report_dir) / f for f in COMPARE_REPORT_FILES], overwrite=overwrite)
    records, _ = read_database(db)
    with progress_bar(compare_count(records), "distances", quiet=as_json) as bar:
        table, matrices, classes = compare_database(
            records, jobs=jobs or os.cpu_count() or 1, on_progress=bar.update
        )
    _print_compare_table(table, as_json)
    if report_dir:
        out, command = Path(report_dir), command_line()
        files = compare_report(table, matrices, classes, command=command)
        write_outputs({out / k: v for k, v in files.items()}, overwrite=overwrite,
                      command=command)
        click.echo(f"report written to {out / 'report.html'}", err=True)


def _print_compare_table(table: CompareTable, as_json: bool) -> None:
    """The Davies-Bouldin table on stdout: JSON, or Markdown and the column notes."""
    from ..analysis.compare import COMPARE_COLUMN_NOTES
    from ..analysis.compare_report import NO_SEPARATION_NOTE, PAPER_NOTE, readable_table
    from ..analysis.report import markdown_table

    if as_json:
        echo_json(table.to_json())
        return
    columns, rows = readable_table(table)
    echo("Davies-Bouldin index (lower is better)")
    echo(markdown_table(columns, rows), nl=False)
    echo("columns: " + "; ".join(f"{k}: {v}" for k, v in COMPARE_COLUMN_NOTES.items()))
    echo(NO_SEPARATION_NOTE)
    echo(PAPER_NOTE)


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
    summary = result.to_json(name)
    if as_json:
        echo_json(summary)
    else:
        _print_sequence(summary, result)
    if report_dir:
        from ..analysis.compare import sequence_outcomes
        from ..analysis.track import track_outcomes
        from ..analysis.track_report import timeline_json
        from .track import write_timeline_report

        outcomes = sequence_outcomes(name, records, result, refs)
        timeline = track_outcomes(outcomes, refs, labelled=True)
        data = timeline_json({"sequence": summary}, timeline, outcomes, True)
        write_timeline_report(
            report_dir, timeline, outcomes, data, title=f"sequence {name}", labelled=True,
            overwrite=overwrite,
        )


def _print_sequence(summary: dict[str, Any], result: SequenceAnalysis) -> None:
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
