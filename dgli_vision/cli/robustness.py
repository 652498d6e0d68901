"""``dgli robustness``: the robustness and reliability tables."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from .errors import handle_errors
from .options import (
    jobs_option,
    json_option,
    overwrite_option,
    parse_conditions,
    per_class_option,
    references_option,
    report_option,
)
from .output import command_line, echo, echo_json, progress_bar

if TYPE_CHECKING:
    from ..analysis.robustness import ConditionScore
    from ..classifier.references import ReferenceSet


@click.command()
@per_class_option(4, 50, "Pairs per class")
@click.option("--seed", default=1000, show_default=True, type=int, help="Seed of the renders.")
@click.option(
    "--conditions",
    "conditions",
    callback=parse_conditions,
    default="",
    help="Conditions to score, comma-separated [default: clean and all].",
)
@jobs_option
@click.option(
    "--markdown",
    type=click.Path(),
    help="Also write the table as Markdown to this file.",
)
@report_option(
    "Write report.md and report.html here: the tables, and per condition a gallery of "
    "the pairs answered wrong or 'cannot tell' with their overlays and reasons."
)
@references_option
@json_option("Print the table as JSON.")
@overwrite_option
@handle_errors
def robustness(
    per_class: int,
    seed: int,
    conditions: tuple[str, ...],
    jobs: int | None,
    markdown: str | None,
    report_dir: str | None,
    references_path: str | None,
    as_json: bool,
    overwrite: bool,
) -> None:
    """Render fresh pairs under each capture condition and score the answers.

    Right, "cannot tell" (exit 1) and wrong, per condition: the robustness table. Then
    the reliability table: for bins of confidence, how many best guesses (those that
    became "cannot tell" included) were right, over all conditions.
    """
    import os

    from ..analysis.report import markdown_table
    from ..analysis.robustness import reliability_table, robustness_table
    from ..analysis.robustness_report import ROBUSTNESS_REPORT_FILES, robustness_json
    from ..classifier.references import load_references
    from ..core.io import guard_outputs, write_outputs
    from ..sim.condition_names import CONDITION_NAMES

    if markdown:
        guard_outputs([markdown], overwrite=overwrite)
    if report_dir:  # fail before the work, not after it
        guard_outputs(
            [Path(report_dir) / name for name in ROBUSTNESS_REPORT_FILES], overwrite=overwrite
        )
    refs = load_references(references_path)
    names = conditions or ("clean", *CONDITION_NAMES)
    jobs = jobs or os.cpu_count() or 1
    scores = _scores(
        names, refs, per_class, seed, jobs, quiet=as_json, overlays=bool(report_dir)
    )
    header, rows = robustness_table(scores)
    table = markdown_table(header, rows)
    reliability = "Reliability (best guesses over all conditions):\n\n" + markdown_table(
        *reliability_table(scores)
    )
    data = robustness_json(seed, per_class, scores)
    if as_json:
        echo_json(data)
    else:
        _print_robustness(table, reliability, scores)
    if markdown:
        command = command_line()
        write_outputs(
            {Path(markdown): f"Robustness: `{command}`\n\n" + table + "\n" + reliability},
            overwrite=overwrite,
            command=command,
        )
    if report_dir:
        _write_report(Path(report_dir), scores, data, overwrite)


def _write_report(
    out: Path, scores: list[ConditionScore], data: dict[str, Any], overwrite: bool
) -> None:
    """report.md, report.html, robustness.json and the overlays into ``out``."""
    from ..analysis.robustness_report import robustness_report
    from ..core.io import write_outputs

    command = command_line()
    files = robustness_report(scores, data, command=command)
    write_outputs({out / k: v for k, v in files.items()}, overwrite=overwrite, command=command)
    click.echo(f"report written to {out / 'report.html'}", err=True)


def _scores(
    names: tuple[str, ...],
    refs: ReferenceSet,
    per_class: int,
    seed: int,
    jobs: int,
    *,
    quiet: bool,
    overlays: bool = False,
) -> list:
    """The scores of the conditions ``names``: on a terminal a progress bar with the time
    left, else each condition told on stderr as it comes (neither when ``quiet``)."""
    import sys

    from ..analysis.robustness import score_condition
    from ..core.classes import CLASS_IDS

    live = sys.stderr.isatty() and not quiet
    total = len(names) * per_class * len(CLASS_IDS)
    scores = []
    with progress_bar(total, "scoring the conditions", quiet=not live) as bar:
        for name in names:
            for score in score_condition(
                name, refs, per_class=per_class, seed=seed, jobs=jobs,
                on_progress=bar.update, overlays=overlays,
            ):
                scores.append(score)
                if not quiet and not live:
                    click.echo(
                        f"{score.condition}: {score.right}/{score.n} right, "
                        f"{score.wrong} wrong",
                        err=True,
                    )
    return scores


def _print_robustness(table: str, reliability: str, scores: list) -> None:
    """The robustness table, the wrong answers and the reliability table on stdout."""
    from ..analysis.evaluate import outcomes_text
    from ..analysis.robustness_report import total_outcomes

    echo(table, nl=False)
    echo("all conditions: " + outcomes_text(total_outcomes(scores)["outcomes"]))
    for s in scores:
        for case in s.wrong_cases:
            echo(f"wrong under {s.condition}: {case}")
    echo("\n" + reliability, nl=False)
