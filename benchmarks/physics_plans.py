"""Plans carried out on physics cloth: the success table of `dgli plan --check --physics`.

Usage: python benchmarks/physics_plans.py [--seed S] [--grid N] [--arc-ratio K]
       [--carry-speed M_S] [--drag MM] [--place-offset MM] [--only KIND|GOAL...]
       [--small] [--json OUT.json] [--figure OUT.png]

Every trial of :data:`dgli_vision.planning.physics_check.PHYSICS_TRIALS` (the one-step
plans from 01 and 02: every corner, strip, half and diagonal fold from flat, the folds
from 02 towards 04 and 06; the unfolds 02 -> 01, 04 -> 02, 11 -> 01; a plan from a
corner fold left 20 mm short), each on MuJoCo flex cloth: rendered, classified,
planned, the plan's first step executed by simulated grippers following each hand's
path, settled, rendered, classified and verified. Prints the table (Markdown) and, with
--json, writes every row. The motion's parameters are options so that the choices of
docs/planning.md can be measured again.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main(argv: list[str] | None = None) -> int:
    from dgli_vision.camera import Intrinsics
    from dgli_vision.classifier.references import load_references
    from dgli_vision.planning.motion import MotionParams
    from dgli_vision.planning.physics_check import (
        PHYSICS_TRIALS,
        PhysicsSetup,
        physics_table,
        run_physics_trial,
    )
    from dgli_vision.sim.physics.model import ClothMaterial

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seed", type=int, default=5252)
    ap.add_argument("--grid", type=int, default=21)
    ap.add_argument("--arc-ratio", type=float, default=MotionParams.arc_ratio)
    ap.add_argument("--carry-speed", type=float, default=MotionParams.carry_speed_m_s)
    ap.add_argument("--drag", type=float, default=0.0, help="mm")
    ap.add_argument("--place-offset", type=float, default=0.0, help="mm")
    ap.add_argument("--only", nargs="*", default=None,
                    help="kinds (one step, unfold, short) or goal classes (11, 12...)")
    ap.add_argument("--small", action="store_true", help="640 x 360 renders")
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument("--figure", type=Path, default=None,
                    help="only draw the half fold 01 -> 11/CD and the diagonal fold "
                         "01 -> 12/C before and after (docs/physics_folds.png)")
    args = ap.parse_args(argv)
    motion = MotionParams(arc_ratio=args.arc_ratio, carry_speed_m_s=args.carry_speed,
                          drag_m=args.drag * 1e-3, place_offset_m=args.place_offset * 1e-3)
    setup = PhysicsSetup(material=ClothMaterial(grid=args.grid), motion=motion)
    if args.small:
        from dataclasses import replace

        setup = replace(setup, intrinsics=Intrinsics(640, 360, 302.5, 302.5, 319.5, 179.5))
    refs = load_references(None)
    if args.figure:
        from dataclasses import replace

        return figure(args.figure, replace(setup, keep_images=True), refs, args.seed)
    rows = []
    t0 = time.perf_counter()
    for k, (start, goal, kind) in enumerate(PHYSICS_TRIALS):
        if args.only and kind not in args.only and goal[0] not in args.only:
            continue
        row = run_physics_trial(start, goal, kind, (args.seed, k), refs, setup=setup)
        rows.append(row)
        m = row.made
        print(f"{start[0]}{'/' + start[1] if start[1] else ''} -> {goal[0]}/{goal[1]} "
              f"[{kind}]: {row.outcome} (after {row.after}, verify {row.verified}) "
              f"drag {m.get('base_drag_mm')} landing {m.get('landing_mm')} "
              f"crease {m.get('crease_mm')} mm {row.note[:90]}", file=sys.stderr, flush=True)
    table = physics_table(rows)
    table["seconds"] = round(time.perf_counter() - t0, 1)
    table["setup"] = {"grid": args.grid, "arc_ratio": args.arc_ratio,
                      "carry_speed_m_s": args.carry_speed, "drag_mm": args.drag,
                      "place_offset_mm": args.place_offset, "seed": args.seed,
                      "small": args.small}
    print(markdown(table))
    if args.json:
        args.json.write_text(json.dumps(table, indent=1) + "\n")
    return 0


def figure(out: Path, setup, refs, seed: int) -> int:
    """Before and after images of a half and a diagonal fold on physics cloth, each
    after image captioned with the verdict read from it."""
    import cv2
    import numpy as np

    from dgli_vision.planning.physics_check import PHYSICS_TRIALS, run_physics_trial

    tiles = []
    for k, (start, goal, kind) in enumerate(PHYSICS_TRIALS):
        if goal not in (("11", "CD"), ("12", "C")) or kind != "one step":
            continue
        row = run_physics_trial(start, goal, kind, (seed, k), refs, setup=setup)
        before, after = (cv2.cvtColor(im, cv2.COLOR_RGB2BGR)[::2, ::2].copy()
                         for im in row.images)
        got = "/".join(v for v in (row.after or ("cannot tell",)) if v)
        for img, text in ((before, f"before: {start[0]}, plan {goal[0]}/{goal[1]}"),
                          (after, f"after (MuJoCo cloth): read as {got}")):
            cv2.putText(img, text, (12, 30), cv2.FONT_HERSHEY_SIMPLEX, 0.8, (0, 0, 0), 4,
                        cv2.LINE_AA)
            cv2.putText(img, text, (12, 30), cv2.FONT_HERSHEY_SIMPLEX, 0.8,
                        (255, 255, 255), 2, cv2.LINE_AA)
        tiles.append(np.concatenate([before, after], axis=1))
    cv2.imwrite(str(out), np.concatenate(tiles, axis=0))
    return 0


def markdown(table: dict) -> str:
    """The table as Markdown: one line per trial, then the totals."""
    out = ["| start | goal | kind | read as | after | outcome | verify | hands | base drag "
           "| landing (mm) | crease (mm) |", "|---" * 11 + "|"]
    for r in table["rows"]:
        out.append(f"| {r['start']} | {r['goal']} | {r['kind']} | {r['seen']} | "
                   f"{r['after']} | {r['outcome']} | {r['verified']} | {r.get('hands', '-')} "
                   f"| {r.get('base_drag_mm', '-')} | {r.get('landing_mm', '-')} | "
                   f"{r.get('crease_mm', '-')} |")
    out.append("")
    out.append(f"right {table['right']} of {table['trials']}; one-step plans "
               f"{table['one_step_success']}; by kind {table['by_kind']}")
    out.append(f"one-step folds, mm (median / p90 / max): crease {table['crease_mm']}, "
               f"tip {table['tip_mm']}, base drag {table['base_drag_mm']}; "
               f"{table['seconds']} s")
    return "\n".join(out)


if __name__ == "__main__":
    raise SystemExit(main())
