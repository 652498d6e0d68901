"""``dgli simulate``: a simulated database of cloth states."""

from __future__ import annotations

from typing import Any

import click

from ..core.words import counted
from .errors import handle_errors
from .options import make_jobs_option, overwrite_option, per_class_option, size_option
from .output import command_line, echo, napkin_provenance, package_version, progress

#: The most cloth ``dgli simulate`` holds, counted in states of the nominal 400 mm napkin
#: (a state of a larger napkin counts by its area): about 3 GB.
MAX_SIMULATED_CLOTH = 10_000


def _check_simulation_size(per_class: int, in_progress: int, layout: Any) -> None:
    """Refuse, before the work, a database that would not fit in memory."""
    from ..core.classes import CLASS_IDS
    from ..core.fold_graph import fold_edges
    from ..sim.database import FOLD_BINS_DEG

    folds = sum("under" not in fold for *_, fold in fold_edges())
    n_states = per_class * len(CLASS_IDS) + in_progress * folds * len(FOLD_BINS_DEG)
    area = layout.width_mm * layout.height_mm / 400.0**2
    if n_states * area > MAX_SIMULATED_CLOTH:
        raise click.BadParameter(
            f"{n_states} states of a {layout.width_mm:g} x {layout.height_mm:g} mm napkin "
            f"hold as much cloth as {n_states * area:.0f} of the 400 mm one; at most "
            f"{MAX_SIMULATED_CLOTH} fit in memory: lower --per-class or --in-progress",
            param_hint="'--per-class'",
        )


@click.command()
@click.argument("out", type=click.Path(file_okay=False))
@per_class_option(20, 200, "States per class")
@click.option("--seed", default=0, show_default=True, type=int, help="Seed of the database.")
@click.option("--no-wrinkles", is_flag=True, help="Fold cleanly, without wrinkles.")
@click.option(
    "--in-progress",
    default=3,
    show_default=True,
    type=click.IntRange(0, 20),
    help="States with a fold in progress, per fold and angle bin (0: none; at most 20).",
)
@click.option(
    "--episodes",
    is_flag=True,
    help="Write the folding sequences I, II and III as cloth episodes that 'dgli label' "
    "reads (OUT/sequence_I.npz..., each frame's true state in OUT/truth.json) instead of "
    "the database.",
)
@click.option(
    "--frames",
    default=24,
    show_default=True,
    type=click.IntRange(2, 1000),
    help="--episodes: frames per sequence, spread evenly over its folds.",
)
@size_option
@make_jobs_option
@overwrite_option
@handle_errors
def simulate(
    out: str,
    per_class: int,
    seed: int,
    no_wrinkles: bool,
    in_progress: int,
    episodes: bool,
    frames: int,
    size_mm: tuple[float, float] | None,
    jobs: int,
    overwrite: bool,
) -> None:
    """Write a simulated database of cloth states to OUT (meshes, truth, index).

    Besides PER-CLASS states of every class with its folds laid flat, the database holds
    states with one fold in progress (every fold a robot can make, turned 10-170
    degrees), labelled by the 90-degree rule; `dgli compare` leaves them out. -j spreads
    the classes over processes (the same database as one).

    With --episodes, OUT gets instead the folding sequences I, II and III as episodes of
    another simulator's cloth (NPZ: the particle grid's positions per frame, metres, z
    up), which `dgli label OUT/*.npz` labels, and truth.json, each frame's true state.
    """

    from ..core.layout import layout_of_size
    from ..core.parallel import ordered_map
    from ..sim.cloth.states import CLASS_IDS
    from ..sim.database_files import write_database

    layout = layout_of_size(size_mm)
    if episodes:
        _write_episodes(out, frames, seed, layout, overwrite)
        return
    ctx = click.get_current_context()
    if ctx.get_parameter_source("frames") == click.core.ParameterSource.COMMANDLINE:
        raise click.UsageError("--frames is for --episodes")
    _check_simulation_size(per_class, in_progress, layout)
    kw = {"wrinkles": not no_wrinkles, "layout": layout}
    tasks = [(per_class, seed, c, kw) for c in CLASS_IDS]
    if in_progress:
        tasks.append((in_progress, seed, None, kw))  # the folds in progress, last
    states = []
    with progress(tasks, "simulating") as bar:
        for part, _ in zip(ordered_map(_simulate_part, tasks, jobs=jobs),
                           bar):
            states += part
    provenance = {
        "command": command_line(),
        "seed": seed,
        "per_class": per_class,
        "in_progress": in_progress,
        "wrinkles": not no_wrinkles,
        **napkin_provenance(layout),
        "package_version": package_version(),
    }
    index = write_database(out, states, provenance, overwrite=overwrite)
    echo(f"wrote {counted(len(states), 'state')} to {index}")


def _simulate_part(task: tuple[int, int, str | None, dict[str, Any]]) -> list:
    """The states of one class, or (class None) those with a fold in progress: a
    worker's task ``(count, seed, class, options)``."""
    from ..sim.database import simulate_folds_in_progress, simulate_states

    count, seed, class_id, kw = task
    if class_id is None:
        return simulate_folds_in_progress(count, seed, **kw)
    return simulate_states(count, seed, classes=(class_id,), **kw)


#: The folding sequences ``--episodes`` writes.
EPISODE_SEQUENCES = ("I", "II", "III")


def _write_episodes(out: str, frames: int, seed: int, layout: Any, overwrite: bool) -> None:
    """``--episodes``: the folding sequences as NPZ episodes, and their truth."""
    from pathlib import Path

    import numpy as np

    from ..core.io import write_outputs
    from ..labelling.export import npz_bytes, sequence_episode

    ctx = click.get_current_context()
    given = [f"--{n.replace('_', '-')}" for n in ("per_class", "in_progress", "no_wrinkles")
             if ctx.get_parameter_source(n) == click.core.ParameterSource.COMMANDLINE]
    if given:
        raise click.UsageError(f"--episodes writes sequences, not a database: drop "
                               f"{' and '.join(given)}")
    root = Path(out)
    files: dict[Path, Any] = {}
    truth: dict[str, Any] = {}
    for k, name in enumerate(EPISODE_SEQUENCES):
        ep = sequence_episode(name, frames, np.random.default_rng([seed, k]), layout)
        files[root / f"sequence_{name}.npz"] = npz_bytes(ep.positions, ep.grid)
        truth[f"sequence_{name}.npz"] = ep.truth
    files[root / "truth.json"] = {
        "format": "dgli-episode-truth", "version": 1, "command": command_line(),
        "seed": seed, "frames": frames, **napkin_provenance(layout),
        "package_version": package_version(), "episodes": truth,
    }
    write_outputs(files, overwrite=overwrite, command=command_line())
    echo(f"wrote {counted(len(EPISODE_SEQUENCES), 'episode')} of {frames} frames to {root} "
         f"(dgli label {root}/*.npz -o {root}/labels)")
