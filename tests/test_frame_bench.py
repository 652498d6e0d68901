"""The per-frame bench: each stage's time, and the summaries it reports."""

from __future__ import annotations

import pytest


def test_every_frame_says_where_its_time_went() -> None:
    """``FrameResult.timings_ms``: each stage's time, in the order the stages ran, adding
    up to about the frame's time (what ``dgli bench --only frames`` reports)."""
    import time
    from pathlib import Path

    from dgli_vision.analysis.frame_bench import FrameBench, FrameTime
    from dgli_vision.classifier.pipeline import classify_frame
    from dgli_vision.classifier.references import load_references
    from dgli_vision.sources.frames import read_frame

    samples = Path(__file__).resolve().parents[1] / "sample_images"
    frame = read_frame(samples / "03_000_color.png", samples / "03_000_depth.png")
    refs = load_references(None)
    t0 = time.perf_counter()
    result = classify_frame(frame, refs)
    total_ms = (time.perf_counter() - t0) * 1e3
    stages = list(result.timings_ms)
    assert stages[:3] == ["table plane", "napkin", "search"]
    assert stages[-3:] == ["classify", "checks", "affordances"]
    assert 0.5 * total_ms <= sum(result.timings_ms.values()) <= total_ms
    bench = FrameBench(
        (
            FrameTime("clean", "a", 10.0, {"search": 4.0}),
            FrameTime("clean", "b", 30.0, {"search": 20.0}),
            FrameTime("gripper", "c", 50.0, {"search": 6.0, "napkin": 30.0}),
        )
    )
    assert bench.summary() == (30.0, 46.0, 50.0)
    assert bench.summary("clean")[2] == 30.0
    assert bench.conditions() == ["clean", "gripper"]
    assert bench.stage_summary()["napkin"][0] == 0.0  # a stage a frame skips costs it 0
    assert [f.name for f in bench.slowest(2)] == ["c", "b"]


def test_the_decode_included_bench_reads_back_the_frames_it_times(tmp_path) -> None:
    """``bench_files`` times each frame from PNG files it writes: the files hold exactly
    the frame's pixels (lossless), so decode-included and in-memory times are of the same
    frames."""
    import numpy as np

    from dgli_vision.analysis.frame_bench import bench_files
    from dgli_vision.classifier.references import load_references
    from dgli_vision.sim.dataset import render_sample
    from dgli_vision.sources.frames import RGBDFrame, read_frame

    r = render_sample("02", 0, 11, conditions=("gripper",)).result
    frame = RGBDFrame(r.color, r.depth_mm, r.intrinsics)
    times = bench_files([("gripper", "02_000", frame)], load_references(None), tmp_path,
                        repeats=1)
    assert times.shape == (1,) and np.isfinite(times).all()
    back = read_frame(tmp_path / "0000_color.png", tmp_path / "0000_depth.png", r.intrinsics)
    assert np.array_equal(back.color, frame.color)
    assert np.array_equal(back.depth_mm, frame.depth_mm)


def test_the_ratio_to_aruco_is_of_the_medians_and_per_frame() -> None:
    """Ours / ArUco: the median of ours over the median of the anchor's, and the
    per-frame ratio's p90 and max, per condition; the machine is called busy when the
    anchor's own times spread."""
    from dgli_vision.analysis.bench import anchor_figures
    from dgli_vision.analysis.frame_bench import AnchorBench, AnchorTime

    bench = AnchorBench(
        (
            AnchorTime("clean", "a", 4.0, 4.0, 1.05),
            AnchorTime("clean", "b", 6.0, 2.0, 1.1),
            AnchorTime("vga", "c", 2.0, 1.0, 2.0),
        )
    )
    med, p90, top = bench.ratios()
    assert med == 4.0 / 2.0 and top == 3.0 and 2.0 < p90 <= 3.0
    assert bench.ratios("clean")[0] == 5.0 / 3.0
    assert bench.medians_ms("vga") == (2.0, 1.0)
    figures = anchor_figures(bench)
    assert [f.ok for f in figures[:2]] == [False, False]
    assert "machine quiet" in figures[5].name  # median spread 1.1
    assert any(f.name.startswith("  vga: median ratio") and f.value == 2.0 for f in figures)
    assert not any("processor time" in f.name for f in figures)  # not measured
    busy = AnchorBench(
        tuple(AnchorTime("dim", str(k), 1.0, 2.0, 1.6, 3.0 + k, 1.0) for k in range(3))
    )
    figures = anchor_figures(busy)
    assert [f.ok for f in figures[:2]] == [True, True]
    assert "BUSY" in figures[5].name
    assert busy.ratios(cpu=True) == (4.0, pytest.approx(4.8), 5.0)
    assert figures[6].name.startswith("  the same in processor time") and figures[6].value == 4.0
    assert "processor time 4.00x, p90 4.80x" in figures[7].name  # each condition's too


def test_bench_vs_aruco_on_a_tiny_set_prints_the_ratio_rows() -> None:
    """``dgli bench --vs-aruco`` on two frames (clean and vga, one repeat): every row
    of the ratios is printed, each condition's with its absolute times (no assertion
    on the times themselves; a missed budget exits 1)."""
    from click.testing import CliRunner

    from dgli_vision.cli import main as cli

    run = CliRunner().invoke(
        cli, ["bench", "--vs-aruco", "--per-condition", "1", "--conditions", "vga",
              "--repeats", "1"],
    )
    assert run.exit_code in (0, 1), run.output
    lines = run.output.splitlines()
    assert lines[0].startswith("ours / ArUco, 2 frames interleaved, one core")
    assert any("per-frame ratio, 90th percentile" in x and "<= 1.5x" in x for x in lines)
    assert any(x.startswith("  clean: median ratio") and "ArUco" in x for x in lines)
    assert any(x.startswith("  vga: median ratio") and "ms" in x for x in lines)
    assert (run.exit_code == 1) == ("MISSED" in run.output)
    bad = CliRunner().invoke(cli, ["bench", "--vs-aruco", "--conditions", "nope"])
    assert bad.exit_code == 2 and "nope" in bad.output


def test_bench_frames_with_one_frame_per_condition_runs(monkeypatch) -> None:
    """``dgli bench --only frames --per-condition 1 --repeats 1``: the folding sequence
    is asked for two frames (one ended in a traceback), each row one figure. One frame
    is rendered; the sequence's rendering and all timing are stand-ins."""
    import itertools
    import re

    import numpy as np
    from click.testing import CliRunner

    from dgli_vision.analysis import frame_bench
    from dgli_vision.cli import main
    from dgli_vision.sim import dataset

    real = frame_bench.bench_set

    def fewer(seed, *, per_condition, sequence_frames, **kw):  # one condition, the sequence
        return itertools.chain(
            itertools.islice(real(seed, per_condition=per_condition, sequence_frames=0, **kw), 1),
            real(seed, per_condition=0, sequence_frames=sequence_frames, **kw),
        )

    def sequence(name, n_frames, seed, conditions):  # the real one's rule, no rendering
        if n_frames < 2:
            raise ValueError(f"a sequence needs at least 2 frames, got {n_frames}")
        asked.append(n_frames)
        return []

    asked: list[int] = []
    monkeypatch.setattr(dataset, "render_sequence", sequence)

    def times(frames, refs, *, repeats):  # the frames rendered, their timing made up
        return frame_bench.FrameBench(tuple(
            frame_bench.FrameTime(c, name, 10.0, {"search": 4.0}) for c, name, _ in frames))

    monkeypatch.setattr(frame_bench, "bench_set", fewer)
    monkeypatch.setattr(frame_bench, "bench_frames", times)
    monkeypatch.setattr(frame_bench, "bench_files",
                        lambda frames, refs, tmp, repeats: np.full(len(frames), 20.0))
    res = CliRunner().invoke(main, ["bench", "--only", "frames", "--per-condition", "1",
                                    "--repeats", "1"])
    assert res.exit_code in (0, 1), res.output  # 1: a budget missed on a busy machine
    assert res.exception is None or isinstance(res.exception, SystemExit), res.exception
    assert asked == [2]  # the sequence asked for its two frames
    assert "every frame (1, in memory" in res.output
    row = next(line for line in res.output.splitlines() if line.startswith("  clean: median ("))
    assert re.match(r"  clean: median \(p90 [\d.]+ ms, slowest [\d.]+ ms\)\s+[\d.]+ ms", row)


def test_a_missed_budget_comes_with_the_machines_load(monkeypatch) -> None:
    from click.testing import CliRunner

    from dgli_vision.analysis import bench
    from dgli_vision.cli import main

    missed = bench.BenchResult("every frame: median", 80.0, "ms", "<= 8 ms", False)
    monkeypatch.setattr(bench, "run_frame_benchmarks", lambda **kw: ([missed], None))
    res = CliRunner().invoke(main, ["bench", "--only", "frames"])
    assert res.exit_code == 1
    assert "MISSED" in res.stdout
    assert "1 budget missed (exit 1); load average" in res.stderr
    assert "time them again on an idle machine" in res.stderr

