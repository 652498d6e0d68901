"""``dgli plan``: the next folds towards a goal state, from an image or a known state,
and ``--check``, the closed loop in the simulator."""

from __future__ import annotations

import json
import sys

import click

from ..core.words import counted
from .errors import handle_errors
from .options import (
    extrinsics_option,
    image_output,
    intrinsics_option,
    json_option,
    mirroring_option,
    overwrite_option,
    references_option,
)
from .output import echo, echo_json, progress_bar


def _state(ctx: click.Context, param: click.Parameter, value: str | None):
    from ..planning.plan import parse_state

    if value is None:
        return None
    try:
        return parse_state(value, need_variant=param.name != "goal")
    except ValueError as exc:
        raise click.BadParameter(str(exc)) from None


def _plan_line(plan, extrinsics=None) -> str:
    """The plan in words; the next step's points in the frame of ``extrinsics`` (an
    :class:`~dgli_vision.core.extrinsics.Extrinsics`, None: the camera's)."""

    def name(k) -> str:
        return f"{k[0]}/{k[1]}" if k[1] else k[0]

    if not plan.steps:
        return f"already in {name(plan.goal)}"
    words = [f"{s.action} {s.fold} -> {name(s.expect)}" for s in plan.steps]
    steps = counted(len(plan.steps), "step")
    text = f"{name(plan.start)} to {name(plan.goal)} in {steps}: " + "; ".join(words)
    first = plan.steps[0]
    if first.grasp_point is not None:
        grasp, place = first.grasp_point, first.place_point
        where = ""
        if extrinsics is not None:
            grasp, place = extrinsics.points([grasp, place])
            where = f" ({extrinsics.frame} frame)"
        g = ", ".join(f"{v:.3f}" for v in grasp)
        p = ", ".join(f"{v:.3f}" for v in place)
        text += (f"\nnext: grasp at ({g}) m, place at ({p}) m, lift {first.lift_height:.3f} m"
                 + where)
    return text


def plan_json(plan, extrinsics=None, up=None) -> dict:
    """``dgli plan --json``'s object: the plan's, with the table's normal ``up`` (the
    direction a grasped corner is lifted along) for a plan made from an image, every 3D
    point in the frame of ``extrinsics`` (None: the camera's), with ``"frame"`` naming
    it."""
    from ..core.extrinsics import in_frame

    data = plan.to_json()
    if up is not None:
        data["up"] = [round(float(v), 6) for v in up]
    return in_frame(data, extrinsics)


def _check(per_pair: int, seed: int, as_json: bool, refs, limit: int | None) -> None:
    from ..planning.check import check_count, check_pairs, check_table

    count = check_count(per_pair=per_pair, limit=limit)
    with progress_bar(count, counted(count, "trial"), quiet=as_json) as bar:
        rows = list(check_pairs(refs, per_pair=per_pair, seed=seed, limit=limit,
                                on_row=lambda _row: bar.update(1)))
    table = check_table(rows)
    if as_json:
        echo_json(table)
        return
    echo(f"{counted(table['pairs'], 'trial')}, success {table['success']:.3f}")
    echo("| steps to goal | right | cannot tell | refused | wrong |")
    echo("|---|---|---|---|---|")
    for n, c in table["by_steps"].items():
        echo(f"| {n} | {c['right']} | {c['cannot tell']} | {c['refused']} | {c['wrong']} |")
    o = table["outcomes"]
    echo(f"| all | {o['right']} | {o['cannot tell']} | {o['refused']} | {o['wrong']} |")
    for r in table["not_right"]:
        echo(
            f"{r['outcome']}: {r['start']} -> {r['goal']} (seen {r['seen']}, expected "
            f"{r['expect']}, got {r['after']}) {r['note']}".rstrip()
        )
    _geometry_lines(table["geometry"])


def _check_physics(seed: int, as_json: bool, refs, every: int | None) -> None:
    """``--check --physics``: the trials of the physics closed loop and their table."""
    from ..planning.physics_check import PHYSICS_TRIALS, physics_table, run_physics_trial

    trials = [t for k, t in enumerate(PHYSICS_TRIALS) if every is None or k % every == 0]
    rows = []
    with progress_bar(len(trials), counted(len(trials), "physics trial"),
                      quiet=as_json) as bar:
        for k, (start, goal, kind) in enumerate(trials):
            rows.append(run_physics_trial(start, goal, kind, (seed, k, 52), refs))
            bar.update(1)
    table = physics_table(rows)
    if as_json:
        echo_json(table)
        return
    echo(f"{counted(table['trials'], 'physics trial')}, {table['right']} right; "
         f"one-step plans {table['one_step_success']:.3f}")
    echo("| start | goal | kind | after | outcome | verify | hands | base drag | "
         "landing | crease |")
    echo("|---" * 10 + "|")
    for r in table["rows"]:
        echo(f"| {r['start']} | {r['goal']} | {r['kind']} | {r['after']} | {r['outcome']} "
             f"| {r['verified']} | {r.get('hands', '-')} | {r.get('base_drag_mm', '-')} "
             f"| {r.get('landing_mm', '-')} | {r.get('crease_mm', '-')} |")
    echo(f"one-step folds (mm, median / p90 / max): crease {_mm3(table['crease_mm'])}, "
         f"tip {_mm3(table['tip_mm'])}, base drag {_mm3(table['base_drag_mm'])}")


def _mm3(s: dict) -> str:
    return "-" if s["median"] is None else f"{s['median']:g} / {s['p90']:g} / {s['max']:g}"


def _geometry_lines(g: dict) -> None:
    """The fold steps' crease and tip errors against the plan, and success rates."""
    n = g["fold_steps"]
    if not n:
        return
    tols = list(g["made"]["success"])

    def mm(s: dict) -> str:
        if s["median"] is None:
            return "-"
        return f"{s['median']:g} / {s['p90']:g} / {s['max']:g}"

    click.echo(f"\nfold steps against the plan ({n}; errors in mm, median / p90 / max):")
    click.echo("| crease | measured | crease error | tip error | "
               + " | ".join(f"success at {t} mm" for t in tols) + " |")
    click.echo("|---" * (4 + len(tols)) + "|")
    for which, what in (("made", "made (simulator)"), ("seen", "seen (after frame)")):
        s = g[which]
        rates = " | ".join(f"{s['success'][t]:.1%}" for t in tols)
        click.echo(f"| {what} | {s['measured']} | {mm(s['crease_mm'])} | {mm(s['tip_mm'])} "
                   f"| {rates} |")
    click.echo(f"crease seen vs made (the measurement's error): {mm(g['measure_mm'])} mm")
    for why, count in g["not_seen"].items():
        click.echo(f"not seen ({count}): {why}")


@click.command("plan")
@click.argument("color", type=click.Path(), required=False)
@click.argument("depth", type=click.Path(), required=False)
@click.option(
    "--goal", callback=_state,
    help="The goal state: 08, 02/A, 05/AB/B (a class also as 8 or four-corners-centre).",
)
@click.option(
    "--from", "start", callback=_state, help="Plan from this state, without an image."
)
@click.option("--check", is_flag=True, help="Run the closed-loop check in the simulator.")
@click.option("--physics", is_flag=True,
              help="--check on MuJoCo flex cloth: each plan's path executed by simulated "
                   "grippers (the 'physics' extra).")
@click.option("--per-pair", type=click.IntRange(1, 20), default=1, show_default=True,
              help="--check: trials per (start, goal) pair.")
@click.option("--seed", type=int, default=0, show_default=True, help="--check: the seed.")
@click.option("--every", type=click.IntRange(1, None), default=None,
              help="--check: only every N-th (start, goal) pair (with --physics, trial) "
                   "(a quicker check).")
@click.option("--verify", "verify_pair", nargs=2, type=click.Path(),
              help="AFTER_COLOR AFTER_DEPTH: the frame after the plan's first step; check "
                   "it made the expected state and the planned crease (dgli verify).")
@click.option("--tolerance", type=click.FloatRange(0, 1000, min_open=True), default=20.0,
              show_default=True, help="--verify: how far (mm) the planned sizes may be missed.")
@intrinsics_option
@references_option
@extrinsics_option
@mirroring_option
@json_option("Print the plan (or the check's table) as one JSON object.")
@click.option("--overlay", type=click.Path(dir_okay=False), callback=image_output,
              help="Draw the next step (grasp, place, fold line) on the image.")
@overwrite_option
@handle_errors
def plan_cmd(
    color: str | None,
    depth: str | None,
    goal,
    start,
    check: bool,
    physics: bool,
    per_pair: int,
    seed: int,
    every: int | None,
    verify_pair: tuple[str, str] | None,
    tolerance: float,
    intrinsics: str | None,
    references_path: str | None,
    extrinsics_path: str | None,
    mirroring: str | None,
    as_json: bool,
    overlay: str | None,
    overwrite: bool,
) -> None:
    """The shortest sequence of folds and unfolds from the state in COLOR DEPTH (or
    --from STATE) to --goal STATE, with the next step as a pick-and-place in the camera
    frame (with --extrinsics, in the robot's base frame). Exit 1 with the reason when
    there is no plan (the state cannot be told, or no sequence of folds leads there).
    """

    from ..classifier.references import load_references
    from ..core.extrinsics import read_extrinsics
    from ..core.layout import layout_of_size
    from ..planning.api import plan_frame
    from ..planning.plan import PlanRefused, plan_geometry

    extrinsics = read_extrinsics(extrinsics_path) if extrinsics_path else None
    if physics and not check:
        raise click.UsageError("--physics goes with --check")
    if check and physics:
        from ..sim.physics import require_mujoco

        require_mujoco()  # before any work: the message names the extra
    refs = load_references(references_path)
    if check and physics:
        _check_physics(seed, as_json, refs, every)
        return
    if check:
        _check(per_pair, seed, as_json, refs, every)
        return
    if goal is None:
        raise click.UsageError("give --goal STATE (or --check)")
    if start is None and (color is None or depth is None):
        raise click.UsageError("give COLOR and DEPTH, or --from STATE")
    if verify_pair and not verify_pair[0]:
        verify_pair = None
    if verify_pair and start is not None:
        raise click.UsageError("--verify checks a plan made from an image: give COLOR DEPTH")
    if start is not None and (color is not None or overlay):
        raise click.UsageError("--from plans without an image: give no COLOR, DEPTH or --overlay")
    layout = layout_of_size(refs.napkin_mm)
    up = None  # the table's normal, for a plan made from an image
    try:
        if start is not None:
            plan = plan_geometry(start, goal, layout, None, None, None)
        else:
            from ..classifier.pipeline import classify_frame
            from ..core.io import guard_outputs, write_picture
            from ..sources.frames import read_frame

            if overlay:
                guard_outputs([overlay], overwrite=overwrite)
            frame = read_frame(color, depth, intrinsics)
            result = classify_frame(frame, refs, layout=layout, mirroring=mirroring)
            frame = result.frame_as_read(frame)  # the pixels the plan is placed in
            up = result.observation.up
            try:
                plan = plan_frame(result, frame, goal, layout)
            except PlanRefused as exc:  # the overlay still shows the frame, and why
                if overlay:
                    write_picture(overlay, _overlay(frame, result, None, str(exc)),
                                  overwrite=overwrite)
                raise
            if overlay:
                write_picture(overlay, _overlay(frame, result, plan), overwrite=overwrite)
    except PlanRefused as exc:
        if as_json:
            echo_json({"plan": None, "reason": str(exc)})
        else:
            echo(f"no plan: {exc}" if not str(exc).startswith("no plan") else str(exc))
        sys.exit(1)
    if verify_pair:
        _verify(plan, verify_pair, intrinsics, refs, layout, tolerance, as_json, extrinsics,
                mirroring, up)
        return
    echo(json.dumps(plan_json(plan, extrinsics, up)) if as_json
         else _plan_line(plan, extrinsics))


def _verify(plan, pair, intrinsics, refs, layout, tolerance: float, as_json: bool,
            extrinsics=None, mirroring: str | None = None, up=None) -> None:
    """``--verify``: the frame after the plan's first step against its expected state
    and planned crease; exit 1 unless the step succeeded."""
    from ..classifier.pipeline import classify_frame
    from ..core.extrinsics import in_frame
    from ..core.fold_measure import Crease
    from ..planning.verify import verify_fold
    from ..sources.frames import read_frame
    from .verify import report

    if not plan.steps:
        raise click.UsageError("--verify: the plan has no step (already at the goal)")
    step = plan.steps[0]
    frame = read_frame(pair[0], pair[1], intrinsics)
    result = classify_frame(frame, refs, layout=layout, mirroring=mirroring)
    crease = Crease.through(*step.crease_mm) if step.crease_mm is not None else None
    check = verify_fold(result, step.expect, layout, fold=step.fold if crease else None,
                        crease=crease, tolerance_mm=tolerance)
    if as_json:
        echo_json({"plan": plan_json(plan, extrinsics, up),
                   "verify": in_frame(check.to_json(), extrinsics)})
        if not check.success:
            sys.exit(1)
        return
    echo(_plan_line(plan, extrinsics))
    report(check, False)


def _overlay(frame, result, plan, refused: str | None = None):
    """The classification's overlay with the plan's next step and its legend drawn on it,
    or, with no plan, why (``refused``). The step's marks go under the stickers and the
    verdict (drawn on the colour image first), its legend over everything."""
    from dataclasses import replace

    import cv2

    from ..analysis.overlay import frame_overlay
    from ..planning.overlay import draw_no_plan, draw_step, draw_step_legend

    if plan is None:
        return draw_no_plan(frame_overlay(frame, result, legend=False),
                            (refused or "").removeprefix("no plan: "))
    if not plan.steps:
        return draw_no_plan(frame_overlay(frame, result, legend=False),
                            "already in the goal state")
    s = plan.steps[0]
    what = s.corner or s.side
    e = f"{s.expect[0]}/{s.expect[1]}" if s.expect[1] else s.expect[0]
    of = f" (step 1 of {len(plan.steps)})" if len(plan.steps) > 1 else ""
    marked = draw_step(cv2.cvtColor(frame.color, cv2.COLOR_RGB2BGR), s, frame.intrinsics,
                       legend=False)
    img = frame_overlay(replace(frame, color=cv2.cvtColor(marked, cv2.COLOR_BGR2RGB)), result,
                        legend=False)  # the step's legend goes there
    return draw_step_legend(img, s, frame.intrinsics, f"next: {s.action} {what} -> {e}{of}")


for _param in plan_cmd.params:  # a state is recorded as it is written: 05/AB/B
    if _param.name in ("goal", "start"):
        _param.list_separator = "/"  # type: ignore[attr-defined]
