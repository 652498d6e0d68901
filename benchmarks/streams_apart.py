"""Colour and depth of different instants (issue 54): the simulator's folding sequences
with each colour image paired with the depth image ``lag`` frames before it (a depth
stream behind the colour stream; a negative lag: ahead of it).

    .venv/bin/python benchmarks/streams_apart.py --seeds 1,2,3 --frames 30 --lags -3,-2,-1,0,1,2,3

For every lag: pairs, right (the colour image's state: the instant a user looks at), not
answered (or below confidence 0.5) and confident wrong (another state at confidence 0.5
or more), with the wrong ones listed: sequence, seed, colour frame and its progress, the
depth frame's state, the answer. Frames are rendered once per sequence and seed
(30 frames: about a minute each).
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from dgli_vision.classifier.pipeline import classify_frame
from dgli_vision.classifier.references import load_references
from dgli_vision.sim.dataset import render_sequence
from dgli_vision.sources.frames import RGBDFrame

CONFIDENT = 0.5


def _ints(text: str) -> list[int]:
    return [int(x) for x in text.split(",") if x.strip()]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=_ints, default=[1, 2, 3])
    ap.add_argument("--frames", type=int, default=30)
    ap.add_argument("--lags", type=_ints, default=[-3, -2, -1, 0, 1, 2, 3])
    ap.add_argument("--sequences", default="I,II,III")
    args = ap.parse_args()
    refs = load_references()
    counts: Counter = Counter()
    wrong: list[str] = []
    for seed in args.seeds:
        for name in args.sequences.split(","):
            frames = list(render_sequence(name, args.frames, seed))
            for lag in args.lags:
                for k, shown in enumerate(frames):
                    if not 0 <= k - lag < len(frames):
                        continue
                    depth = frames[k - lag]
                    c = shown.result
                    pair = RGBDFrame(c.color, depth.result.depth_mm, c.intrinsics, "c", "d")
                    p = classify_frame(pair, refs).prediction
                    truth = shown.state.class_id
                    if p is not None and p.confidence >= CONFIDENT:
                        verdict = "right" if p.class_id == truth else "wrong"
                    else:
                        verdict = "not answered"
                    counts[lag, verdict] += 1
                    if verdict == "wrong":
                        wrong.append(
                            f"  lag {lag:+d}: sequence {name} seed {seed} frame {k} "
                            f"(progress {shown.state.params['progress']:.2f}, {truth}; "
                            f"depth's {depth.state.class_id}) read "
                            f"{p.class_id} at {p.confidence:.2f}"
                        )
    print("| lag (frames) | pairs | right | not answered | confident wrong |")
    print("|---:|---:|---:|---:|---:|")
    for lag in args.lags:
        n = [counts[lag, v] for v in ("right", "not answered", "wrong")]
        print(f"| {lag:+d} | {sum(n)} | {n[0]} | {n[1]} | {n[2]} |")
    if wrong:
        print("\nconfident wrong:")
        print("\n".join(wrong))


if __name__ == "__main__":
    main()
