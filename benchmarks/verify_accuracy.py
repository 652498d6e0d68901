"""How often `dgli verify` is right: before/after renders of planned folds, some made
badly on purpose (the figures of docs/folds.md).

Usage: python benchmarks/verify_accuracy.py [--trials N] [--seed S] [--small]
       [--tolerance MM] [--tasks corner,strip,second] [--modes ...] [--json OUT.json]

Each trial, as `dgli plan --check` does: a start state (the flat napkin, or a corner
folded) is drawn (wrinkles, placement) and rendered from a random camera under random
light with sensor noise; it is classified and a fold planned (``--tasks``, in turn: a
corner, a strip, or a second corner by default; ``half`` and ``diagonal`` fold the flat
napkin in half over a mid-line or a diagonal, whose crease only the napkin's outline
fixes); the planned fold line is taken to the cloth (through the true camera)
and carried out in the simulator, either

- as planned (what perception placed it as: its own error included),
- **short**: a corner's tip lands 40 mm short of its target (the crease moved 20 mm
  towards it), a half or diagonal fold's crease lies 30 mm nearer the flap, a strip's
  crease lies 40 mm nearer its side (its inset 40 mm short;
  moved 20 mm, the inset would be off by the tolerance itself, and its truth a matter
  of tenths of a mm), or
- **skewed**: the crease turned 15 degrees about its middle, or
- **long** (``--modes``): a half or diagonal fold's crease moved 30 mm away from the
  flap (the flap overhangs the napkin beneath, whose stickers stay hidden);

the cloth is rendered again from the same camera and `verify_fold` judges it against the
plan's step (the expected state and the planned crease). The truth is the same rule
applied to the fold made (the simulator's crease, exact): success when the crease and
the legs, tip or inset are all within the tolerance of the plan's. A verdict is right
when it says success for a fold that succeeded, failed for one that did not; "cannot
tell" is counted apart. The goal: at least 98% of the verdicts right, and no success
claimed for a fold that failed.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

from dgli_vision.classifier.pipeline import classify_frame
from dgli_vision.classifier.references import load_references
from dgli_vision.core.camera import DEFAULT_INTRINSICS, Intrinsics
from dgli_vision.core.classes import CORNERS
from dgli_vision.core.fold_measure import Crease, crease_distance_mm, fold_kind, fold_measures
from dgli_vision.core.layout import default_layout
from dgli_vision.planning.api import plan_frame
from dgli_vision.planning.check import _executed_steps, _frame, _placement
from dgli_vision.planning.plan import PlanRefused
from dgli_vision.planning.verify import verify_fold
from dgli_vision.sim.cloth.states import FoldStep, draw_fold_steps, make_state
from dgli_vision.sim.dataset import random_camera
from dgli_vision.sim.render import Lighting, SensorModel, render

SMALL = Intrinsics(640, 360, 302.5, 302.5, 319.5, 179.5)
#: How a trial's fold is made (the default modes; "long" on request).
MODES = ("as planned", "short", "skewed")
ALL_MODES = (*MODES, "long")
#: The tasks a trial plans, in turn (the default ones; "half" and "diagonal" on request).
TASKS = ("corner", "strip", "second")
ALL_TASKS = (*TASKS, "half", "diagonal")


def truth_success(word: str, made: Crease, planned: Crease, layout, tol: float) -> bool:
    """The fold made against the plan, exactly: crease, legs, tip or inset within
    ``tol`` (``dgli verify``'s rule, without uncertainty)."""
    d = crease_distance_mm(made, planned, layout)
    if d is None or d > tol:
        return False
    got, want = fold_measures(word, made, layout), fold_measures(word, planned, layout)
    kind, _ = fold_kind(word)
    if kind == "corner":
        legs = [abs(got["legs_mm"][e] - w) for e, w in want["legs_mm"].items()
                if w is not None and got["legs_mm"][e] is not None]
        return max(legs, default=0.0) <= tol and math.dist(got["tip_mm"], want["tip_mm"]) <= tol
    if kind == "side":
        return abs(got["inset_mm"] - want["inset_mm"]) <= tol
    return abs(got["offset_mm"] - want["offset_mm"]) <= tol


def _botched(step: FoldStep, mode: str, shift_mm: float = 20.0) -> FoldStep:
    """The fold step made ``mode``: ``shift_mm`` nearer the flap, or turned 15 degrees."""
    p0, p1, flap = (np.asarray(x, dtype=float) for x in (step.p0, step.p1, step.flap))
    if mode == "as planned":
        return step
    mid, half = 0.5 * (p0 + p1), 0.5 * (p1 - p0)
    if mode in ("short", "long"):
        t = half / np.linalg.norm(half)
        n = np.array([-t[1], t[0]])
        n = n if (flap - mid) @ n > 0 else -n
        n = n if mode == "short" else -n
        return FoldStep(tuple(p0 + shift_mm * n), tuple(p1 + shift_mm * n), step.flap,
                        step.under)
    c, s = math.cos(math.radians(15.0)), math.sin(math.radians(15.0))
    turned = np.array([c * half[0] - s * half[1], s * half[0] + c * half[1]])
    return FoldStep(tuple(mid - turned), tuple(mid + turned), step.flap, step.under)


def _task(task: str, rng: np.random.Generator) -> tuple[tuple, tuple]:
    """A trial's start and goal: a corner, a strip, a second corner, a half fold or a
    diagonal fold (its side or corner drawn from ``rng``)."""
    i = int(rng.integers(4))
    if task == "corner":
        return ("01", None), ("02", CORNERS[i])
    if task == "strip":
        return ("01", None), ("09", CORNERS[i] + CORNERS[(i + 1) % 4])
    if task == "half":
        return ("01", None), ("11", CORNERS[i] + CORNERS[(i + 1) % 4])
    if task == "diagonal":
        return ("01", None), ("12", CORNERS[i])
    a, b = CORNERS[i], CORNERS[(i + 2) % 4]
    return ("02", a), ("06", "".join(sorted(a + b)))


def trial(
    k: int,
    seed: int,
    refs,
    intrinsics: Intrinsics,
    tol: float,
    tasks: tuple[str, ...] = TASKS,
    modes: tuple[str, ...] = MODES,
) -> dict[str, Any]:
    """One before/after pair (see the module's description)."""
    layout = default_layout()
    rng = np.random.default_rng([seed, k, 59])
    if tasks == TASKS:
        # (the default tasks draw as they always did: k % 3, then the side or corner)
        start, goal = _task(TASKS[k % 3], rng)
    else:
        start, goal = _task(tasks[k % len(tasks)], rng)
    mode = modes[(k // len(tasks)) % len(modes)]  # every task made every way, in turn
    steps, params = draw_fold_steps(start[0], start[1], layout, rng)
    words = list(params["folds"])
    wrinkle, yaw, offset = _placement(rng)
    wseed = int(rng.integers(2**31))

    def state(key, folds):
        return make_state(key[0], key[1], folds, layout=layout, wrinkle_mm=wrinkle, yaw=yaw,
                          offset_m=offset, rng=wseed, params=dict(params))

    pose, _ = random_camera(state(("01", None), []), rng, intrinsics=intrinsics)
    light = Lighting.random(rng)
    before = render(state(start, steps), pose, intrinsics=intrinsics, lighting=light,
                    sensor=SensorModel(), rng=rng, layout=layout)
    row: dict[str, Any] = {"trial": k, "start": start, "goal": goal, "mode": mode}
    result = classify_frame(_frame(before), refs, layout=layout)
    try:
        plan = plan_frame(result, _frame(before), goal, layout)
    except PlanRefused as exc:
        return {**row, "outcome": "no plan", "note": str(exc)}
    step = plan.steps[0]
    if step.action != "fold" or step.crease_mm is None:
        return {**row, "outcome": "no plan", "note": f"first step {step.action} {step.fold}"}
    done = _executed_steps(step, steps, words, pose, yaw, offset, layout)
    kind = fold_kind(step.fold)[0]
    half_or_diagonal = kind == "diagonal" or step.fold.endswith(" half")
    shift = 30.0 if half_or_diagonal else 40.0 if kind == "side" else 20.0
    made_step = _botched(done[-1], mode, shift)
    made = Crease.through(made_step.p0, made_step.p1)
    planned = Crease.through(*step.crease_mm)
    truth = truth_success(step.fold, made, planned, layout, tol)
    after = render(state(step.expect, [*done[:-1], made_step]), pose, intrinsics=intrinsics,
                   lighting=light, sensor=SensorModel(), rng=rng, layout=layout)
    verdict = classify_frame(_frame(after), refs, layout=layout)
    check = verify_fold(verdict, step.expect, layout, fold=step.fold, crease=planned,
                        tolerance_mm=tol)
    return {**row, "fold": step.fold, "truth": truth, "success": check.success,
            "outcome": check.outcome, "line": check.line(),
            "made_crease_mm": crease_distance_mm(made, planned, layout)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--trials", type=int, default=60)
    ap.add_argument("--seed", type=int, default=7070)
    ap.add_argument("--small", action="store_true", help="640 x 360 renders")
    ap.add_argument("--tolerance", type=float, default=20.0)
    ap.add_argument("--tasks", default=",".join(TASKS),
                    help=f"comma-separated, in turn: {', '.join(ALL_TASKS)}")
    ap.add_argument("--modes", default=",".join(MODES),
                    help=f"comma-separated, in turn: {', '.join(ALL_MODES)}")
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    tasks = tuple(t.strip() for t in args.tasks.split(","))
    modes = tuple(m.strip() for m in args.modes.split(","))
    bad = [x for x in tasks if x not in ALL_TASKS] + [x for x in modes if x not in ALL_MODES]
    if bad:
        ap.error(f"unknown task or mode: {', '.join(bad)}")
    refs = load_references(None)
    intr = SMALL if args.small else DEFAULT_INTRINSICS
    rows = []
    t0 = time.perf_counter()
    for k in range(args.trials):
        r = trial(k, args.seed, refs, intr, args.tolerance, tasks, modes)
        rows.append(r)
        print(json.dumps(r, default=str), flush=True)
    judged = [r for r in rows if r.get("success") is not None]
    right = [r for r in judged if r["success"] == r["truth"]]
    false_ok = [r for r in judged if r["success"] and not r["truth"]]
    by_mode: dict[str, Counter] = {}
    for r in rows:
        c = by_mode.setdefault(r["mode"], Counter())
        c["trials"] += 1
        c[r["outcome"]] += 1
        if "truth" in r:
            c["truth success" if r["truth"] else "truth failed"] += 1
        if r.get("success") is not None:
            c["right"] += r["success"] == r["truth"]
    summary = {
        "trials": len(rows),
        "verdicts": len(judged),
        "right": len(right),
        "right_share": round(len(right) / len(judged), 4) if judged else None,
        "success_claimed_for_failed": len(false_ok),
        "cannot_tell": sum(r["outcome"] == "cannot tell" for r in rows),
        "no_plan": sum(r["outcome"] == "no plan" for r in rows),
        "by_mode": {m: dict(c) for m, c in by_mode.items()},
        "tolerance_mm": args.tolerance,
        "seconds": round(time.perf_counter() - t0, 1),
        "resolution": f"{intr.width} x {intr.height}",
    }
    print(json.dumps(summary, indent=1))
    if args.json:
        args.json.write_text(json.dumps({"summary": summary, "rows": rows}, indent=1,
                                        default=str))


if __name__ == "__main__":
    main()
