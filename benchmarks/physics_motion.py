"""Which motion works on physics cloth: the half fold and the diagonal fold of a flat
napkin on MuJoCo flex cloth, for several carry arcs, hands and speeds (the choices of
docs/planning.md).

Usage: python benchmarks/physics_motion.py [--grid N] [--only NAME...]

Each variant folds the napkin lying flat in the sim frame (no camera, no perception:
the motion alone) and measures, once settled, how far the napkin that stays was dragged
(the median displacement of its vertices more than 30 mm inside the fold line, mm) and
how far each grasped corner lies from where the fold should lay it (mm, in the dragged
napkin's own frame). Variants: ``arc K`` (the default path with ``arc_ratio`` K),
``ellipse`` (the motion before: a half-ellipse over grasp -> place peaking at the
grasp's distance from the line plus 20 mm), ``one hand`` (a side grasped at its middle
only), ``fast`` (carry at 0.4 m/s).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def _ellipse(hand, g, p, r):
    """The old path: a half-ellipse from grasp to place peaking at r + 20 mm."""
    from dataclasses import replace

    mid, a = 0.5 * (g + p), 0.5 * (g - p)
    out = []
    arc = [w for w in hand.path if w.phase in ("lift", "carry", "lower")]
    n = len(arc)
    for k, w in enumerate(arc, start=1):
        th = np.pi * k / n
        q = mid + np.cos(th) * a + np.array([0, 0, np.sin(th) * (r + 0.02)])
        out.append(replace(w, point=tuple(q)))
    rest = [w for w in hand.path if w.phase not in ("lift", "carry", "lower")]
    first = [w for w in rest if w.phase in ("approach", "grasp")]
    last = [w for w in rest if w.phase in ("release", "retreat")]
    return replace(hand, path=(*first, *out, *last))


def run(name: str, fold: str, grid: int) -> dict:
    from dgli_vision.core.layout import default_layout
    from dgli_vision.planning.motion import MotionParams, hands_motion
    from dgli_vision.sim.physics.grippers import HandPath, execute
    from dgli_vision.sim.physics.model import ClothMaterial, build_model

    layout = default_layout()
    mat = ClothMaterial(grid=grid)
    rad = mat.radius_m
    up = np.array([0.0, 0.0, 1.0])
    if fold == "half":  # side CD over a mid-line 204 mm in (class 11's middle)
        line_v = 0.4 - 0.204
        line = (np.array([0.0, line_v, rad]), np.array([0.4, line_v, rad]))
        corners = [(0.4, 0.4), (0.0, 0.4)] if name != "one hand" else [(0.2, 0.4)]
        targets = [(x, 2 * line_v - y) for x, y in corners]
        stay = lambda uv: uv[:, 1] < line_v * 1e3 - 30  # noqa: E731
    else:  # corner C over the diagonal BD
        line = (np.array([0.4, 0.0, rad]), np.array([0.0, 0.4, rad]))
        corners, targets = [(0.4, 0.4)], [(0.0, 0.0)]
        stay = lambda uv: uv.sum(axis=1) < 400 - 42  # noqa: E731
    k = float(name.split()[1]) if name.startswith("arc") else 0.9
    speed = 0.4 if name == "fast" else 0.2
    params = MotionParams(arc_ratio=k, carry_speed_m_s=speed)
    grasps = [(f"corner {i}", np.array([*c, rad]), None, np.array([*t, 3 * rad]))
              for i, (c, t) in enumerate(zip(corners, targets))]
    hands = hands_motion(grasps, line, up, params)
    if name == "ellipse":
        hands = tuple(_ellipse(h, g[1], g[3], np.linalg.norm(g[1][:2] - g[3][:2]) / 2)
                      for h, g in zip(hands, grasps))
    paths = [HandPath(np.array([w.t for w in h.path]), np.array([w.point for w in h.path]),
                      np.array([w.gripper == "closed" for w in h.path])) for h in hands]
    flat = build_model(layout, material=mat)
    verts = tuple(int(np.argmin(np.linalg.norm(flat.positions() - g[1], axis=1)))
                  for g in grasps)
    cm = build_model(layout, material=mat, hand_vertices=verts)
    t0 = time.perf_counter()
    ex = execute(cm, paths, settle_s=1.0)
    keep = stay(cm.uv) & (ex.xyz[:, 2] < 2.5 * rad)
    before, after = flat.positions()[keep, :2], ex.xyz[keep, :2]
    drag = float(np.median(np.linalg.norm(after - before, axis=1))) * 1e3
    shift = np.median(after - before, axis=0)
    land = [float(np.linalg.norm(ex.xyz[v, :2] - shift - t)) * 1e3
            for v, t in zip(verts, targets)]
    return {"fold": fold, "variant": name, "base_drag_mm": round(drag, 1),
            "landing_mm": [round(x, 1) for x in land], "seconds": round(time.perf_counter() - t0)}


VARIANTS = [("half", "arc 1.1"), ("half", "arc 1.0"), ("half", "arc 0.9"), ("half", "arc 0.8"),
            ("half", "ellipse"), ("half", "one hand"), ("half", "fast"),
            ("diagonal", "arc 1.0"), ("diagonal", "arc 0.9"), ("diagonal", "arc 0.8"),
            ("diagonal", "ellipse")]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--grid", type=int, default=21)
    ap.add_argument("--only", nargs="*", default=None)
    args = ap.parse_args(argv)
    print("| fold | variant | base dragged (mm) | corners from their place (mm) |")
    print("|---|---|---|---|")
    for fold, name in VARIANTS:
        if args.only and name not in args.only and fold not in args.only:
            continue
        r = run(name, fold, args.grid)
        print(f"| {fold} | {name} | {r['base_drag_mm']} | {r['landing_mm']} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
