"""``dgli evaluate``: classify every labelled pair of a folder and report."""

from __future__ import annotations

import sys
from collections.abc import Iterator
from typing import Any

import click

from ..core.words import counted
from .errors import handle_errors
from .options import (
    colours_option,
    jobs_option,
    json_option,
    recording_options,
    references_option,
    report_option,
    run_overwrite_option,
)
from .output import answer_then_report, command_line, echo, echo_json, package_version
from .runs import (
    Stop,
    classify_into,
    open_recording_with,
    recording_notes,
    references_of,
    require_report_for_resume,
    run_journalled,
    stop_signals,
)


@click.command()
@click.argument("folder", type=click.Path())
@report_option("Write a report here.")
@json_option("Print the summary as JSON.")
@jobs_option
@references_option
@colours_option
@recording_options
@click.option(
    "--lenient",
    is_flag=True,
    help="Skip (and list) label rows with an unknown class or variant, or repeated, "
    "instead of stopping.",
)
@click.option(
    "--resume",
    is_flag=True,
    help="Go on with an interrupted run: keep the pairs already in the report folder's "
    "results.jsonl and classify the rest (refused when the run differs: references, "
    "labels, colours, intrinsics, options).",
)
@run_overwrite_option
@handle_errors
def evaluate(
    folder: str,
    report_dir: str | None,
    as_json: bool,
    jobs: int | None,
    references_path: str | None,
    colours_path: str | None,
    lenient: bool,
    resume: bool,
    overwrite: bool,
    **recording_opts: Any,
) -> None:
    """Classify every labelled pair of FOLDER and report accuracy and confusions.

    FOLDER may also be a recorded episode (a ROS or RealSense bag) with --labels.

    Labels are checked first: an unknown class or variant, or a pair listed twice,
    stops the run (exit 2) unless --lenient; pairs that cannot be read are listed with
    their error and the run goes on. With --report, each pair's result is appended to
    results.jsonl as it is done; Ctrl-C or SIGTERM writes the report of what is done and
    exits 130 (143), and --resume goes on from there, giving the same report as an
    uninterrupted run. Exit 1 when no pair could be classified, 2 when none could be read.
    """
    import os

    from ..analysis.workers import start_workers_early
    from ..sources.colours_file import read_colours

    require_report_for_resume(resume, report_dir)
    colours = read_colours(colours_path) if colours_path else None  # (a bad file: no work)
    pairs, problems, recording = _labelled_input(folder, lenient, recording_opts)
    n_jobs = jobs or os.cpu_count() or 1
    # the labels are good: the workers start up while this process loads the references
    start_workers_early(n_jobs, references_path, colours)
    from ..analysis.evaluate import adopt_workers
    from ..analysis.evaluation_report import REPORT_FILES

    refs, refs_path = references_of(references_path)
    adopt_workers(n_jobs, refs, colours, references_path)
    run = _EvaluationRun(
        folder,
        report_dir,
        pairs,
        problems,
        recording,
        refs,
        refs_path,
        colours_path,
        jobs,
        as_json,
    )
    header = {
        "kind": "evaluate",
        "folder": folder,
        "pairs": None if recording else pairs,
        "labels_path": recording_opts["labels_path"],
        "refs_path": refs_path,
        "colours_path": colours_path,
        "options": {"lenient": lenient, **recording_opts},
    }
    run_journalled(run, report_dir, REPORT_FILES, header, resume=resume, overwrite=overwrite)


def _labelled_input(folder: str, lenient: bool, recording_opts: dict[str, Any]) -> tuple:
    """The labelled pairs of ``folder``, the problems found in its labels (listed on
    stderr) and, for a recording file, the recording (its pairs are read as they are
    classified)."""
    from ..core.errors import InvalidInputError
    from ..sources.labelled import find_labelled_pairs
    from ..sources.recording import is_recording_file

    recording = None
    if is_recording_file(folder):
        if not recording_opts["labels_path"]:
            raise InvalidInputError(
                f"recording '{folder}' needs --labels FILE to be evaluated (CSV: frame or "
                "time, label, variant); 'dgli track' reads it without labels"
            )
        recording = open_recording_with(folder, recording_opts)
        pairs, problems = [], []
    else:
        pairs, problems = find_labelled_pairs(folder, lenient=lenient)
    for problem in problems:
        if problem.kind != "missing file":  # those are listed with the failures
            click.echo(f"skipped: {problem.message}", err=True)
    return pairs, problems, recording


class _EvaluationRun:
    """``dgli evaluate`` once its inputs are known: classify, print, report."""

    def __init__(
        self,
        folder: str,
        report_dir: str | None,
        pairs: list,
        problems: list,
        recording: Any,
        refs: Any,
        refs_path: Any,
        colours_path: str | None,
        jobs: int | None,
        as_json: bool,
    ) -> None:
        import os

        self.folder, self.report_dir = folder, report_dir
        self.pairs, self.problems, self.recording = pairs, problems, recording
        self.refs, self.refs_path, self.colours_path = refs, refs_path, colours_path
        self.jobs = jobs or os.cpu_count() or 1
        self.as_json = as_json

    def go(self, journal: tuple[Any, list] | None, *, overwrite: bool) -> None:
        """Classify what is not done yet (``journal``: the results.jsonl writer and the
        objects already in it), print, write the report, exit as the outcome says."""
        import time

        from ..analysis.evaluate import outcomes_of, pair_key, summarise

        writer, earlier = journal if journal else (None, [])
        done = outcomes_of(earlier, None if self.recording else self.pairs)
        t0 = time.perf_counter()
        with stop_signals() as stop:
            try:
                self._classify(done, writer, stop)
            finally:
                if writer:
                    writer.close()
        outcomes = [done[pair_key(p)] for p in self.pairs if pair_key(p) in done]
        result = summarise(outcomes, time.perf_counter() - t0)
        skipped = [p.message for p in self.problems if p.kind != "missing file"]
        if self.recording:
            recording_notes(self.recording, quiet=self.as_json)
            skipped += [f"{name}: no label" for name in self.unlabelled]
        answer_then_report(
            lambda: self._print(result, skipped),
            (lambda: self._report(result, skipped, overwrite)) if self.report_dir else None,
        )
        if stop.stopped:
            click.echo(
                f"interrupted: {len(outcomes)} of {counted(len(self.pairs), 'pair')} done"
                + ("; go on with the same command and --resume" if self.report_dir else ""),
                err=True,
            )
            sys.exit(stop.exit_code)
        if result.n and not result.classified and not any(o.correct for o in outcomes):
            if all(o.error for o in outcomes):
                click.echo(f"error: {_none_of(result.n)} could be read", err=True)
                sys.exit(2)
            click.echo(f"error: {_none_of(result.n)} could be classified", err=True)
            sys.exit(1)

    def _classify(self, done: dict, writer: Any, stop: Stop) -> None:
        """Classify the pairs not in ``done`` into it (and ``writer``), until all are or
        a stop signal comes (:func:`stop_signals`)."""
        from ..analysis.evaluate import pair_key
        from ..sources.colours_file import read_colours

        recording, pairs = self.recording, self.pairs
        colours = read_colours(self.colours_path) if self.colours_path else None
        self.unlabelled: list[str] = []

        def todo() -> Iterator[Any]:  # a recording's frames are read as they are classified
            for pair in recording.frames if recording else pairs:
                if recording and not pair.label:
                    self.unlabelled.append(pair.color)
                    continue
                if recording:
                    pairs.append(pair.light())
                if pair_key(pair) not in done:
                    yield pair

        count = recording.count if recording else sum(pair_key(p) not in done for p in pairs)
        if count:
            classify_into(todo(), count, "classifying", self, writer, done, stop, colours=colours)

    def _print(self, result: Any, skipped: list[str]) -> None:
        if self.as_json:
            echo_json({**result.to_json(), "skipped": skipped})
            return
        from ..analysis.evaluate import SPLIT_COLUMNS, counts_text
        from ..analysis.report import markdown_table

        # the four outcomes once, then what share was answered and how well
        answered = result.outcomes_text().split("; ", 1)[1]
        echo(f"{counted(result.n, 'pair')}: {counts_text(result.outcome_counts)}; {answered}")
        echo(
            f"class accuracy {result.accuracy:.2%}, "
            f"variant accuracy {result.variant_accuracy_text()}, "
            f"{result.seconds:.1f} s with {self.jobs} worker(s)"
        )
        echo(
            markdown_table(
                ["true \\ predicted", *result.labels, *SPLIT_COLUMNS],
                [[lab, *row] for lab, row in zip(result.labels, result.confusion_split())],
            ),
            nl=False,
        )
        for o in result.outcomes:
            if o.error is not None:
                echo(f"unreadable: {o.pair.color}: {o.error}")
            elif o.predicted is None:
                why = (o.reason or "no reason given").removeprefix("cannot tell: ")
                echo(f"cannot tell: {o.pair.color}: {why}")
            elif not o.correct:
                echo(
                    f"wrong: {o.pair.color}: labelled {o.pair.label}, answered {o.predicted}"
                )

    def _report(self, result: Any, skipped: list[str], overwrite: bool) -> None:
        from pathlib import Path

        from ..analysis.evaluation_report import build_report
        from ..core.io import file_sha256, record_outputs, write_outputs
        from ..core.json_ready import json_ready
        from ..sources.frames import read_color

        meta = {
            "command": command_line(),
            "folder": self.folder,
            "references": str(self.refs_path),
            "references_sha256": file_sha256(self.refs_path),
            "package_version": package_version(),
            "jobs": self.jobs,
            "skipped": skipped,
        }
        from ..classifier.pipeline import classify_frame
        from ..sources.colours_file import read_colours

        colours = read_colours(self.colours_path) if self.colours_path else None
        out = Path(self.report_dir)
        files = build_report(
            result, meta, read_color,
            classify=lambda frame: classify_frame(frame, self.refs, colours=colours),
        )
        write_outputs(
            {out / name: json_ready(c) if isinstance(c, dict) else c for name, c in files.items()},
            overwrite=overwrite,
            command=meta["command"],
        )
        record_outputs([out / "results.jsonl"], meta["command"])
        click.echo(f"report written to {out / 'report.html'} (and report.md)", err=True)


def _none_of(n: int) -> str:
    """``"none of the 3 pairs"``, or ``"not even the one pair"`` for one."""
    return "not even the one pair" if n == 1 else f"none of the {n} pairs"
