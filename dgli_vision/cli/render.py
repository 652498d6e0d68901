"""``dgli render``: a labelled RGB-D folder (or a recorded sequence) of simulated states."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import click

from ..core.words import counted
from ..sim.condition_names import CONDITION_HELP
from .errors import handle_errors
from .options import (
    make_jobs_option,
    overwrite_option,
    parse_conditions,
    per_class_option,
    size_option,
)
from .output import command_line, echo, napkin_provenance, package_version, progress
from .runs import folder_lock, stop_signals


@click.command("render")
@click.argument("out", type=click.Path(file_okay=False))
@per_class_option(1, 50, "Pairs per class (0: none, with --outside)", minimum=0)
@click.option(
    "--outside",
    default=0,
    show_default=True,
    type=click.IntRange(0, 400),
    help="Also render this many states outside the twelve (folded in quarters, "
    "gate-folded, a strip and a corner, a corner folded twice, a skewed fold, two "
    "strips, a diagonal folded again, crumpled: eight kinds in turn), labelled none.",
)
@click.option("--seed", default=0, show_default=True, type=int, help="Seed of the whole set.")
@click.option(
    "--clean", is_flag=True, help="Switch the sensor model off (no noise, blur, dropouts)."
)
@click.option(
    "--nominal", is_flag=True, help="Nominal scene: straight down from 520 mm, default lighting."
)
@click.option(
    "--conditions",
    "conditions",
    callback=parse_conditions,
    default="",
    help="Capture conditions, comma-separated, all of them applied together to every "
    "pair (see --per-condition for a folder per condition): "
    + ", ".join(f"{k} ({v})" for k, v in CONDITION_HELP.items())
    + ".",
)
@click.option(
    "--per-condition",
    is_flag=True,
    help="One set per condition of --conditions instead, each in its own folder "
    "OUT/<condition>/ under that condition alone.",
)
@click.option(
    "--sequence",
    type=click.Choice(["I", "II", "III"]),
    default=None,
    help="Render this folding sequence as one recording instead (frames in order, "
    "frames.csv, labels by the 90-degree rule).",
)
@click.option(
    "--frames",
    default=25,
    show_default=True,
    type=click.IntRange(2),
    help="Frames of --sequence, spread evenly over its folds.",
)
@click.option(
    "--gripper",
    is_flag=True,
    help="A robot's gripper holds the corner being folded in every frame of --sequence "
    "(without --sequence: the condition grasp).",
)
@click.option(
    "--resume",
    is_flag=True,
    help="Go on with an interrupted render of the same set into OUT: keep its complete "
    "pairs and render the rest (refused when the set differs).",
)
@click.option(
    "--engine",
    type=click.Choice(["raster", "cycles"]),
    default="raster",
    show_default=True,
    help="raster: the tool's own renderer; cycles: path-traced by Blender's Cycles on the "
    "CPU with a camera pipeline and a time-of-flight depth model (the photoreal extra: "
    "pip install dgli_vision[photoreal]; tens of seconds a pair).",
)
@click.option(
    "--envelope",
    type=click.Choice(["spec", "far", "head", "wide", "all"]),
    default="all",
    show_default=True,
    help="With --engine cycles, where the camera stands: spec (450-800 mm, tilt <= 15 deg), "
    "far (0.7-1.0 m, <= 25 deg), head (a robot's head camera, 1.0-1.2 m, <= 35 deg), "
    "all of these three in turn, or wide (1.0-2.0 m, <= 35 deg).",
)
@click.option(
    "--scene",
    type=click.Choice(["standard", "varied"]),
    default="standard",
    show_default=True,
    help="With --engine cycles, the scene: standard, or varied (the napkin anywhere in "
    "the view, wooden or matte tables, a bar lamp whose streak crosses a sticker, lamps "
    "of 2,700-6,500 K each, the camera pipeline's and depth model's parameters drawn).",
)
@click.option(
    "--samples",
    default=32,
    show_default=True,
    type=click.IntRange(1, 4096),
    help="With --engine cycles, Cycles' samples per pixel (adaptive, then denoised).",
)
@size_option
@make_jobs_option
@overwrite_option
@handle_errors
def render_cmd(
    out: str,
    per_class: int,
    outside: int,
    seed: int,
    clean: bool,
    nominal: bool,
    conditions: tuple[str, ...],
    per_condition: bool,
    sequence: str | None,
    frames: int,
    gripper: bool,
    resume: bool,
    engine: str,
    envelope: str,
    scene: str,
    samples: int,
    size_mm: tuple[float, float] | None,
    jobs: int,
    overwrite: bool,
) -> None:
    """Render a labelled RGB-D folder of simulated states to OUT (the labelled-folder
    format of docs/napkin.md). --outside N adds N states outside the twelve, labelled
    none (docs/outside.md).

    With --sequence, a folding sequence as the frames of one recording, for `dgli track`.
    --conditions applies all its conditions together to every pair; with
    --per-condition each condition gets a set of its own, in OUT/<condition>/.
    Each pair is written, and listed in labels.csv, as soon as it is rendered: Ctrl-C
    or SIGTERM exits 130 (143), and even a kill keeps the pairs done; --resume renders
    the rest. -j spreads the pairs over processes (the same
    pairs as one; a sequence's frames render in one).
    """
    if engine == "cycles":
        _check_cycles(conditions, sequence, gripper)
    from pathlib import Path

    from ..core.io import guard_outputs
    from ..core.layout import layout_of_size
    from ..sim.dataset import render_plan
    from ..sources.labelled import labelled_folder_files

    _check_options(per_condition, conditions, sequence, per_class, outside, engine, scene)
    # (folder, its conditions): one set, or one per condition
    sets = ([(str(Path(out) / c), (c,)) for c in conditions] if per_condition
            else [(out, conditions)])
    if gripper:
        sets = [(f, c if "grasp" in c else (*c, "grasp")) for f, c in sets]
    # a path-traced set is slow: in the order of the pairs' numbers, so that one stopped
    # part-way (Ctrl-C writes what is done) has every class
    names, cases = render_plan(
        per_class, sequence, frames, by_number=engine == "cycles", outside=outside
    )
    for folder, _ in sets:  # every folder before the work
        guard_outputs(labelled_folder_files(folder, names, frames=bool(sequence)),
                      overwrite=overwrite)

    layout = layout_of_size(size_mm)
    for folder, conds in sets:
        provenance = {
            "command": command_line(),
            "seed": seed,
            **({"sequence": sequence, "frames": frames} if sequence
               else {"per_class": per_class}),
            **({"outside": outside} if outside else {}),
            "clean": clean,
            "nominal": nominal,
            **({"conditions": list(conds)} if conds else {}),
            **napkin_provenance(layout),
            **(
                {"engine": engine, "envelope": envelope, "samples": samples,
                 **({"scene": scene} if scene != "standard" else {})}
                if engine == "cycles"
                else {}
            ),
            "package_version": package_version(),
        }
        options: dict[str, Any] = {
            "nominal": nominal, "clean": clean, "conditions": conds, "layout": layout
        }
        if engine == "cycles":
            import os

            threads = max(1, (os.cpu_count() or 2) // max(1, jobs))
            options = {
                "nominal": nominal, "clean": clean, "layout": layout, "engine": engine,
                "envelope": envelope, "samples": samples, "threads": threads,
                "scene": scene,
            }
        with folder_lock(folder):
            _render_set(
                folder, names, cases, provenance, options, resume=resume, overwrite=overwrite,
                jobs=jobs,
            )


def _check_options(
    per_condition: bool,
    conditions: tuple[str, ...],
    sequence: str | None,
    per_class: int,
    outside: int,
    engine: str,
    scene: str,
) -> None:
    """The options that do not go together, refused as a usage error (exit 2)."""
    if per_condition and not conditions:
        raise click.UsageError("--per-condition needs --conditions C,...")
    if not sequence and per_class == 0 and outside == 0:
        raise click.UsageError("--per-class 0 renders nothing: give --outside N as well")
    if sequence and outside:
        raise click.UsageError("--outside renders single pairs, not a --sequence")
    if engine == "cycles" and outside:
        raise click.UsageError("--outside renders with the raster engine only")
    if engine != "cycles" and scene != "standard":
        raise click.UsageError("--scene varied renders with --engine cycles only")


def _render_set(
    out: str,
    names: list[str],
    cases: list[tuple[str, int]],
    provenance: dict[str, Any],
    options: dict[str, Any],
    *,
    resume: bool,
    overwrite: bool,
    jobs: int = 1,
) -> None:
    """Render the pairs of ``names`` (of a sequence, or ``cases``: class and number) not
    kept from an interrupted run (``resume``), writing each as it is done (its images,
    then the listings naming it: a kill at any instant keeps the pairs finished), and
    exit 130/143 if stopped."""
    from ..sim.dataset import SEQUENCE_FRAME_SECONDS, kept_pairs, render_sequence
    from ..sources.labelled import LabelledFolderWriter

    sequence, seed = provenance.get("sequence"), provenance["seed"]
    kept = kept_pairs(out, provenance, names) if resume else {}
    todo = [k for k, n in enumerate(names) if n not in kept]
    if kept:
        click.echo(f"resuming: {len(kept)} of {counted(len(names), 'pair')} kept", err=True)
    if sequence:
        stream = render_sequence(
            sequence,
            len(names),
            seed,
            skip={k for k, n in enumerate(names) if n in kept},
            **options,
        )
    else:
        from ..core.parallel import ordered_map

        stream = ordered_map(_render_case, [(cases[k], seed, options) for k in todo], jobs=jobs)
    index = {n: k for k, n in enumerate(names)}
    writer = LabelledFolderWriter(out, provenance, names, frames=bool(sequence), kept=kept,
                                  overwrite=overwrite)
    with stop_signals() as stop, stop.ends(), progress(todo, "rendering", lines=True) as bar:
        for _, sample in zip(bar, stream):  # the bar first: each line counts pairs written
            with stop.holding():  # the pair and the listings naming it
                if not writer.written and not resume:
                    # an earlier render's pairs not rendered again go first
                    _remove_earlier_pairs(out, names, bool(sequence), overwrite)
                time_s = index[sample.name] * SEQUENCE_FRAME_SECONDS if sequence else None
                writer.add(sample, time_s)
    labels = writer.labels
    done = writer.written + len(kept)
    if stop.stopped:
        click.echo(
            f"interrupted: {done} of {counted(len(names), 'pair')} written to {out}"
            + (f" (labels: {labels}); go on with the same command and --resume" if done else ""),
            err=True,
        )
        sys.exit(stop.exit_code)
    echo(f"wrote {counted(done, 'pair')} to {out} (labels: {labels})")


def _remove_earlier_pairs(out: str, names: list[str], sequence: bool, overwrite: bool) -> None:
    """Remove the pairs an earlier render listed in ``out`` that this one does not
    render again (a smaller set, another sequence), and its frames.csv when this one
    writes none: none is left beside the new labels.csv."""
    from ..core.io import remove_earlier_outputs
    from ..sources.labelled import listed_files

    suffixes = ("_color.png", "_depth.png")
    again = set(names)
    earlier = [
        n for n in listed_files(out)
        if not (n.endswith(suffixes) and Path(n).name[: -len("_color.png")] in again)
        and n not in ("labels.csv", "frames.csv" if sequence else "")
    ]
    remove_earlier_outputs(out, earlier, overwrite=overwrite)


def _check_cycles(conditions: tuple[str, ...], sequence: str | None, gripper: bool) -> None:
    """Refuse what --engine cycles does not render, then find Blender (bpy) before the
    work: one line and exit 2 naming the extra to install when it is missing."""
    from ..core.errors import InvalidInputError

    for given, what in ((conditions, "--conditions"), (sequence, "--sequence"),
                        (gripper, "--gripper")):
        if given:
            raise InvalidInputError(
                f"{what} is not rendered by --engine cycles (its lights, materials and "
                "camera pipeline are its capture conditions); leave it out or use "
                "--engine raster"
            )
    from ..sim.cycles_scene import check_bpy

    check_bpy()


def _render_case(task: tuple[tuple[str, int], int, dict[str, Any]]) -> Any:
    """One pair of a set: ``((class, number), seed, options)`` (a worker's task)."""
    (class_id, k), seed, options = task
    if options.get("engine") == "cycles":
        from ..sim.photoreal import render_photo_sample

        cycles = {key: v for key, v in options.items() if key != "engine"}
        return render_photo_sample(class_id, k, seed, **cycles)
    from ..sim.dataset import render_sample

    return render_sample(class_id, k, seed, **options)
