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
    size_mm: tuple[float, float] | None,
    jobs: int,
    overwrite: bool,
) -> None:
    """Write a simulated database of cloth states to OUT (meshes, truth, index).

    Besides PER-CLASS states of every class with its folds laid flat, the database holds
    states with one fold in progress (every fold a robot can make, turned 10-170
    degrees), labelled by the 90-degree rule; `dgli compare` leaves them out. -j spreads
    the classes over processes (the same database as one).
    """

    from ..core.layout import layout_of_size
    from ..core.parallel import ordered_map
    from ..sim.cloth.states import CLASS_IDS
    from ..sim.database_files import write_database

    layout = layout_of_size(size_mm)
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
