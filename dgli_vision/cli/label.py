"""``dgli label``: the fold state of every frame of other simulators' cloth episodes."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import click

from ..core.words import counted
from ..labelling.formats import FORMATS, UNITS
from .errors import handle_errors
from .options import (
    json_option,
    make_jobs_option,
    overwrite_option,
    parse_size,
    references_option,
)
from .output import command_line


@click.command("label")
@click.argument("inputs", nargs=-1, required=True, metavar="INPUT [INPUT...]")
@click.option(
    "-o",
    "--out",
    "out_dir",
    type=click.Path(file_okay=False),
    help="Write NAME.jsonl, NAME.csv and NAME_timeline.svg and .png per episode, and "
         "summary.json and report.html (the timelines on one page) here.",
)
@json_option("Print {\"episodes\": [...], \"summary\": {...}} as one JSON object.")
@click.option(
    "--format",
    "fmt",
    type=click.Choice(FORMATS),
    help="Input format [default: by extension: .npz, .mat, a folder of .obj/.ply meshes].",
)
@click.option(
    "--up-axis",
    default="z",
    show_default=True,
    help="The simulator's up axis: x, y, z or with a sign (-y).",
)
@click.option(
    "--units",
    type=click.Choice(list(UNITS)),
    default="m",
    show_default=True,
    help="Length unit of the positions.",
)
@click.option(
    "--size",
    "size_mm",
    callback=parse_size,
    metavar="W[xH]",
    help="The cloth's real size in mm (positions are scaled to it; refused when a rest "
    "frame of a napkin's size in --units measures more than 5% otherwise) [default: "
    "measured on the rest frame in --units].",
)
@click.option(
    "--rest",
    type=click.Path(),
    help="A file (or mesh folder) whose first frame is the flat cloth at rest "
    "[default: each episode's first frame, which must then be flat: an episode that "
    "starts folded is refused].",
)
@make_jobs_option
@click.option(
    "--dask",
    "dask_address",
    metavar="ADDRESS",
    help="Run on a Dask distributed cluster (its scheduler's address, tcp://host:8786); "
    "needs the 'dask' extra.",
)
@click.option(
    "--no-geometry",
    is_flag=True,
    help="Leave each frame's fold sizes out (measured on the mesh; about as much work "
    "again as the rest of the labelling).",
)
@click.option(
    "--goal",
    "goal_text",
    metavar="STATE[:SIZES]",
    help="Judge each episode's last frame against this goal: the largest distance of a "
    "vertex from the goal's ideal folded cloth (the simulation benchmarks' success: within "
    "45 mm, 75 mm for two or more folds) beside ours (the state, each crease and tip within "
    "20 mm). SIZES: a corner's legs (02:AB=180,BC=180), inset=MM, offset=MM or tip=U,V "
    "[default: the class's middle sizes].",
)
@click.option(
    "--resume",
    is_flag=True,
    help="Go on with an interrupted run: keep the episodes already in -o DIR's "
    "results.jsonl and label the rest (refused when the run differs: inputs, references, "
    "options).",
)
@references_option
@overwrite_option
@handle_errors
def label_cmd(
    inputs: tuple[str, ...],
    out_dir: str | None,
    as_json: bool,
    fmt: str | None,
    up_axis: str,
    units: str,
    size_mm: tuple[float, float] | None,
    rest: str | None,
    jobs: int,
    dask_address: str | None,
    references_path: str | None,
    goal_text: str | None,
    no_geometry: bool,
    resume: bool,
    overwrite: bool,
) -> None:
    """Label every frame of cloth episodes from other simulators.

    INPUT is an NPZ file (positions (T, N, 3) or (N, 3) with grid (rows, cols) or
    faces (F, 3); SoftGym's (T, N, 4)), CloSE's MATLAB .mat (phiPositions, Eb) or a
    folder of .obj/.ply meshes, one per frame in name order. Each frame gets its state
    (class, variant, fold in progress, confidence), smoothed over the episode; a bad
    episode is reported (one line) and the others go on (exit 2 at the end).

    With -o DIR, each episode's files are written, and it is recorded in results.jsonl,
    as soon as it is labelled; one run at a time writes into DIR. Ctrl-C or SIGTERM
    writes summary.json of what is done and exits 130 (143); --resume goes on from there.
    """
    from ..core.errors import InvalidInputError
    from ..core.io import guard_outputs
    from ..labelling.episodes import ReadOptions, parse_up_axis
    from ..labelling.goal import parse_goal

    parse_up_axis(up_axis)  # a bad axis stops before any work
    goal = parse_goal(goal_text) if goal_text is not None else None
    if resume and not out_dir:
        raise InvalidInputError("--resume needs -o DIR, where results.jsonl is kept")
    options = ReadOptions(fmt, up_axis, units, size_mm, rest, not no_geometry)
    run = _LabelRun(tuple(inputs), options, references_path, jobs, dask_address, as_json, goal)
    if out_dir is None:
        run.go(None, None, overwrite=overwrite)
        return
    from .runs import folder_lock, open_journal

    out = Path(out_dir)
    planned = [out / "summary.json", out / "report.html"]  # results.jsonl: open_journal's
    for n in run.names:
        planned += [out / f"{n}{ext}" for ext in (".jsonl", ".csv", "_timeline.png",
                                                  "_timeline.svg")]
    with folder_lock(out):  # before anything is checked or written there
        guard_outputs(planned, overwrite=overwrite or resume)
        journal = open_journal(out / "results.jsonl", run.header(), resume, overwrite)
        run.go(out, journal, overwrite=overwrite or resume)


def _write_stdout(text: str) -> None:
    """Write ``text`` to standard output and make sure all of it went: a full disk or a
    closed pipe is an error (exit 2), never a truncated answer and exit 0. (A text
    stream over an unbuffered file drops what a short write did not take, without an
    error, so the bytes go to the raw stream, each write's count checked.)"""
    from ..core.errors import OutputError

    buffer = getattr(sys.stdout, "buffer", None)
    if buffer is None:  # not a byte stream underneath: as any other output
        click.echo(text)
        return
    raw = getattr(buffer, "raw", buffer)  # (unbuffered, PYTHONUNBUFFERED: the raw file)
    data = memoryview((text + "\n").encode(sys.stdout.encoding or "utf-8", errors="replace"))
    try:
        sys.stdout.flush()
        while len(data):
            n = raw.write(data[: 1 << 20])
            if not n:  # None (would block) or 0: nothing more goes
                raise OSError(28, "No space left on device")
            data = data[n:]
    except OSError as exc:
        raise OutputError(f"cannot write to standard output: {exc.strerror or exc}") from None


class _LabelRun:
    """``dgli label`` once its inputs are known: label, write, print, sum up."""

    def __init__(
        self,
        inputs: tuple[str, ...],
        options: Any,
        references_path: str | None,
        jobs: int,
        dask_address: str | None,
        as_json: bool,
        goal: Any = None,
    ) -> None:
        from ..labelling.outputs import episode_names

        self.inputs, self.options = inputs, options
        self.references_path, self.jobs, self.dask = references_path, jobs, dask_address
        self.as_json = as_json
        self.goal = goal
        self.names = episode_names(inputs)

    def header(self) -> dict[str, Any]:
        """What defines this run, for results.jsonl: each input by its files' names,
        sizes and times, the references and rest file by checksum, the options."""
        from ..classifier.references import default_references_path
        from ..core.run_lock import file_digest, listing_digest, run_header

        def files_of(path: str) -> list[tuple[str, int, int]]:
            p = Path(path)
            found = sorted(p.iterdir()) if p.is_dir() else [p]
            rows = []
            for f in found:
                try:
                    st = f.stat()
                    rows.append((str(f.resolve()), st.st_size, st.st_mtime_ns))
                except OSError:
                    rows.append((str(f), -1, -1))
            return rows

        inputs = listing_digest(row for path in self.inputs for row in files_of(path))
        refs = self.references_path or default_references_path()
        o = self.options
        return run_header(
            "label",
            {
                "input": inputs,
                "references": file_digest(refs),
                "options": {
                    "format": o.format,
                    "up_axis": o.up_axis,
                    "units": o.units,
                    "size_mm": list(o.size_mm) if o.size_mm else None,
                    "rest": listing_digest(files_of(o.rest)) if o.rest else None,
                    **({"goal": self.goal.text} if self.goal is not None else {}),
                    **({} if o.geometry else {"geometry": False}),
                },
            },
        )

    def go(self, out: Path | None, journal: Any, *, overwrite: bool) -> None:
        """Label the episodes not in ``journal`` (its writer and the objects already in
        it), write and print each as it comes, then the summary; exit as it says."""
        from ..core.json_ready import json_ready
        from ..labelling.label import EpisodeFailure
        from ..labelling.run import LabelJob, label_episodes
        from .runs import stop_signals

        writer, earlier = journal if journal else (None, [])
        done: dict[str, dict[str, Any]] = {}
        for line in earlier:
            if isinstance(line, dict) and line.get("episode") in self.names:
                done[line["episode"]] = line
        todo = [(n, p) for n, p in zip(self.names, self.inputs) if n not in done]
        job = LabelJob(tuple(p for _, p in todo), self.options, self.references_path,
                       self.jobs, self.dask, self.goal)
        for name in self.names:  # what an earlier run did, in order, as it said it
            if name in done:
                self._print_episode(done[name])
        with stop_signals() as stop:
            try:
                with stop.ends():
                    for (name, _), result in zip(todo, label_episodes(job)):
                        if isinstance(result, EpisodeFailure):
                            entry = {"episode": name, "path": result.path, "error": result.error}
                        else:
                            entry = {"episode": name, "path": result.path,
                                     "result": result.to_json()}
                        with stop.holding():  # its files and its journal line, or neither
                            if out is not None:
                                self._write_episode(out, name, result, overwrite)
                            if writer:
                                writer.write(json_ready(entry))
                            done[name] = entry
                        self._print_episode(entry)
            finally:
                if writer:
                    writer.close()
        entries = [done[n] for n in self.names if n in done]
        self._finish(entries, out, overwrite, complete=not stop.stopped)
        if stop.stopped:
            click.echo(
                f"interrupted: {len(entries)} of {counted(len(self.names), 'episode')} done"
                + ("; go on with the same command and --resume" if out else ""),
                err=True,
            )
            sys.exit(stop.exit_code)

    def _write_episode(self, out: Path, name: str, result: Any, overwrite: bool) -> None:
        from ..core.io import write_outputs
        from ..labelling.label import EpisodeLabels
        from ..labelling.outputs import episode_files

        if isinstance(result, EpisodeLabels):
            files = episode_files(out, name, result)
            write_outputs(files, overwrite=overwrite, command=command_line())

    def _print_episode(self, entry: dict[str, Any]) -> None:
        from ..labelling.label import state_text

        if "error" in entry:
            click.echo(f"error: {entry['error']}", err=True)
            return
        ep = entry["result"]
        if ep.get("note"):
            click.echo(f"note: '{ep['path']}': {ep['note']}", err=True)
        if self.as_json:
            return
        frames = ep["frames"]
        answered = sum(f["class"] is not None for f in frames)
        first = frames[0]["smoothed"] if frames else {"class": "01", "variant": None}
        click.echo(
            f"{ep['path']}: {counted(len(frames), 'frame')} ({answered} with a class); "
            "starts as "
            f"{state_text((first['class'], first['variant']))}"
        )
        for c in ep["changes"]:
            a, b = c["from"], c["to"]
            click.echo(
                f"  frame {c['frame']}: {state_text((a['class'], a['variant']))} -> "
                f"{state_text((b['class'], b['variant']))}"
            )
        g = ep.get("goal")
        if g:
            sg, ours = g["softgym"], g["dgli"]
            told = {True: "success", False: "failed", None: "cannot tell"}[ours["success"]]
            why = f" ({'; '.join(ours['reasons'])})" if ours["reasons"] else ""
            click.echo(
                f"  goal {g['goal']}: benchmark {'success' if sg['success'] else 'failed'} "
                f"(largest distance {sg['max_distance_mm']:g} mm, within "
                f"{sg['threshold_mm']:g}); dgli {told}{why}"
            )

    def _finish(
        self, entries: list[dict[str, Any]], out: Path | None, overwrite: bool, complete: bool
    ) -> None:
        from ..core.io import record_outputs, write_outputs
        from ..core.json_ready import json_ready
        from ..labelling.outputs import summary_of_entries

        summary = summary_of_entries(entries)
        if not complete:
            summary["interrupted"] = {"done": len(entries), "of": len(self.names)}
        if out is not None:
            from ..labelling.outputs import label_html

            page = label_html(entries, summary, f"dgli label: {out}")
            write_outputs(
                {out / "summary.json": {"command": command_line(), **summary},
                 out / "report.html": page},
                overwrite=overwrite,
                command=command_line(),
            )
            record_outputs([out / "results.jsonl"], command_line())
        if self.as_json:
            episodes = [e["result"] for e in entries if "result" in e]
            _write_stdout(json.dumps(json_ready({"episodes": episodes, "summary": summary})))
        else:
            failed = len(summary["failed"])
            click.echo(
                f"{summary['labelled']} of {counted(summary['episodes'], 'episode')} labelled, "
                f"{counted(summary['frames'], 'frame')}, "
                f"{counted(summary['changes'], 'state change')}"
                + (f"; {failed} failed (above)" if failed else "")
                + (f"; written to {out}" if out else "")
            )
        if not complete:
            return
        if summary["failed"]:
            sys.exit(2)
        if summary["frames"] and not summary["frames_with_class"]:
            sys.exit(1)
