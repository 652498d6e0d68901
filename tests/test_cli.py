"""The dgli command group driven through click with argv lists."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from dgli_vision.cli import main
from dgli_vision.core.layout import default_layout


def run(args):
    result = CliRunner().invoke(main, args)
    assert "Traceback" not in result.output
    return result


def test_help_lists_commands():
    result = run(["--help"])
    assert result.exit_code == 0
    assert "coords" in result.output and "bench" in result.output


def test_coords_json_gives_flat_coordinates():
    result = run(["coords", "--json"])
    assert result.exit_code == 0
    data = json.loads(result.output)
    assert len(data["coordinates"]) == 28
    np.testing.assert_allclose(data["coordinates"], default_layout().flat_coordinates())


def test_coords_plain_lists_pairs():
    result = run(["coords"])
    assert result.exit_code == 0
    assert "0-1" in result.output and "6-7" in result.output


#: The benchmark groups ``dgli bench`` runs (module, function); each returns its figures
#: (``run_frame_benchmarks``: a tuple, the figures first).
BENCH_GROUPS = [
    ("dgli_vision.analysis.bench", "run_dgli_benchmarks"),
    ("dgli_vision.analysis.bench", "run_pipeline_benchmarks"),
    ("dgli_vision.analysis.bench", "run_frame_benchmarks"),
    ("dgli_vision.analysis.bench", "run_recording_benchmarks"),
    ("dgli_vision.labelling.bench", "run_label_benchmarks"),
    ("dgli_vision.analysis.bench", "run_watch_benchmarks"),
    ("dgli_vision.analysis.bench", "run_aruco_benchmarks"),
]


def test_bench_groups_are_every_group_the_command_runs():
    import inspect
    import re

    from dgli_vision.cli import bench

    called = set(re.findall(r"\b(run_\w+_benchmarks)\(", inspect.getsource(bench)))
    assert called == {name for _, name in BENCH_GROUPS}


def every_budget(monkeypatch, ok: bool) -> None:
    """The groups measure as they do, and every figure with a budget is then marked met
    (or missed): whether a busy machine meets a budget is not for a test to decide, the
    exit code that follows from it is."""
    import dataclasses
    import importlib

    def judged(results):
        return [r if r.ok is None else dataclasses.replace(r, ok=ok) for r in results]

    for module_name, name in BENCH_GROUPS:
        module = importlib.import_module(module_name)
        real = getattr(module, name)

        def wrapper(*args, _real=real, **kwargs):
            out = _real(*args, **kwargs)
            return (judged(out[0]), *out[1:]) if isinstance(out, tuple) else judged(out)

        monkeypatch.setattr(module, name, wrapper)


def test_bench_reports_figures_and_writes_markdown(tmp_path, monkeypatch):
    out = tmp_path / "RESULTS.md"
    args = ["bench", "--states", "300", "--repeats", "1", "--only", "dgli", "--markdown"]
    every_budget(monkeypatch, True)
    result = run([*args, str(out)])
    assert result.exit_code == 0, result.output
    assert "pairs/s" in result.output and "numpy per-pair loop" in result.output
    assert "MISSED" not in result.output
    text = out.read_text()
    assert text.startswith("| benchmark |") and "| ok |" in text


def test_bench_exits_1_when_a_budget_is_missed_and_still_writes_the_figures(
    tmp_path, monkeypatch
):
    from dgli_vision.analysis import bench
    from dgli_vision.analysis.bench import BenchResult

    figures = [
        BenchResult("dGLI kernel: one boundary", 3.2e6, "pairs/s", ">= 10 M pairs/s", False),
        BenchResult("kernel / numpy per-pair loop", 3330.0, "x", ">= 1000x", True),
        BenchResult("per-pair loop, plain Python floats", 2.2e4, "pairs/s"),
    ]
    monkeypatch.setattr(bench, "run_dgli_benchmarks", lambda **kwargs: figures)
    out = tmp_path / "RESULTS.md"
    result = run(["bench", "--only", "dgli", "--markdown", str(out)])
    assert result.exit_code == 1, result.output
    lines = result.stdout.splitlines()  # (stderr: the group's name, the machine's load)
    assert len(lines) == 3 and lines[0].endswith("MISSED") and lines[1].endswith("ok")
    assert "| dGLI kernel: one boundary | 3.20 M pairs/s | >= 10 M pairs/s | MISSED |" in (
        out.read_text()
    )


def test_bench_finds_the_shipped_samples_from_any_folder(tmp_path, monkeypatch):
    from dgli_vision.cli.bench import _samples_folder

    monkeypatch.chdir(tmp_path)
    found = Path(_samples_folder(None))
    assert (found / "labels.csv").is_file() and found.name == "sample_images"
    assert _samples_folder("mine") == "mine"


@pytest.mark.slow
def test_every_bench_group_runs(tmp_path, monkeypatch):
    # a minute and more: run with -m slow; `dgli bench` itself runs these for RESULTS.md
    every_budget(monkeypatch, True)
    # (--per-condition 1 asks for a held-fold sequence of one frame: ValueError)
    result = run(["bench", "--states", "300", "--repeats", "1", "--per-condition", "2"])
    assert result.exit_code == 0, result.output
    assert "MISSED" not in result.output
    assert "frames/s" in result.output and "evaluate speed-up" in result.output


def test_unknown_command_is_usage_error():
    result = run(["no-such-command"])
    assert result.exit_code == 2
