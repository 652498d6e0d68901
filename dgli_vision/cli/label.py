"""``dgli label``: the fold state of every frame of other simulators' cloth episodes."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import click

from .errors import handle_errors
from .options import json_option, overwrite_option, references_option
from .output import command_line


def _cloth_size(
    ctx: click.Context, param: click.Parameter, value: str | None
) -> tuple[float, float] | None:
    from ..core.layout import parse_size

    if value is None:
        return None
    try:
        return parse_size(value)
    except ValueError as exc:
        raise click.BadParameter(str(exc)) from None


@click.command("label")
@click.argument("inputs", nargs=-1, required=True, metavar="INPUT [INPUT...]")
@click.option(
    "-o",
    "--out",
    "out_dir",
    type=click.Path(file_okay=False),
    help="Write NAME.jsonl, NAME.csv and NAME_timeline.png per episode and summary.json here.",
)
@json_option("Print {\"episodes\": [...], \"summary\": {...}} as one JSON object.")
@click.option(
    "--format",
    "fmt",
    type=click.Choice(["npz", "mat", "meshes"]),
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
    type=click.Choice(["m", "cm", "mm"]),
    default="m",
    show_default=True,
    help="Length unit of the positions.",
)
@click.option(
    "--size",
    "size_mm",
    callback=_cloth_size,
    metavar="W[xH]",
    help="The cloth's real size in mm (positions are scaled to it) [default: measured on "
    "the rest frame in --units].",
)
@click.option(
    "--rest",
    type=click.Path(),
    help="A file (or mesh folder) whose first frame is the flat cloth at rest "
    "[default: each episode's first frame].",
)
@click.option(
    "-j", "--jobs", type=click.IntRange(1), default=1, show_default=True,
    help="Local worker processes.",
)
@click.option(
    "--dask",
    "dask_address",
    metavar="ADDRESS",
    help="Run on a Dask distributed cluster (its scheduler's address, tcp://host:8786); "
    "needs the 'dask' extra.",
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
    overwrite: bool,
) -> None:
    """Label every frame of cloth episodes from other simulators.

    INPUT is an NPZ file (positions (T, N, 3) or (N, 3) with grid (rows, cols) or
    faces (F, 3); SoftGym's (T, N, 4)), CloSE's MATLAB .mat (phiPositions, Eb) or a
    folder of .obj/.ply meshes, one per frame in name order. Each frame gets its state
    (class, variant, fold in progress, confidence), smoothed over the episode; a bad
    episode is reported (one line) and the others go on (exit 2 at the end).
    """
    from ..core.io import guard_outputs
    from ..labelling.episodes import ReadOptions, parse_up_axis
    from ..labelling.outputs import episode_names
    from ..labelling.run import LabelJob, label_episodes

    parse_up_axis(up_axis)  # a bad axis stops before any work
    options = ReadOptions(fmt, up_axis, units, size_mm, rest)
    job = LabelJob(tuple(inputs), options, references_path, jobs, dask_address)
    names = episode_names(inputs)
    out = Path(out_dir) if out_dir else None
    if out is not None:
        planned = [out / "summary.json"]
        for n in names:
            planned += [out / f"{n}.jsonl", out / f"{n}.csv", out / f"{n}_timeline.png"]
        guard_outputs(planned, overwrite=overwrite)
    results = []
    for name, result in zip(names, label_episodes(job)):
        results.append(result)
        _report_episode(result, name, out, as_json, overwrite)
    _finish(results, out, as_json, overwrite)


def _report_episode(
    result: Any, name: str, out: Path | None, as_json: bool, overwrite: bool
) -> None:
    from ..core.io import write_outputs
    from ..labelling.label import EpisodeFailure, state_text
    from ..labelling.outputs import episode_files

    if isinstance(result, EpisodeFailure):
        click.echo(f"error: {result.error}", err=True)
        return
    if out is not None:
        files = episode_files(out, name, result)
        write_outputs(files, overwrite=overwrite, command=command_line())
    if as_json:
        return
    frames = result.frames
    answered = sum(f.class_id is not None for f in frames)
    first = (frames[0].smoothed_class, frames[0].smoothed_variant)
    click.echo(
        f"{result.path}: {len(frames)} frames ({answered} with a class); starts as "
        f"{state_text(first)}"
    )
    for t, a, b in result.changes:
        click.echo(f"  frame {t}: {state_text(a)} -> {state_text(b)}")


def _finish(results: list, out: Path | None, as_json: bool, overwrite: bool) -> None:
    from ..analysis.evaluate import json_ready
    from ..core.io import write_outputs
    from ..labelling.label import EpisodeLabels
    from ..labelling.outputs import summary_of

    summary = summary_of(results)
    if out is not None:
        write_outputs(
            {out / "summary.json": {"command": command_line(), **summary}},
            overwrite=overwrite,
            command=command_line(),
        )
    if as_json:
        episodes = [r.to_dict() for r in results if isinstance(r, EpisodeLabels)]
        click.echo(json.dumps(json_ready({"episodes": episodes, "summary": summary})))
    else:
        failed = len(summary["failed"])
        click.echo(
            f"{summary['labelled']} of {summary['episodes']} episodes labelled, "
            f"{summary['frames']} frames, {summary['changes']} state changes"
            + (f"; {failed} failed (above)" if failed else "")
            + (f"; written to {out}" if out else "")
        )
    if summary["failed"]:
        sys.exit(2)
    if summary["frames"] and not summary["frames_with_class"]:
        sys.exit(1)
