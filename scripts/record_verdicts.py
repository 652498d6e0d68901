"""Record the verdicts of a varied set of rendered frames, for the test that keeps the
pipeline's answers unchanged while it is made faster (tests/test_verdicts_locked.py).

    .venv/bin/python scripts/record_verdicts.py [--out tests/data/verdicts_locked.json]

The frames are :data:`FRAMES` (class, sample, capture conditions) rendered with seed
:data:`SEED` by :func:`dgli_vision.sim.dataset.render_sample`; each is classified with
the packaged references, and its verdict written: the class and variant of the
prediction (or null and the kind of "cannot tell"), those of the best guess, its
confidence and distance (6 decimals), and the stickers found. Run it on the code whose
answers are the reference (it was run on main at cdac10a, before the napkin-region
work of issue 40, and again when issue 38 made the confidence continuous: the distances
moved by near ties sharing their ranks, no class or confidence changed), and when issue
51 made the camera's handedness known (a camera not declared mirrored is taken as not
mirrored, so 02, 03, 09 and 10 are no longer capped at 0.45: 02_1 photo and 03_0 far
went from 0.45 to 1.0; no class, variant or distance changed).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

#: The seed of the renders.
SEED = 4040

#: (class, sample, conditions): several classes under several capture conditions,
#: among them the photograph-like and far cameras where stickers are small.
FRAMES: tuple[tuple[str, int, tuple[str, ...]], ...] = (
    ("12", 0, ()),
    ("02", 1, ("photo",)),
    ("03", 0, ("far",)),
    ("04", 0, ("head",)),
    ("05", 0, ("grasp",)),
    ("07", 0, ("clutter",)),
    ("08", 0, ("vga",)),
    ("02", 0, ("mirror",)),
    ("05", 1, ("gripper",)),
)


def verdict(result) -> dict:
    """The parts of a :class:`~dgli_vision.classifier.pipeline.FrameResult` the test
    compares."""
    p, g = result.prediction, result.best_guess
    return {
        "class": p.class_id if p else None,
        "variant": p.variant if p else None,
        "why": result.why,
        "guess_class": g.class_id if g else None,
        "guess_variant": g.variant if g else None,
        "confidence": round(float(g.confidence), 6) if g else None,
        "distance": round(float(g.distance), 6) if g else None,
        "found": int(result.detections.found.sum()),
    }


def frames():
    """The rendered frames: (label, RGBDFrame)."""
    from dgli_vision.sim.dataset import render_sample
    from dgli_vision.sources.frames import RGBDFrame

    for class_id, k, conditions in FRAMES:
        s = render_sample(class_id, k, SEED, conditions=conditions)
        r = s.result
        label = f"{class_id}_{k} {'+'.join(conditions) or 'clean'}"
        yield label, RGBDFrame(r.color, r.depth_mm, r.intrinsics, label, label)


def main() -> None:
    from dgli_vision.classifier.pipeline import classify_frame
    from dgli_vision.classifier.references import load_references

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(REPO / "tests/data/verdicts_locked.json"))
    args = parser.parse_args()
    refs = load_references(None)
    out = {label: verdict(classify_frame(f, refs)) for label, f in frames()}
    Path(args.out).write_text(json.dumps({"seed": SEED, "verdicts": out}, indent=1) + "\n")
    print(f"{len(out)} verdicts written to {args.out}")


if __name__ == "__main__":
    main()
