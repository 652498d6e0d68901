"""``dgli track``: the state timeline of the frames of a recording."""

from __future__ import annotations

import sys
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

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
from .output import answer_then_report, command_line, echo, echo_json
from .runs import (
    Journal,
    Stop,
    classify_into,
    open_recording_with,
    recording_notes,
    references_of,
    require_report_for_resume,
    run_journalled,
    stop_signals,
)
from .watch import rerun_option, viewer_of

if TYPE_CHECKING:
    from ..analysis.evaluate import PairOutcome
    from ..analysis.track import Timeline
    from ..classifier.references import ReferenceSet
    from ..core.io import JsonLinesWriter
    from ..sources.labelled import LabelledPair
    from ..sources.recording import Recording


@click.command()
@click.argument("folder", metavar="RECORDING", type=click.Path())
@report_option(
    "Write the timeline (CSV, JSON, picture), the frame distance heatmap and each "
    "frame's result (results.jsonl, as it is done) here."
)
@json_option("Print the timeline as JSON.")
@jobs_option
@references_option
@colours_option
@recording_options
@click.option(
    "--resume",
    is_flag=True,
    help="Go on with an interrupted run: keep the frames already in the report folder's "
    "results.jsonl and classify the rest (refused when the run differs).",
)
@rerun_option
@run_overwrite_option
@handle_errors
def track(
    folder: str,
    report_dir: str | None,
    as_json: bool,
    jobs: int | None,
    references_path: str | None,
    colours_path: str | None,
    resume: bool,
    rerun: str | None,
    overwrite: bool,
    **recording_opts: Any,
) -> None:
    """The state timeline of the frames of RECORDING.

    RECORDING is a folder of pairs (in the order of its frames.csv, color,depth[,time],
    or by name), a ROS 1 .bag, a ROS 2 bag (.db3, .mcap or its folder; needs the
    'recordings' extra) or a RealSense SDK .bag. A bag is read as it is classified.
    Each frame is classified, then the states are smoothed over time (a hidden Markov
    model whose moves are single folds and unfolds). A frame that cannot be read is a
    gap, listed; the run goes on. With labels (a folder's labels.csv, a bag's --labels),
    the timeline is scored. Exit 1 when no frame could be classified at all. With
    --report, each frame's result is kept as it is done: Ctrl-C or SIGTERM gives the
    timeline of the frames done and exits 130 (143), and --resume goes on from there.
    """
    import os

    from ..analysis.workers import start_workers_early
    from ..sources.colours_file import read_colours

    require_report_for_resume(resume, report_dir)
    colours = read_colours(colours_path) if colours_path else None
    jobs = jobs or os.cpu_count() or 1
    if os.path.exists(folder):  # they start up while this process loads and opens
        start_workers_early(jobs, references_path, colours)
    refs, refs_path = references_of(references_path)
    from ..analysis.evaluate import adopt_workers

    adopt_workers(jobs, refs, colours, references_path)
    recording = open_recording_with(folder, recording_opts)
    viewer = viewer_of(rerun, overwrite, None, folder)
    run = _TrackRun(folder, report_dir, recording, refs, colours, jobs, as_json)
    run.viewer, run.recording_opts = viewer, recording_opts
    header = {
        "kind": "track",
        "folder": folder,
        "pairs": recording.frames if recording.kind == "folder" else None,
        "labels_path": recording_opts["labels_path"],
        "refs_path": refs_path,
        "colours_path": colours_path,
        "options": recording_opts,
    }
    from ..analysis.track_report import TRACK_REPORT_FILES

    files = TRACK_REPORT_FILES  # besides results.jsonl and the overlays
    run_journalled(run, report_dir, files, header, resume=resume, overwrite=overwrite)




class _TrackRun:
    """``dgli track`` once its inputs are known: classify, smooth, print, report."""

    def __init__(
        self,
        folder: str,
        report_dir: str | None,
        recording: Recording,
        refs: ReferenceSet,
        colours: dict[str, tuple[int, int, int]] | None,
        jobs: int | None,
        as_json: bool,
    ) -> None:
        import os

        self.folder, self.report_dir, self.recording = folder, report_dir, recording
        self.refs, self.colours = refs, colours
        self.jobs = jobs or os.cpu_count() or 1
        self.as_json = as_json
        self.viewer: Any = None  # --rerun's RerunLog
        self.recording_opts: dict[str, Any] = {}
        self._keys: dict[tuple[str, str], tuple[str, str]] = {}

    def go(self, journal: Journal | None, *, overwrite: bool) -> None:
        """Classify the frames not done yet (``journal``: the results.jsonl writer and
        the objects already in it), smooth, print, report, exit as the outcome says."""
        from ..analysis.evaluate import outcomes_of, pair_key
        from ..analysis.track import track_outcomes
        from ..analysis.track_report import timeline_json

        writer, earlier = journal if journal else (None, [])
        done = outcomes_of(earlier, None)
        seen: list[LabelledPair] = []  # the frames in order, as far as they were read
        with stop_signals() as stop:
            try:
                self._classify(done, writer, seen, stop)
            finally:
                if writer:
                    writer.close()
        keys = self._keys
        found = (keys.get((p.color, p.depth)) or pair_key(p) for p in seen)
        outcomes = [done[k] for k in found if k in done]
        recording_notes(self.recording, quiet=self.as_json)
        labelled = self.recording.labelled and all(o.pair.label for o in outcomes)
        timeline = track_outcomes(
            outcomes, self.refs, times=[o.pair.time for o in outcomes], labelled=labelled
        )
        read = {"kind": self.recording.kind, "notes": list(self.recording.notes)}
        data = timeline_json(
            {"folder": self.folder, "recording": read}, timeline, outcomes, labelled
        )
        if self.viewer is not None:
            self._log(timeline, outcomes)
        if stop.stopped:
            data["interrupted"] = {"frames_done": len(outcomes), "frames": self.recording.count}
        answer_then_report(
            lambda: self._print(data, timeline, len(outcomes)),
            (lambda: self._report(data, timeline, outcomes, labelled, overwrite))
            if self.report_dir else None,
        )
        if stop.stopped:
            click.echo(
                f"interrupted: {len(outcomes)} of {counted(self.recording.count, 'frame')} done"
                + ("; go on with the same command and --resume" if self.report_dir else ""),
                err=True,
            )
            sys.exit(stop.exit_code)
        if all(f.gap for f in timeline.frames):
            sys.exit(1)

    def _log(self, timeline: Timeline, outcomes: list[PairOutcome]) -> None:
        """The timeline logged to the viewer, each frame's image read again."""
        from ..analysis.viewer import log_timeline

        again = open_recording_with(self.folder, self.recording_opts)
        try:
            log_timeline(self.viewer, timeline, outcomes, again.frames)
        finally:
            close = getattr(again.frames, "close", None)
            if close is not None:
                close()
            self.viewer.close()
        if self.viewer.path is not None:
            click.echo(f"viewer recording written to {self.viewer.path}", err=True)

    def _classify(
        self,
        done: dict[tuple[str, str], PairOutcome],
        writer: JsonLinesWriter | None,
        seen: list[LabelledPair],
        stop: Stop,
    ) -> None:
        """Classify the frames not in ``done`` into it (and ``writer``), each frame read
        into ``seen``, until all are or a stop signal comes (:func:`stop_signals`)."""
        from ..analysis.evaluate import pair_key

        keys = self._keys  # each frame's key (real paths) worked out once

        def key(pair: LabelledPair) -> tuple[str, str]:
            return keys.get((pair.color, pair.depth)) or pair_key(pair)

        def todo() -> Iterator[LabelledPair]:  # a bag's frames are read as they are classified
            for pair in self.recording.frames:
                seen.append(pair.light())
                keys[(pair.color, pair.depth)] = k = pair_key(pair)
                if k not in done:
                    yield pair

        classify_into(
            todo(),
            self.recording.count,
            "tracking",
            self,
            writer,
            done,
            stop,
            colours=self.colours,
            distances=True,
            key=key,
        )

    def _print(self, data: dict[str, Any], timeline: Timeline, n: int) -> None:
        from ..core.classes import CLASS_NAMES

        if self.as_json:
            echo_json(data)
            return

        def state(key: tuple[str, str | None]) -> str:
            name = CLASS_NAMES.get(key[0], "(no known state)")
            return f"{key[0]} {name}" + (f" {key[1]}" if key[1] else "")

        first = next((f for f in timeline.frames if not f.gap), None)
        echo(
            f"{counted(n, 'frame')}; "
            + (
                f"starts as {state((first.smoothed_class, first.smoothed_variant))}"
                if first
                else "no frame could be classified"
            )
        )
        for t, a, b in timeline.changes:
            echo(f"  frame {t}: {state(a)} -> {state(b)}")
        for f in timeline.frames:
            if f.gap:
                echo(f"gap: frame {f.index} ({f.color}): {f.note}")
        if "outcomes" in data:
            from ..analysis.evaluate import outcomes_text

            echo("frames' own answers: " + outcomes_text(data["outcomes"], "frames"))
        sc = timeline.score
        if sc is not None:
            echo(
                f"frame accuracy {sc.raw_accuracy:.0%} raw, {sc.smoothed_accuracy:.0%} "
                f"smoothed; state changes true {list(sc.true_changes)}, found "
                f"{list(sc.found_changes)} (precision {sc.precision:.2f}, recall "
                f"{sc.recall:.2f}, within 2 frames)"
            )

    def _report(
        self,
        data: dict[str, Any],
        timeline: Timeline,
        outcomes: list[PairOutcome],
        labelled: bool,
        overwrite: bool,
    ) -> None:
        from ..classifier.pipeline import classify_frame

        write_timeline_report(
            self.report_dir,
            timeline,
            outcomes,
            data,
            title=f"timeline of {self.folder}",
            labelled=labelled,
            overwrite=overwrite,
            journal=True,
            classify=lambda frame: classify_frame(frame, self.refs, colours=self.colours),
        )


def write_timeline_report(
    report_dir: str | Path,
    timeline: Timeline,
    outcomes: list[PairOutcome],
    data: dict[str, Any],
    *,
    title: str,
    labelled: bool,
    overwrite: bool,
    journal: bool = False,
    classify: Any = None,
) -> None:
    """The report of a timeline (:func:`~dgli_vision.analysis.track_report.track_report`)
    written into ``report_dir``, with the provenance of the command (and of the run's
    results.jsonl when ``journal``); ``dgli sequence --report`` writes the same. With
    ``classify`` (``classify(frame) -> FrameResult``) each frame drawn is classified again
    for its overlay's evidence (:func:`~dgli_vision.analysis.track_report.track_report`)."""
    from ..analysis.track_report import track_report
    from ..core.io import record_outputs, write_outputs
    from ..sources.frames import read_color

    out = Path(report_dir)
    command = command_line()
    files = track_report(
        timeline,
        outcomes,
        {"command": command, **data},
        title=title,
        labelled=labelled,
        read_color=read_color,
        classify=classify,
    )
    write_outputs({out / k: v for k, v in files.items()}, overwrite=overwrite, command=command)
    if journal:
        record_outputs([out / "results.jsonl"], command)
    click.echo(f"report written to {out / 'report.html'}", err=True)
