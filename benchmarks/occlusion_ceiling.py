"""How much of an object-covered napkin the stickers can tell at all: the tool's verdicts
under a gripper against those of an ideal sticker reader (docs/robustness.md).

Usage: python benchmarks/occlusion_ceiling.py [--seed S] [--per-class N]
       [--conditions gripper,grasp] [-j JOBS]

For every pair rendered as `dgli robustness` renders it, the ideal reader is handed the
simulator's truth instead of the images: the exact 3D position of every sticker the
camera sees (at least half its disc), which missing stickers lie under the cloth
(hidden: evidence of a fold), and which are covered by the object only (unknown). It
names the state with the tool's own classifier and confidence rule. It knows more than
the images hold (where an object covers the place a sticker would lie flat, the images
cannot say whether the sticker is there or under a fold), so its share of confident right
answers bounds what any reading of the stickers can reach on these renders.
"""

from __future__ import annotations

import argparse
import multiprocessing
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from dgli_vision.classifier.classify import MIN_CONFIDENCE, classify_coordinates
from dgli_vision.classifier.pipeline import classify_frame
from dgli_vision.classifier.references import ReferenceSet, load_references
from dgli_vision.core.classes import CLASS_IDS, LIFTED_MM
from dgli_vision.core.dgli import cloth_coordinates
from dgli_vision.core.errors import DetectionError
from dgli_vision.sim.dataset import render_sample
from dgli_vision.sim.render import VISIBLE_FRACTION
from dgli_vision.sources.frames import RGBDFrame

_REFS: ReferenceSet | None = None


def _init() -> None:
    import cv2

    global _REFS
    cv2.setNumThreads(1)
    _REFS = load_references()


def _ideal(sample, refs: ReferenceSet) -> tuple[str | None, float]:
    """The ideal reader's class and confidence for a rendered sample."""
    r = sample.result
    seen = r.visible
    under_cloth = sample.state.visible_fraction < VISIBLE_FRACTION
    unknown = ~seen & ~under_cloth
    points = sample.state.sticker_points.copy()  # world, metres, table at z = 0
    points[~seen] = np.nan
    coords = cloth_coordinates(points.reshape(-1, 2, 3), (0.0, 0.0, 1.0))
    heights = points[:, 2] * 1e3
    lifted = np.where(np.isfinite(heights), (heights > LIFTED_MM).astype(float), np.nan)
    try:
        p = classify_coordinates(
            coords, refs, visible=seen, unknown=unknown, lifted=lifted, heights_mm=heights
        )
    except DetectionError:
        return None, 0.0
    return p.class_id, p.confidence


def _one(task: tuple[str, int, int, str]) -> tuple[str, bool, bool, bool]:
    """Condition, whether the object covers a sticker the camera would see without it,
    whether the tool is right, whether the ideal reader is right and confident."""
    condition, seed, k, class_id = task
    assert _REFS is not None
    sample = render_sample(class_id, k, seed, conditions=(condition,))
    r = sample.result
    frame = RGBDFrame(r.color, r.depth_mm, r.intrinsics, sample.name, sample.name, "render")
    verdict = classify_frame(frame, _REFS).prediction
    truth = sample.state.class_id
    cls, confidence = _ideal(sample, _REFS)
    covers = bool((~r.visible & (sample.state.visible_fraction >= VISIBLE_FRACTION)).any())
    tool_right = verdict is not None and verdict.class_id == truth
    return condition, covers, tool_right, cls == truth and confidence >= MIN_CONFIDENCE


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=31)
    ap.add_argument("--per-class", type=int, default=8)
    ap.add_argument("--conditions", default="gripper,grasp")
    ap.add_argument("-j", "--jobs", type=int, default=2)
    a = ap.parse_args()
    conditions = a.conditions.split(",")
    tasks = [
        (c, a.seed, k, cid) for c in conditions for cid in CLASS_IDS for k in range(a.per_class)
    ]
    ctx = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(a.jobs, mp_context=ctx, initializer=_init) as pool:
        out = list(pool.map(_one, tasks, chunksize=2))
    print(f"seed {a.seed}, {a.per_class} pairs per class and condition\n")
    print("| condition | pairs | the object covers a sticker | tool right | ideal reader right |")
    print("|---|---|---|---|---|")
    for c in conditions:
        for covers in (False, True, None):
            rows = [o for o in out if o[0] == c and (covers is None or o[1] == covers)]
            if not rows:
                continue
            label = {False: "no", True: "yes", None: "**all**"}[covers]
            n = len(rows)
            tool = sum(o[2] for o in rows)
            ideal = sum(o[3] for o in rows)
            print(
                f"| {c} | {n} | {label} | {tool} ({100 * tool / n:.0f}%) | "
                f"{ideal} ({100 * ideal / n:.0f}%) |"
            )


if __name__ == "__main__":
    main()
