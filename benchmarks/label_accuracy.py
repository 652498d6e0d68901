"""How right `dgli label` is on the project's own simulator exported as other simulators
write their cloth (the figures of docs/simulation.md).

Usage: python benchmarks/label_accuracy.py [SEED] [--per-variant N] [--frames N]
       [--picture OUT.png]

For a seed: finished states of every class and variant (N of each), one episode per
input format (NPZ grid, SoftGym's (T, N, 4), NPZ remeshed, CloSE .mat, OBJ and PLY
folders), each under its own random rigid motion, up axis and unit; and the folding
sequences I, II and III (frames spread evenly, fold sizes drawn) as a grid and
remeshed. Prints the share right by class and by variant, per frame and smoothed, and
the state changes found within 2 frames.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

from dgli_vision.analysis.track import score_timeline
from dgli_vision.core.classes import CLASS_NAMES, VARIANTS
from dgli_vision.core.layout import default_layout
from dgli_vision.labelling.episodes import ReadOptions
from dgli_vision.labelling.export import (
    remesh,
    rigid_motion,
    to_simulator,
    write_mat,
    write_meshes,
    write_npz,
)
from dgli_vision.labelling.label import EpisodeLabels
from dgli_vision.labelling.outputs import timeline_files
from dgli_vision.labelling.run import LabelJob, label_episodes
from dgli_vision.sim.cloth.mesh import flat_mesh
from dgli_vision.sim.cloth.sequences import sequence_progress, sequence_state, sequence_steps
from dgli_vision.sim.cloth.states import sample_state

FORMATS = (  # name, up axis, units, how
    ("grid", "y", "cm", "grid"),
    ("softgym", "y", "m", "softgym"),
    ("remeshed", "-x", "mm", "faces"),
    ("close.mat", "z", "m", "mat"),
    ("obj", "y", "cm", ".obj"),
    ("ply", "z", "mm", ".ply"),
)


def _write(out: Path, name: str, meshes: list, rng: np.random.Generator, fmt: tuple) -> tuple:
    """One episode of ``meshes`` in format ``fmt``; returns (path, ReadOptions)."""
    kind, up, units, how = fmt
    ny, nx = meshes[0].shape
    if how in ("grid", "softgym"):
        pos = np.stack([m.xyz for m in meshes])
    else:
        rm = remesh((400.0, 400.0), 3000, rng)
        pos = rm.positions(meshes)
    sim = to_simulator(rigid_motion(pos, rng), up, units)
    path = out / f"{name}_{kind}"
    if how == "grid":
        write_npz(path.with_suffix(".npz"), sim, grid=(ny, nx))
    elif how == "softgym":
        write_npz(path.with_suffix(".npz"), sim, grid=(ny, nx), softgym=True)
    elif how == "faces":
        write_npz(path.with_suffix(".npz"), sim, faces=rm.faces)
    elif how == "mat":
        write_mat(path.with_suffix(".mat"), sim, rm.border)
    else:
        write_meshes(path, sim, rm.faces, suffix=how)
    path = path.with_suffix(".npz") if how in ("grid", "softgym", "faces") else path
    path = path.with_suffix(".mat") if how == "mat" else path
    return str(path), ReadOptions(up_axis=up, units=units)


def _label(path: str, options: ReadOptions) -> EpisodeLabels:
    (ep,) = label_episodes(LabelJob((path,), options))
    assert isinstance(ep, EpisodeLabels), ep
    return ep


def finished_states(seed: int, per_variant: int, out: Path) -> None:
    rng = np.random.default_rng(seed)
    meshes, truth = [flat_mesh(default_layout())], [("01", None)]
    for c, variants in VARIANTS.items():
        for v in variants:
            for k in range(per_variant):
                state = sample_state(c, v, np.random.default_rng([seed, int(c), len(truth), k]))
                meshes.append(state.mesh)
                truth.append((c, v))
    print(f"finished states, seed {seed}: {len(truth)} frames per format")
    print("| format | up, units | right by class | right by variant | no answer |")
    print("|---|---|---|---|---|")
    totals = np.zeros(3)
    og: dict[str, list] = {}
    for fmt in FORMATS:
        path, options = _write(out, "finished", meshes, rng, fmt)
        ep = _label(path, options)
        for f, t in zip(ep.frames, truth):
            og.setdefault(t[0], []).append(f.omnigibson)
        cls = np.mean([f.class_id == t[0] for f, t in zip(ep.frames, truth)])
        var = np.mean([(f.class_id, f.variant) == t for f, t in zip(ep.frames, truth)])
        none = sum(f.class_id is None for f in ep.frames)
        totals += (cls, var, none)
        print(f"| {fmt[0]} | {fmt[1]}, {fmt[2]} | {cls:.1%} | {var:.1%} | {none} |")
    print(f"| all | | {totals[0] / len(FORMATS):.1%} | {totals[1] / len(FORMATS):.1%} | "
          f"{int(totals[2])} |")
    print("\nOmniGibson's predicates on the same frames (all formats)")
    print("| class | frames | Folded | Unfolded | neither |")
    print("|---|---|---|---|---|")
    for c, marks in og.items():
        m = np.array(marks, dtype=bool)
        neither = ~m[:, 0] & ~m[:, 1]
        print(f"| {c} {CLASS_NAMES[c]} | {len(m)} | {m[:, 0].mean():.0%} | "
              f"{m[:, 1].mean():.0%} | {neither.mean():.0%} |")


def sequences(seed: int, n_frames: int, out: Path, picture: str | None) -> None:
    rng = np.random.default_rng(seed)
    print(f"\nfolding sequences, seed {seed}, {n_frames} frames each")
    print("| sequence | format | frames right | smoothed right | changes true | found |")
    print("|---|---|---|---|---|---|")
    right = total = 0
    for name in ("I", "II", "III"):
        steps = sequence_steps(name, rng=rng)
        yaw = float(rng.uniform(0, 2 * np.pi))
        states = [
            sequence_state(name, p, steps=steps, yaw=yaw)
            for p in sequence_progress(name, n_frames)
        ]
        truth = [s.class_id for s in states]
        for fmt in (FORMATS[0], FORMATS[2], FORMATS[3]):
            path, options = _write(out, f"seq{name}", [s.mesh for s in states], rng, fmt)
            ep = _label(path, options)
            sc = score_timeline(
                truth, [f.class_id for f in ep.frames], [f.smoothed_class for f in ep.frames]
            )
            right += round(sc.raw_accuracy * len(truth))
            total += len(truth)
            print(f"| {name} | {fmt[0]} | {sc.raw_accuracy:.1%} | {sc.smoothed_accuracy:.1%} "
                  f"| {list(sc.true_changes)} | {list(sc.found_changes)} |")
            if picture and name == "II" and fmt[3] == "faces":  # the PNG (and its SVG)
                import cv2

                charts = timeline_files(ep, "x", "dgli label: sequence II, remeshed")
                cv2.imwrite(picture, charts["x_timeline.png"])
                Path(picture).with_suffix(".svg").write_text(charts["x_timeline.svg"])
    print(f"| all | | {right / total:.1%} | | | |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("seed", nargs="?", type=int, default=2027)
    ap.add_argument("--per-variant", type=int, default=3)
    ap.add_argument("--frames", type=int, default=24)
    ap.add_argument("--picture")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        finished_states(args.seed, args.per_variant, Path(tmp))
        sequences(args.seed, args.frames, Path(tmp), args.picture)


if __name__ == "__main__":
    main()
