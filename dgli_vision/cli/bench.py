"""``dgli bench``: the benchmark figures against their budgets."""

from __future__ import annotations

import sys

import click

from ..core.words import counted
from .errors import handle_errors
from .options import overwrite_option
from .output import command_line, echo


def _format_figure(value: float, unit: str) -> str:
    if unit.endswith("/s"):
        for scale, prefix in ((1e6, "M "), (1e3, "k ")):
            if value >= scale:
                return f"{value / scale:.2f} {prefix}{unit}"
        return f"{value:.1f} {unit}"
    if unit == "x":
        return f"{value:,.0f}x" if value >= 10 else f"{value:.2f}x"
    return f"{value:.3g} {unit}"


@click.command()
@click.option("--states", default=100_000, show_default=True, help="States in the batch case.")
@click.option("--repeats", default=5, show_default=True, help="Timing rounds (best is kept).")
@click.option(
    "--markdown",
    type=click.Path(),
    help="Also write the figures as a Markdown table to this file.",
)
@click.option(
    "--only",
    type=click.Choice(["dgli", "pipeline", "frames", "recording", "label", "watch"]),
    help="Run one group of benchmarks only. frames: every frame of a varied set it "
    "renders (every capture condition, another camera, a fold held by a gripper), its "
    "median, p90 and slowest frame and each stage's time. label: dgli label's frames per "
    "second per core (96 x 58 grid, 3,000-vertex remeshed cloth) and -j 2's speed-up.",
)
@click.option(
    "--per-condition",
    default=12,
    show_default=True,
    type=click.IntRange(1, 120),
    help="Frames per capture condition in the frames group (and in --vs-aruco).",
)
@click.option(
    "--vs-aruco",
    is_flag=True,
    help="Only ours against OpenCV's ArUco detector (DICT_4X4_50, default parameters), "
    "frame by frame, interleaved, one core, on the frames of every capture condition: "
    "median of ours over median of ArUco's (budget <= 1.0) and the per-frame ratio's "
    "p90 (<= 1.5) and max, per condition and overall, with the absolute times. The "
    "frames group reports the same ratios.",
)
@click.option(
    "--conditions",
    "conditions_text",
    metavar="A,B,...",
    help="Capture conditions of the frames group and --vs-aruco after clean "
    "[default: every one the renderer knows].",
)
@click.option(
    "--samples",
    type=click.Path(file_okay=False),
    help="Labelled folder for the pipeline benchmarks [default: sample_images here, "
    "else the shipped samples of the source tree].",
)
@overwrite_option
@handle_errors
def bench(
    states: int,
    repeats: int,
    markdown: str | None,
    only: str | None,
    samples: str | None,
    per_condition: int,
    vs_aruco: bool,
    conditions_text: str | None,
    overwrite: bool,
) -> None:
    """Measure the benchmark figures against their budgets (one core where a budget says so)."""
    import shutil
    from pathlib import Path

    from ..analysis import bench as b
    from ..core.io import guard_outputs

    if markdown:
        guard_outputs([markdown], overwrite=overwrite)
    conditions = _conditions(conditions_text)
    if vs_aruco and only not in (None, "frames"):
        raise click.UsageError("--vs-aruco is part of the frames group: not with --only "
                               f"{only}")
    results = []

    def stage(what: str) -> None:  # a word before each long group (a minute or more)
        click.echo(f"bench: {what} ...", err=True)

    if vs_aruco:
        figures, _ = b.run_aruco_benchmarks(
            per_condition=per_condition, repeats=repeats, conditions=conditions
        )
        _echo(figures, markdown, overwrite)
        return
    if only in (None, "dgli"):
        stage(f"dgli coordinates, {states:,} states, best of {repeats}")
        results += b.run_dgli_benchmarks(n_states=states, repeats=repeats)
    if only in (None, "pipeline", "recording", "watch"):
        samples = _samples_folder(samples)
    if only in (None, "pipeline"):
        exe = Path(sys.executable).parent / "dgli-classify"
        exe_path = str(exe) if exe.exists() else shutil.which("dgli-classify")
        stage(f"pipeline on '{samples}', best of {repeats} (about a minute)")
        results += b.run_pipeline_benchmarks(samples, repeats=repeats, classify_exe=exe_path)
    if only in (None, "frames"):
        stage(f"frames: rendering {counted(per_condition, 'frame')} a condition and timing "
              f"each, best of {repeats} (a minute or more)")
        results += b.run_frame_benchmarks(
            per_condition=per_condition, sequence_frames=per_condition, repeats=repeats,
            conditions=conditions,
        )[0]
    if only in (None, "recording"):
        stage("recording")
        results += b.run_recording_benchmarks(samples)
    if only in (None, "label"):
        from ..labelling.bench import run_label_benchmarks

        stage("label")
        results += run_label_benchmarks(repeats=repeats)
    if only in (None, "watch"):
        stage("watch")
        results += b.run_watch_benchmarks(samples)
    _echo(results, markdown, overwrite)


def _conditions(text: str | None) -> tuple[str, ...]:
    """The capture conditions of ``--conditions``, checked against the renderer's."""
    from ..sim.condition_names import CONDITION_NAMES

    if not text:
        return ()
    names = tuple(n.strip() for n in text.split(",") if n.strip() and n.strip() != "clean")
    unknown = [n for n in names if n not in CONDITION_NAMES]
    if unknown:
        raise click.BadParameter(
            f"unknown condition {unknown[0]!r} (known: {', '.join(CONDITION_NAMES)})",
            param_hint="--conditions",
        )
    return names


def _echo(results: list, markdown: str | None, overwrite: bool) -> None:
    """Print the figures (and write them as Markdown); exit 1 when a budget is missed."""
    rows = []
    for r in results:
        value = _format_figure(r.value, r.unit)
        verdict = "" if r.ok is None else ("ok" if r.ok else "MISSED")
        rows.append((r.name, value, r.goal, verdict))
        echo(f"{r.name:<60} {value:>18}  {r.goal:<16} {verdict}")
    if markdown:
        _write_markdown(rows, markdown, overwrite)
    missed = sum(r.ok is False for r in results)
    if missed:
        click.echo(_busy_note(missed), err=True)
        sys.exit(1)  # a budget missed: the figures are printed (and written) all the same


def _busy_note(missed: int) -> str:
    """What a missed budget may mean: the machine's load beside its cores."""
    import os

    cores = os.cpu_count() or 1
    try:
        load = os.getloadavg()[0]
    except OSError:
        return (f"note: {counted(missed, 'budget')} missed (exit 1); time them again on an "
                "idle machine")
    busy = " (a busy machine: the times are not this tool's own)" if load > 0.5 * cores else ""
    return (
        f"note: {counted(missed, 'budget')} missed (exit 1); load average {load:.1f} on "
        f"{counted(cores, 'core')}{busy}; time them again on an idle machine"
    )


def _write_markdown(rows: list[tuple[str, str, str, str]], markdown: str, overwrite: bool) -> None:
    import platform
    from pathlib import Path

    from ..core.io import write_outputs

    lines = [
        "| benchmark | figure | goal | verdict |",
        "|---|---|---|---|",
        *(f"| {n} | {v} | {g} | {ok} |" for n, v, g, ok in rows),
        "",
        f"Machine: {platform.machine()}, Python {platform.python_version()}, "
        f"numpy {__import__('numpy').__version__}.",
    ]
    write_outputs(
        {Path(markdown): "\n".join(lines) + "\n"}, overwrite=overwrite, command=command_line()
    )


def _samples_folder(samples: str | None) -> str:
    """The labelled folder of the pipeline benchmarks: ``samples``, else
    ``sample_images`` in the working folder, else the source tree's shipped samples."""
    from pathlib import Path

    if samples:
        return samples
    for folder in (Path("sample_images"), Path(__file__).resolve().parents[2] / "sample_images"):
        if (folder / "labels.csv").is_file():
            return str(folder)
    raise click.UsageError(
        "no sample_images folder here or in the source tree: give --samples FOLDER"
    )
