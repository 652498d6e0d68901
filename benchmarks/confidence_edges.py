"""The classifier's edges on labelled folders (issue 38): confident wrong answers, how far
the confidence moves under tiny changes of the images, and the nearest distances that
right and wrong answers reach.

    .venv/bin/dgli render /tmp/bfm --per-class 3 --seed 101 --conditions backface,mirror
    .venv/bin/dgli render /tmp/seq --sequence II --frames 40 --seed 301
    .venv/bin/python benchmarks/confidence_edges.py /tmp/bfm /tmp/seq [--perturb]

For each folder: pairs, answered, right, confident wrong (best guess of another class at
confidence 0.5 or more), right answers below 0.5; the quantiles of the nearest distance
of right answers and the largest of wrong ones. With ``--perturb`` each pair is
classified again with its depth rounded at another phase (as a 0.1 mm sensor read in mm
is), its depth shifted by a pixel and its colour moved by a grey level, and the largest
change of confidence is printed.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from dgli_vision.classifier.api import frame_from
from dgli_vision.classifier.pipeline import classify_frame
from dgli_vision.classifier.references import load_references
from dgli_vision.sim.jitter import tiny_changes
from dgli_vision.sources.frames import RGBDFrame
from dgli_vision.sources.labelled import find_pairs


def perturbed(frame: RGBDFrame, rng: np.random.Generator) -> list[RGBDFrame]:
    """The frame under the three tiny changes of :func:`tiny_changes`."""
    return tiny_changes(frame, rng)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("folders", nargs="+")
    ap.add_argument("--perturb", action="store_true")
    ap.add_argument("--seed", type=int, default=7)
    args = ap.parse_args()
    refs = load_references()
    rng = np.random.default_rng(args.seed)
    for folder in args.folders:
        n = answered = right = conf_wrong = right_low = 0
        right_d, wrong_d, jumps = [], [], []
        for pair in find_pairs(folder):
            frame = frame_from(pair.color, pair.depth, pair.intrinsics_file)
            res = classify_frame(frame, refs)
            g = res.best_guess
            n += 1
            answered += res.prediction is not None
            ok = res.prediction is not None and res.prediction.class_id == pair.label
            right += ok
            right_low += ok and g.confidence < 0.5
            if g is not None:
                (right_d if g.class_id == pair.label else wrong_d).append(g.distance)
                conf_wrong += g.class_id != pair.label and g.confidence >= 0.5
            if args.perturb:
                base = g.confidence if g is not None else 0.0
                for other in perturbed(frame, rng):
                    h = classify_frame(other, refs).best_guess
                    jumps.append(abs((h.confidence if h is not None else 0.0) - base))
        q = np.quantile(right_d, [0.5, 0.9, 1.0]).round(3).tolist() if right_d else []
        print(
            f"{folder}: {n} pairs, {answered} answered, {right} right, {conf_wrong} confident "
            f"wrong, {right_low} right below 0.5; nearest distance of right answers "
            f"(median, 90%, max) {q}, of wrong ones max "
            f"{max(wrong_d) if wrong_d else float('nan'):.3f}"
        )
        if jumps:
            j = np.array(jumps)
            over = int((j > 0.2).sum())
            print(f"  confidence change: max {j.max():.3f}, over 0.2: {over} of {len(j)}")


if __name__ == "__main__":
    main()
