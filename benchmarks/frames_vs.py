"""Per-frame times of this checkout against another commit, measured back to back.

    .venv/bin/python benchmarks/frames_vs.py BASE_REV [--per-condition N] [--rounds R]
        [--markdown OUT.md]

The varied set of ``dgli bench --only frames`` (every capture condition, another camera,
a folding sequence with a gripper) is rendered once, by this checkout, and kept on disk.
Then the two checkouts (this one and ``BASE_REV`` in a temporary git worktree) classify
every frame in turn, one process each, pinned to the same core: A B A B ... for
``--rounds`` rounds, each frame's best time over the rounds kept; after each frame the
worker also times OpenCV's ArUco detector (DICT_4X4_50, default parameters) on its grey
image, the anchor of ``dgli bench --vs-aruco``, so each checkout's ours / ArUco ratio
is given too. A busy machine slows both alike, so the ratios are the honest figure; the
absolute times are for reference.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]

#: Run in a checkout's directory (its package first on sys.path): time every frame once.
WORKER = r"""
import json, os, sys, time
sys.path.insert(0, os.getcwd())
os.sched_setaffinity(0, {int(sys.argv[3])})
import cv2
import numpy as np
cv2.setNumThreads(1)
aruco = cv2.aruco.ArucoDetector(
    cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_50), cv2.aruco.DetectorParameters()
).detectMarkers
from dgli_vision.classifier.pipeline import classify_frame
from dgli_vision.classifier.references import load_references
from dgli_vision.core.camera import Intrinsics
from dgli_vision.sources.frames import RGBDFrame
refs = load_references(None)
index = json.loads(open(sys.argv[1]).read())
out = []
for i, item in enumerate(index):
    z = np.load(item["file"])
    intr = Intrinsics(*item["intrinsics"], distortion=tuple(item["distortion"]))
    frame = RGBDFrame(z["color"], z["depth"], intr, item["name"], item["name"])
    if i == 0:
        classify_frame(frame, refs)  # warm the caches once
    grey = cv2.cvtColor(np.ascontiguousarray(frame.color), cv2.COLOR_RGB2GRAY)
    t0 = time.perf_counter()
    result = classify_frame(frame, refs)
    t1 = time.perf_counter()
    aruco(grey)
    t2 = time.perf_counter()
    out.append([(t1 - t0) * 1e3, dict(result.timings_ms), (t2 - t1) * 1e3])
open(sys.argv[2], "w").write(json.dumps(out))
"""


def render_set(folder: Path, per_condition: int) -> Path:
    """Render the bench's frames into ``folder`` (npz) and return their index file."""
    sys.path.insert(0, str(REPO))
    from dgli_vision.analysis.frame_bench import bench_set

    index = []
    for k, (condition, name, frame) in enumerate(bench_set(0, per_condition=per_condition)):
        path = folder / f"{k:04d}.npz"
        np.savez(path, color=frame.color, depth=frame.depth_mm)
        i = frame.intrinsics
        index.append(
            {
                "file": str(path),
                "condition": condition,
                "name": name,
                "intrinsics": [i.width, i.height, i.fx, i.fy, i.cx, i.cy],
                "distortion": list(i.distortion or ()),
            }
        )
    path = folder / "index.json"
    path.write_text(json.dumps(index))
    return path


def time_checkout(checkout: Path, index: Path, out: Path, core: int) -> list:
    """One pass of ``checkout`` over the frames: [(total ms, stages), ...]."""
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    cmd = [sys.executable, "-c", WORKER, str(index), str(out), str(core)]
    subprocess.run(cmd, cwd=checkout, env=env, check=True)
    return json.loads(out.read_text())


def best_of(passes: list[list]) -> list:
    """Per frame, the pass with the smallest total, with the anchor's best time over the
    passes in place of its own (the table takes the better of the two checkouts')."""
    return [
        [*min(frame_passes, key=lambda p: p[0])[:2], min(p[2] for p in frame_passes)]
        for frame_passes in zip(*passes)
    ]


def table(index: list[dict], base: list, new: list) -> str:
    """Markdown: per condition and per stage, base and new medians / p90 / max, ratios."""
    lines = [
        "| frames | before: median / p90 / max (ms) | after | after / before (median) "
        "| ArUco median (ms) | ours / ArUco before: median, p90, max | after |",
        "|---|---|---|---|---|---|---|",
    ]
    conditions = list(dict.fromkeys(item["condition"] for item in index))
    for cond in [*conditions, None]:
        pick = [k for k, item in enumerate(index) if cond in (None, item["condition"])]
        b = np.array([base[k][0] for k in pick])
        a = np.array([new[k][0] for k in pick])
        anchor = np.array([min(base[k][2], new[k][2]) for k in pick])
        label = cond or f"**all {len(pick)}**"
        lines.append(
            f"| {label} | {_stats(b)} | {_stats(a)} | {np.median(a) / np.median(b):.2f} "
            f"| {np.median(anchor):.2f} | {_ratios(b, anchor)} | {_ratios(a, anchor)} |"
        )
    lines += ["", "| stage | before: median (ms) | after | after / before |", "|---|---|---|---|"]
    stages = list(dict.fromkeys(s for run in (base, new) for frame in run for s in frame[1]))
    for s in stages:
        b = np.median([frame[1].get(s, 0.0) for frame in base])
        a = np.median([frame[1].get(s, 0.0) for frame in new])
        ratio = f"{a / b:.2f}" if b > 0 else "new"
        lines.append(f"| {s} | {b:.2f} | {a:.2f} | {ratio} |")
    return "\n".join(lines) + "\n"


def _ratios(t: np.ndarray, anchor: np.ndarray) -> str:
    per = t / anchor
    return (
        f"{np.median(t) / np.median(anchor):.2f} / {np.percentile(per, 90):.2f} / "
        f"{per.max():.2f}"
    )


def _stats(t: np.ndarray) -> str:
    return f"{np.median(t):.1f} / {np.percentile(t, 90):.1f} / {t.max():.1f}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("base", help="the commit to compare with (e.g. HEAD~3)")
    ap.add_argument("--per-condition", type=int, default=4)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--core", type=int, default=max(os.sched_getaffinity(0)))
    ap.add_argument("--markdown", type=Path)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="dgli-frames-vs-") as tmp:
        tmp = Path(tmp)
        worktree = tmp / "base"
        subprocess.run(
            ["git", "worktree", "add", "-q", "--detach", str(worktree), args.base],
            cwd=REPO,
            check=True,
        )
        try:
            (tmp / "frames").mkdir()
            index_path = render_set(tmp / "frames", args.per_condition)
            passes: dict[str, list] = {"base": [], "new": []}
            for r in range(args.rounds):
                for name, checkout in (("base", worktree), ("new", REPO)):
                    out = tmp / f"{name}{r}.json"
                    passes[name].append(time_checkout(checkout, index_path, out, args.core))
                    print(f"round {r + 1}/{args.rounds}: {name} done", file=sys.stderr)
            index = json.loads(index_path.read_text())
            text = table(index, best_of(passes["base"]), best_of(passes["new"]))
        finally:
            subprocess.run(["git", "worktree", "remove", "--force", str(worktree)], cwd=REPO)
    head = f"Per-frame times, {args.base} (before) against this checkout (after), "
    head += f"best of {args.rounds} alternating rounds, one core.\n\n"
    print(head + text)
    if args.markdown:
        args.markdown.write_text(head + text)


if __name__ == "__main__":
    main()
