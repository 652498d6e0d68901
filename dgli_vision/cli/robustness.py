"""``dgli robustness``: the robustness and reliability tables."""

from __future__ import annotations

import json

import click

from .errors import handle_errors
from .options import (
    jobs_option,
    json_option,
    overwrite_option,
    parse_conditions,
    per_class_option,
    references_option,
)
from .output import command_line


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
    from pathlib import Path

    from ..condition_names import CONDITION_NAMES
    from ..io import guard_outputs, write_outputs
    from ..references import load_references
    from ..report import markdown_table
    from ..robustness import (
        reliability_rows,
        reliability_table,
        robustness_table,
        score_condition,
    )

    if markdown:
        guard_outputs([markdown], overwrite=overwrite)
    refs = load_references(references_path)
    names = conditions or ("clean", *CONDITION_NAMES)
    jobs = jobs or os.cpu_count() or 1
    scores = []
    for name in names:
        for score in score_condition(name, refs, per_class=per_class, seed=seed, jobs=jobs):
            scores.append(score)
            if not as_json:
                click.echo(
                    f"{score.condition}: {score.right}/{score.n} right, {score.wrong} wrong",
                    err=True,
                )
    header, rows = robustness_table(scores)
    table = markdown_table(header, rows)
    reliability = "Reliability (best guesses over all conditions):\n\n" + markdown_table(
        *reliability_table(scores)
    )
    if as_json:
        click.echo(
            json.dumps(
                {
                    "seed": seed,
                    "per_class": per_class,
                    "rows": [dict(zip(header, r)) for r in rows],
                    "wrong": {s.condition: list(s.wrong_cases) for s in scores},
                    "reliability": reliability_rows(scores),
                }
            )
        )
    else:
        click.echo(table, nl=False)
        for s in scores:
            for case in s.wrong_cases:
                click.echo(f"wrong under {s.condition}: {case}")
        click.echo("\n" + reliability, nl=False)
    if markdown:
        command = command_line()
        write_outputs(
            {Path(markdown): f"Robustness: `{command}`\n\n" + table + "\n" + reliability},
            overwrite=overwrite,
            command=command,
        )
