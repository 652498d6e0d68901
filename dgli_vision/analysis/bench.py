"""Benchmarks: throughput of the dGLI kernel against a per-pair Python loop.

Figures are measured in one run and reported as ratios against a baseline measured in the
same run, so that a slow or busy machine shifts both alike. Nothing here prints; the CLI
(``dgli bench``) formats the results.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..core.dgli import cloth_coordinates
from .frame_bench import AnchorBench, FrameBench

__all__ = [
    "BenchResult",
    "baseline_cloth_coordinates_loop",
    "baseline_gli_pair",
    "baseline_gli_pair_numpy",
    "one_core",
    "run_aruco_benchmarks",
    "run_dgli_benchmarks",
    "run_frame_benchmarks",
    "run_pipeline_benchmarks",
    "run_watch_benchmarks",
]

#: The paper's forward-difference step for eq. 8.
PAPER_EPS = 1e-8


@dataclass(frozen=True)
class BenchResult:
    """One benchmark figure.

    Attributes
    ----------
    name : str
        What was measured.
    value : float
        The figure, in ``unit``.
    unit : str
        Unit of ``value`` (e.g. ``"pairs/s"``, ``"ms"``, ``"x"``).
    goal : str
        The budget from DESIGN.md, or ``""``.
    ok : bool or None
        Whether the goal is met (None when there is no goal).
    """

    name: str
    value: float
    unit: str
    goal: str = ""
    ok: bool | None = None


def baseline_gli_pair(a: NDArray, b: NDArray, c: NDArray, d: NDArray) -> float:
    """GLI of one segment pair by the Klenin-Langowski arcsin formula with its sign factor.

    The per-pair formula a researcher writes from the paper (eq. 3 plus the sign factor of
    Klenin and Langowski, 2000), in plain Python floats. Independent of
    :func:`dgli_vision.core.dgli.gli`, which it is tested against.
    """
    r13 = [c[k] - a[k] for k in range(3)]
    r14 = [d[k] - a[k] for k in range(3)]
    r23 = [c[k] - b[k] for k in range(3)]
    r24 = [d[k] - b[k] for k in range(3)]
    r12 = [b[k] - a[k] for k in range(3)]
    r34 = [d[k] - c[k] for k in range(3)]

    def cross(x: list[float], y: list[float]) -> list[float]:
        return [x[1] * y[2] - x[2] * y[1], x[2] * y[0] - x[0] * y[2], x[0] * y[1] - x[1] * y[0]]

    def dot(x: list[float], y: list[float]) -> float:
        return x[0] * y[0] + x[1] * y[1] + x[2] * y[2]

    def unit(x: list[float]) -> list[float]:
        n = math.sqrt(dot(x, x))
        return [v / n for v in x] if n > 0 else [0.0, 0.0, 0.0]

    n1 = unit(cross(r13, r14))
    n2 = unit(cross(r14, r24))
    n3 = unit(cross(r24, r23))
    n4 = unit(cross(r23, r13))

    def asin(x: float) -> float:
        return math.asin(max(-1.0, min(1.0, x)))

    omega = asin(dot(n1, n2)) + asin(dot(n2, n3)) + asin(dot(n3, n4)) + asin(dot(n4, n1))
    sign = math.copysign(1.0, dot(cross(r34, r12), r13))
    return sign * omega / (4.0 * math.pi)


def baseline_gli_pair_numpy(a: NDArray, b: NDArray, c: NDArray, d: NDArray) -> float:
    """The same formula as :func:`baseline_gli_pair` written with numpy on 3-vectors.

    This is the per-pair loop body most researchers write first (``np.cross``,
    ``np.linalg.norm``, ``np.arcsin``); numpy's per-call overhead on 3-vectors makes it
    about 20 times slower than plain floats.
    """
    r13, r14, r23, r24 = c - a, d - a, c - b, d - b
    faces = [np.cross(r13, r14), np.cross(r14, r24), np.cross(r24, r23), np.cross(r23, r13)]
    normals = []
    for f in faces:
        n = np.linalg.norm(f)
        normals.append(f / n if n > 0 else f)
    omega = sum(
        np.arcsin(np.clip(np.dot(normals[k], normals[(k + 1) % 4]), -1.0, 1.0)) for k in range(4)
    )
    sign = np.sign(np.dot(np.cross(d - c, b - a), r13))
    return float(sign * omega / (4.0 * np.pi))


def baseline_cloth_coordinates_loop(
    segments: NDArray,
    up: tuple[float, float, float] = (0.0, 0.0, 1.0),
    *,
    use_numpy: bool = False,
) -> NDArray[np.float64]:
    """Cloth coordinates by a per-pair Python loop and the paper's forward difference.

    Parameters
    ----------
    segments : ndarray, shape (m, 2, 3)
        One state's segments.
    up : tuple of float
        Unit direction of the derivative.
    use_numpy : bool, keyword-only
        Loop body on numpy 3-vectors (:func:`baseline_gli_pair_numpy`) instead of plain
        floats (:func:`baseline_gli_pair`).

    Returns
    -------
    ndarray, shape (m (m - 1) / 2,)
    """
    if use_numpy:
        seg = np.asarray(segments, dtype=np.float64)
        u = np.asarray(up, dtype=np.float64)
        out_np = []
        for i in range(len(seg)):
            for j in range(i + 1, len(seg)):
                (a, b), (c, d) = seg[i], seg[j]
                g0 = baseline_gli_pair_numpy(a, b, c, d)
                g1 = baseline_gli_pair_numpy(a, b + PAPER_EPS * u, c, d + PAPER_EPS * u)
                out_np.append((g1 - g0) / PAPER_EPS)
        return np.array(out_np)
    seg = segments.tolist()
    m = len(seg)
    out = []
    for i in range(m):
        for j in range(i + 1, m):
            a, b = seg[i]
            c, d = seg[j]
            b2 = [b[k] + PAPER_EPS * up[k] for k in range(3)]
            d2 = [d[k] + PAPER_EPS * up[k] for k in range(3)]
            g0 = baseline_gli_pair(a, b, c, d)
            out.append((baseline_gli_pair(a, b2, c, d2) - g0) / PAPER_EPS)
    return np.array(out)


@contextmanager
def one_core() -> Iterator[None]:
    """Pin the process to one CPU while measuring (Linux; a no-op elsewhere)."""
    getter = getattr(os, "sched_getaffinity", None)
    setter = getattr(os, "sched_setaffinity", None)
    if getter is None or setter is None:
        yield
        return
    before = getter(0)
    setter(0, {min(before)})
    try:
        yield
    finally:
        setter(0, before)


def _best_seconds(fn: Callable[[], object], *, repeats: int, min_time: float = 0.2) -> float:
    """Best per-call time over ``repeats`` rounds of as many calls as fill ``min_time``."""
    fn()  # warm-up
    calls = 1
    while True:
        t0 = time.perf_counter()
        for _ in range(calls):
            fn()
        elapsed = time.perf_counter() - t0
        if elapsed >= min_time / repeats or calls > 1_000_000:
            break
        calls *= 2
    best = elapsed / calls
    for _ in range(repeats - 1):
        t0 = time.perf_counter()
        for _ in range(calls):
            fn()
        best = min(best, (time.perf_counter() - t0) / calls)
    return best


def _loop_seconds(states: NDArray, *, use_numpy: bool, repeats: int) -> float:
    """Best time per pair of :func:`baseline_cloth_coordinates_loop` over ``states``."""

    def run() -> None:
        for state in states:
            baseline_cloth_coordinates_loop(state, use_numpy=use_numpy)

    return _best_seconds(run, repeats=repeats) / (len(states) * 28)


@dataclass(frozen=True)
class _KernelTimes:
    """Seconds per call of the kernel (a boundary, the batch) and per pair of the loops."""

    boundary: float
    batch: float
    loop_float: float
    loop_numpy: float


def _time_kernel_and_loops(boundary: NDArray, batch: NDArray, repeats: int) -> _KernelTimes:
    """Time the kernel and the per-pair loops on one core (the loops on a few states)."""
    loop_states = batch[: max(1, min(len(batch), 200))]
    with one_core():
        t_boundary = _best_seconds(lambda: cloth_coordinates(boundary), repeats=repeats)
        t_batch = _best_seconds(lambda: cloth_coordinates(batch), repeats=repeats, min_time=1.0)
        t_loop = _loop_seconds(loop_states, use_numpy=False, repeats=min(repeats, 3))
        t_loop_np = _loop_seconds(loop_states[:20], use_numpy=True, repeats=min(repeats, 3))
    return _KernelTimes(t_boundary, t_batch, t_loop, t_loop_np)


def run_dgli_benchmarks(
    *, n_states: int = 100_000, repeats: int = 5, seed: int = 0
) -> list[BenchResult]:
    """Throughput of :func:`cloth_coordinates` on one core, and against a Python loop.

    Parameters
    ----------
    n_states : int, keyword-only
        States of 8 segments in the batch case (100,000 gives 2.8 M pairs).
    repeats : int, keyword-only
        Timing rounds; the best is kept.
    seed : int, keyword-only
        Seed of the random segments.

    Returns
    -------
    list of BenchResult
    """
    rng = np.random.default_rng(seed)
    boundary = rng.normal(size=(76, 2, 3))
    batch = rng.normal(size=(n_states, 8, 2, 3))
    n_boundary = 76 * 75 // 2
    n_batch = n_states * 28
    times = _time_kernel_and_loops(boundary, batch, repeats)
    goal = ">= 10 M pairs/s"
    results = []
    for name, n, t in (
        ("dGLI kernel: one 76-segment boundary (2,850 pairs)", n_boundary, times.boundary),
        (
            f"dGLI kernel: {n_states:,} states x 8 segments ({n_batch:,} pairs)",
            n_batch,
            times.batch,
        ),
    ):
        rate = n / t
        results.append(BenchResult(name, rate, "pairs/s", goal, rate >= 10e6))
    rate = n_batch / times.batch
    np_rate = 1.0 / times.loop_numpy
    results.append(
        BenchResult("per-pair loop, numpy on 3-vectors (paper eqs. 3, 8)", np_rate, "pairs/s")
    )
    ratio = rate / np_rate
    results.append(
        BenchResult("kernel / numpy per-pair loop", ratio, "x", ">= 1000x", ratio >= 1000)
    )
    float_rate = 1.0 / times.loop_float
    results.append(BenchResult("per-pair loop, plain Python floats", float_rate, "pairs/s"))
    results.append(BenchResult("kernel / plain-float loop", rate / float_rate, "x"))
    return results


def _median_seconds(fn: Callable[[], object], repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def _classify_figures(pair: Any, refs: Any, repeats: int) -> list[BenchResult]:
    """Classifying one pair: from the files in-process, and from memory on one core."""
    from ..classifier.pipeline import classify_frame
    from ..sources.frames import read_frame

    classify_frame(read_frame(pair.color, pair.depth), refs)  # warm-up (imports, caches)
    t = _median_seconds(
        lambda: classify_frame(read_frame(pair.color, pair.depth), refs), repeats * 4
    )
    frame = read_frame(pair.color, pair.depth)
    with one_core():
        t_mem = _median_seconds(lambda: classify_frame(frame, refs), repeats * 4)
    return [
        BenchResult(
            "classify one 1280x720 pair in-process, decode included",
            t * 1e3,
            "ms",
            "<= 50 ms median",
            t <= 0.050,
        ),
        BenchResult(
            "detect + lift + classify one 1280x720 frame in memory, one core",
            t_mem * 1e3,
            "ms",
        ),
    ]


def _cold_start_figures(classify_exe: str, pair: Any, repeats: int) -> list[BenchResult]:
    """``dgli-classify`` on one pair from a cold shell, and a bare Python start-up."""
    import subprocess
    import sys

    def cold() -> None:
        subprocess.run([classify_exe, pair.color, pair.depth], check=True, capture_output=True)

    def bare() -> None:
        subprocess.run([sys.executable, "-c", "pass"], check=True, capture_output=True)

    t_cold = _median_seconds(cold, repeats)
    t_bare = _median_seconds(bare, repeats)
    return [
        BenchResult(
            "dgli-classify from a cold shell, one pair",
            t_cold,
            "s",
            "<= 1.5 s wall",
            t_cold <= 1.5,
        ),
        BenchResult("  of which bare Python start-up (same run)", t_bare, "s"),
    ]


def _render_and_simulate_figures(repeats: int) -> list[BenchResult]:
    """Rendering one pair, and simulating a database of 12 x 20 states."""
    from ..core.camera import look_at_table
    from ..sim.cloth.states import sample_state
    from ..sim.database import simulate_states
    from ..sim.render import render

    state = sample_state("05", rng=1)
    pose = look_at_table(0.52, target=(*state.mesh.xyz[:, :2].mean(axis=0), 0.0))
    render(state, pose, rng=0)  # warm-up (Open3D import, texture)
    t_render = _median_seconds(lambda: render(state, pose, rng=0), repeats)
    t_sim = _median_seconds(lambda: simulate_states(20, 0), 1)
    return [
        BenchResult("render one 1280x720 RGB-D pair", t_render, "s", "<= 0.3 s", t_render <= 0.3),
        BenchResult("simulate 12 x 20 states (no files)", t_sim, "s", "< 10 s", t_sim < 10),
    ]


def _parallel_evaluate_figures(pairs: list, refs: Any) -> list[BenchResult]:
    """``dgli evaluate`` of about 144 pairs with -j 1 and -j 2, as commands (start-up and
    the worker's start included, as the budget is the command's), and the speed-up.

    The folder is the sample pairs over and over (copies, and a labels.csv in a
    temporary folder: a symbolic or a hard link is the same pair again); each
    command runs in turn, three pairs of runs, and the median of the three paired ratios
    is kept (robust to a noisy machine). Beside it, the speed-up of the same work in this
    process once its worker is running: what start-up costs the command."""
    import csv
    import shutil
    import subprocess
    import sys
    import tempfile
    from pathlib import Path

    from .evaluate import _shutdown_pool, evaluate_pairs

    copies = max(1, 144 // len(pairs))
    with tempfile.TemporaryDirectory(prefix="dgli-bench-") as tmp:
        with open(Path(tmp) / "labels.csv", "w", newline="") as f:
            rows = csv.writer(f)
            rows.writerow(["color", "depth", "label", "variant"])
            for k in range(copies):
                for p in pairs:
                    names = [f"{k:03d}_{Path(x).name}" for x in (p.color, p.depth)]
                    for name, src in zip(names, (p.color, p.depth)):
                        shutil.copyfile(src, Path(tmp) / name)
                    rows.writerow([*names, p.label, p.variant or ""])
        n = copies * len(pairs)

        def command(jobs: int) -> Callable[[], object]:
            argv = [sys.executable, "-m", "dgli_vision", "evaluate", tmp, "-j", str(jobs)]
            return lambda: subprocess.run([*argv, "--json"], check=True, capture_output=True)

        runs = []
        for _ in range(3):
            t1 = _median_seconds(command(1), 1)
            t2 = _median_seconds(command(2), 1)
            runs.append((t1 / t2, t1, t2))
    ratio, t1, t2 = sorted(runs)[1]
    # the same work in this process with the worker already running: the speed-up once
    # started (what a program classifying batch after batch gets)
    many = pairs * copies
    list(evaluate_pairs(many[:4], refs, jobs=2))  # the worker started, warm
    warm = _median_seconds(lambda: list(evaluate_pairs(many, refs, jobs=1)), 1) / (
        _median_seconds(lambda: list(evaluate_pairs(many, refs, jobs=2)), 1)
    )
    _shutdown_pool()
    return [
        BenchResult(f"dgli evaluate {n} pairs, -j 1 (the command)", t1, "s"),
        BenchResult(f"dgli evaluate {n} pairs, -j 2 (the command)", t2, "s"),
        BenchResult(
            "evaluate speed-up -j 2 / -j 1 (median of 3 pairs of runs)",
            ratio,
            "x",
            ">= 1.8x",
            ratio >= 1.8,
        ),
        BenchResult(
            "  the same in one process, its worker already started (no start-up)", warm, "x"
        ),
    ]


def _track_figure(pairs: list, refs: Any) -> BenchResult:
    """dgli track: 300 frames (the sample pairs in turn), classified with 2 workers and
    smoothed over time; what a recording of a folding episode costs."""
    from .evaluate import evaluate_pairs
    from .track import track_outcomes

    frames = (pairs * (300 // len(pairs) + 1))[:300]

    def track() -> None:
        outcomes = list(evaluate_pairs(frames, refs, jobs=2, distances=True))
        track_outcomes(outcomes, refs)

    fps = len(frames) / _median_seconds(track, 1)
    return BenchResult(
        "track 300 frames of 1280x720, -j 2", fps, "frames/s", ">= 20 frames/s", fps >= 20
    )


def run_pipeline_benchmarks(
    samples_dir: str, *, repeats: int = 5, classify_exe: str | None = None
) -> list[BenchResult]:
    """Classification, cold start, rendering, simulation and parallel evaluation.

    Parameters
    ----------
    samples_dir : str
        A labelled folder (``sample_images``) to classify.
    repeats : int, keyword-only
        Repetitions per figure (the median is kept).
    classify_exe : str, keyword-only
        The ``dgli-classify`` executable for the cold-start figure (skipped if None).

    Returns
    -------
    list of BenchResult
    """
    from ..classifier.references import load_references
    from ..sources.labelled import find_pairs

    pairs = find_pairs(samples_dir)
    refs = load_references()
    pair = pairs[min(4, len(pairs) - 1)]
    results = _classify_figures(pair, refs, repeats)
    if classify_exe:
        results += _cold_start_figures(classify_exe, pair, repeats)
    results += _render_and_simulate_figures(repeats)
    results += _parallel_evaluate_figures(pairs, refs)
    results.append(_track_figure(pairs, refs))
    return results


_PEAK_RSS = (
    "import resource, subprocess, sys; "
    "subprocess.run(sys.argv[1:], check=True, stdout=subprocess.DEVNULL); "
    "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)"
)


def run_recording_benchmarks(
    samples_dir: str, *, n_frames: int = 300, repeats: int = 3
) -> list[BenchResult]:
    """``dgli track`` on a recorded ROS 2 episode: frames per second of the whole command
    (start-up included) and the peak memory of its largest process.

    The episode is ``n_frames`` 1280 x 720 frames of the sample pairs in turn at 30 Hz,
    raw ``rgb8`` colour and ``16UC1`` aligned depth with their ``CameraInfo``, written
    as MCAP with ``rosbags`` into a temporary folder (about 1.4 GB for 300 frames); and
    ``dgli watch --bag --fast`` on the same episode: answers per second, against twice
    the recording's rate. Empty without the ``recordings`` extra.
    """
    import importlib.util
    import json
    import subprocess
    import sys
    import tempfile
    from pathlib import Path

    if importlib.util.find_spec("rosbags") is None:
        return []
    from ..sources.bag_writer import write_bag
    from ..sources.frames import read_frame
    from ..sources.labelled import find_pairs

    frames = [read_frame(p.color, p.depth) for p in find_pairs(samples_dir)]

    def episode():
        for k in range(n_frames):
            f = frames[k % len(frames)]
            yield 1.7e9 + k / 30, f.color, f.depth_mm

    with tempfile.TemporaryDirectory(prefix="dgli-bench-") as tmp:
        bag = write_bag(Path(tmp) / "episode", episode(), frames[0].intrinsics)
        size = sum(p.stat().st_size for p in bag.iterdir()) / 2**20
        track = [sys.executable, "-m", "dgli_vision", "track", str(bag), "-j", "2", "--json"]
        t = _median_seconds(
            lambda: subprocess.run(track, check=True, capture_output=True), repeats
        )
        peak_kib = int(
            subprocess.run(
                [sys.executable, "-c", _PEAK_RSS, *track],
                check=True,
                capture_output=True,
                text=True,
            ).stdout
        )
        watch = [sys.executable, "-m", "dgli_vision", "watch", "--bag", str(bag), "--jsonl"]
        fast = subprocess.run([*watch, "--fast"], check=True, capture_output=True, text=True)
    quick = json.loads(fast.stdout.splitlines()[-1])["summary"]
    fast_rate = quick["classified"] / quick["seconds"] if quick["seconds"] else 0.0
    fps, peak = n_frames / t, peak_kib / 1024
    name = f"track a {n_frames}-frame 1280x720 ROS 2 episode ({size:,.0f} MB MCAP), -j 2"
    return [
        BenchResult(name, fps, "frames/s", ">= 100 frames/s", fps >= 100),
        BenchResult("  peak memory of its largest process", peak, "MB", "< 500 MB", peak < 500),
        BenchResult(
            "dgli watch --fast on the same episode (recorded at 30 fps): answers", fast_rate,
            "frames/s", ">= 60 frames/s", fast_rate >= 60,
        ),
    ]


def run_watch_benchmarks(
    samples_dir: str, *, n_frames: int = 300, fps: int = 30
) -> list[BenchResult]:
    """``dgli watch`` on a RealSense recording played at its recorded pace: does the
    live path keep up with a camera at ``fps`` frames per second on this machine?

    The recording is ``n_frames`` frames of the sample pairs in turn, written with the
    RealSense SDK's recorder (1280 x 720 RGB8 colour, 640 x 360 Z16 depth in 0.1 mm
    units, uncompressed as a camera gives them) into a temporary folder, and played by
    ``dgli watch --bag --realtime --jsonl`` in a subprocess: the capture thread takes
    each frame from the SDK at the recorded pace, the worker aligns and classifies the
    newest one. Figures: answers per second, the share of frames dropped (they came
    while one was classified), the latency from a frame's arrival to its answer (median
    and p90), how far reading fell behind the recorded pace, and the processor time the
    command used per second of video (in cores: at most two on a two-core machine); then
    the same recording read as fast as it can be classified (``--fast``): answers per
    second, against twice the recording's rate. Empty without the ``realsense`` extra.
    """
    import importlib.util
    import json
    import subprocess
    import sys
    import tempfile
    from pathlib import Path

    if importlib.util.find_spec("pyrealsense2") is None:
        return []
    from ..sources.frames import read_frame
    from ..sources.labelled import find_pairs
    from ..sources.realsense_writer import write_realsense_recording

    frames = [read_frame(p.color, p.depth) for p in find_pairs(samples_dir)]

    def episode():
        for k in range(n_frames):
            f = frames[k % len(frames)]
            yield 100.0 + k / fps, f.color, f.depth_mm

    with tempfile.TemporaryDirectory(prefix="dgli-bench-") as tmp:
        rec = write_realsense_recording(
            Path(tmp) / "episode.db3", episode(), frames[0].intrinsics, fps=fps, compress=False
        )
        size = rec.stat().st_size / 2**20
        watch = [sys.executable, "-m", "dgli_vision", "watch", "--bag", str(rec), "--jsonl"]
        before = _children_cpu()
        out = subprocess.run(watch, check=True, capture_output=True, text=True).stdout
        cores = (_children_cpu() - before) / (n_frames / fps)
        fast = subprocess.run(
            [*watch, "--fast"], check=True, capture_output=True, text=True
        ).stdout
    quick = json.loads(fast.splitlines()[-1])["summary"]
    fast_rate = quick["classified"] / quick["seconds"] if quick["seconds"] else 0.0
    summary = json.loads(out.splitlines()[-1])["summary"]
    rate = summary["classified"] / summary["seconds"] if summary["seconds"] else 0.0
    dropped = summary["dropped"] / max(summary["arrived"], 1)
    lat = summary["latency_ms"]
    behind = summary["behind_s"]
    return [
        BenchResult(
            f"watch a {n_frames}-frame RealSense recording ({size:,.0f} MB .db3) at "
            f"{fps} fps: answers",
            rate,
            "frames/s",
        ),
        BenchResult(
            "  frames dropped (came while one was classified)", 100 * dropped, "%", "0 %",
            summary["dropped"] == 0,
        ),
        BenchResult(
            "  latency, frame to answer, median", lat["median"], "ms",
            f"< {1000 / fps:.0f} ms (a frame)", lat["median"] < 1000 / fps,
        ),
        BenchResult("  latency, p90", lat["p90"], "ms"),
        BenchResult(
            "  reading behind the recorded pace, at worst", behind, "s", "< 0.5 s", behind < 0.5
        ),
        BenchResult("  processor time per second of video", cores, "cores", "< 2", cores < 2),
        BenchResult(
            "  the same recording with --fast (as fast as it can): answers", fast_rate,
            "frames/s", f">= {2 * fps} frames/s", fast_rate >= 2 * fps,
        ),
    ]


def _cores() -> int:
    """The processors this process may run on."""
    getter = getattr(os, "sched_getaffinity", None)
    return len(getter(0)) if getter is not None else os.cpu_count() or 1


def _children_cpu() -> float:
    """Processor seconds (user + system) of the finished child processes so far."""
    import resource

    use = resource.getrusage(resource.RUSAGE_CHILDREN)
    return use.ru_utime + use.ru_stime


#: Busy machine: the anchor's slowest over its best time on a frame, median over frames,
#: above which the figures are said to come from a busy machine.
BUSY_SPREAD = 1.3


def anchor_figures(bench: AnchorBench) -> list[BenchResult]:
    """The ratio rows of :func:`run_aruco_benchmarks`: every frame against the budgets
    (median of ours over median of ArUco's <= 1.0, per-frame p90 <= 1.5), the absolute
    times beside them, whether the machine was busy, then each condition's ratios."""
    med, p90, top = bench.ratios()
    ours, anchor = bench.medians_ms()
    spread = bench.anchor_spread()
    busy = spread > BUSY_SPREAD
    n = len(bench.frames)
    out = [
        BenchResult(f"ours / ArUco, {n} frames interleaved, one core: median / median",
                    med, "x", "<= 1.0x", med <= 1.0),
        BenchResult("  per-frame ratio, 90th percentile", p90, "x", "<= 1.5x", p90 <= 1.5),
        BenchResult("  per-frame ratio, largest", top, "x"),
        BenchResult("  ours (classify_pair on arrays, best of the repeats): median", ours, "ms"),
        BenchResult("  ArUco detectMarkers on the grey frame: median", anchor, "ms"),
        BenchResult(
            "  ArUco's slowest / best per frame (median): "
            + ("MACHINE BUSY, absolute times inflated" if busy else "machine quiet"),
            spread, "x",
        ),
    ]
    c_med, c_p90, _ = bench.ratios(cpu=True)
    if np.isfinite(c_med):
        out.append(BenchResult(
            f"  the same in processor time (thread_time; p90 {c_p90:.2f}x): median ratio",
            c_med, "x"))
    for condition in bench.conditions():
        c_med, c_p90, c_top = bench.ratios(condition)
        c_ours, c_anchor = bench.medians_ms(condition)
        p_med, p_p90, _ = bench.ratios(condition, cpu=True)
        in_cpu = (
            f"; processor time {p_med:.2f}x, p90 {p_p90:.2f}x" if np.isfinite(p_med) else ""
        )
        out.append(BenchResult(
            f"  {condition}: median ratio (p90 {c_p90:.2f}x, max {c_top:.2f}x; "
            f"ours {c_ours:.2f} ms, ArUco {c_anchor:.2f} ms{in_cpu})", c_med, "x"))
    return out


def run_aruco_benchmarks(
    *,
    seed: int = 2024,
    per_condition: int = 8,
    repeats: int = 3,
    conditions: tuple[str, ...] = (),
    frames: list | None = None,
) -> tuple[list[BenchResult], AnchorBench]:
    """Ours against OpenCV's ArUco detector, frame by frame, interleaved, one core.

    Every capture condition the renderer knows (or ``conditions``), ``per_condition``
    frames each, rendered in memory (or ``frames``, as
    :func:`~dgli_vision.analysis.frame_bench.bench_set` gives them); each frame
    classified as ``classify_pair`` does on arrays and looked at by ArUco in turn, best
    of ``repeats`` each (:func:`~dgli_vision.analysis.frame_bench.bench_vs_aruco`).

    Returns
    -------
    figures : list of BenchResult
        :func:`anchor_figures`.
    bench : AnchorBench
        Every frame's times.
    """
    import cv2

    from ..classifier.references import load_references
    from .frame_bench import bench_set, bench_vs_aruco

    refs = load_references(None)
    if frames is None:
        frames = list(
            bench_set(seed, per_condition=per_condition, sequence_frames=0,
                      conditions=conditions)
        )
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        with one_core():
            bench = bench_vs_aruco(iter(frames), refs, repeats=repeats)
    finally:
        cv2.setNumThreads(threads)
    return anchor_figures(bench), bench


def run_frame_benchmarks(
    *,
    seed: int = 2024,
    per_condition: int = 12,
    sequence_frames: int = 12,
    repeats: int = 3,
    conditions: tuple[str, ...] = (),
) -> tuple[list[BenchResult], FrameBench]:
    """The per-frame path over a varied set it renders itself, one core.

    Every capture condition (one frame per class each; ``vga`` is another camera), and
    the frames of a folding sequence with a gripper holding the corner it folds. Each
    frame in memory, best of ``repeats``; then against ArUco on the same frames
    (:func:`run_aruco_benchmarks`), whose ratios carry the budgets.

    Returns
    -------
    figures : list of BenchResult
        The ratios to ArUco (:func:`anchor_figures`, with the budgets); median, 90th
        percentile and largest time over every frame, from memory and from the PNG
        files; the median and p90 of each condition and of each stage (absolute times
        move 1.2-1.5x from day to day on a shared machine: no budget).
    bench : FrameBench
        Every frame's times.
    """
    import tempfile

    from ..classifier.references import load_references
    from .frame_bench import bench_files, bench_frames, bench_set

    refs = load_references(None)
    frames = list(
        bench_set(seed, per_condition=per_condition, sequence_frames=sequence_frames,
                  conditions=conditions)
    )
    anchored, _ = run_aruco_benchmarks(frames=frames, repeats=repeats)
    with one_core():
        bench = bench_frames(iter(frames), refs, repeats=repeats)
    with tempfile.TemporaryDirectory(prefix="dgli-bench-") as tmp:
        with one_core():
            from_files = bench_files(frames, refs, tmp, repeats=repeats)
        from_files_2 = bench_files(frames, refs, tmp, repeats=repeats)
    med, p90, top = bench.summary()
    n = len(bench.frames)
    out = [
        *anchored,
        BenchResult(f"every frame ({n}, in memory, one core): median", med, "ms"),
        BenchResult("every frame: 90th percentile", p90, "ms"),
        BenchResult("every frame: slowest", top, "ms"),
        BenchResult("every frame from its PNG files, decode included, one core: median",
                    float(np.median(from_files)), "ms"),
        BenchResult(f"  the same on {_cores()} cores (the two images decode side by side):"
                    " median", float(np.median(from_files_2)), "ms"),
    ]
    for condition in bench.conditions():
        c_med, c_p90, c_top = bench.summary(condition)
        out.append(BenchResult(
            f"  {condition}: median (p90 {c_p90:.1f} ms, slowest {c_top:.1f} ms)", c_med, "ms"
        ))
    for stage, (s_med, s_p90) in bench.stage_summary().items():
        out.append(BenchResult(f"  stage {stage}: median (p90 {s_p90:.2f} ms)", s_med, "ms"))
    return out, bench
