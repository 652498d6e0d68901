"""``-j N`` gives the results of one process: the same database, the same renders."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from dgli_vision.cli import main
from dgli_vision.core.parallel import ordered_map


def test_simulate_on_two_workers_writes_the_database_of_one(tmp_path):
    args = ["--per-class", "1", "--in-progress", "0", "--seed", "3"]
    for j in ("1", "2"):
        res = CliRunner().invoke(main, ["simulate", str(tmp_path / j), *args, "-j", j])
        assert res.exit_code == 0, res.output
    one, two = tmp_path / "1", tmp_path / "2"
    files = sorted(p.relative_to(one) for p in one.rglob("*") if p.is_file())
    assert files == sorted(p.relative_to(two) for p in two.rglob("*") if p.is_file())
    for name in files:
        if name.name in {"index.json", ".dgli-outputs.json"}:  # the command line differs
            continue
        assert (one / name).read_bytes() == (two / name).read_bytes(), name
    a, b = (json.loads((d / "index.json").read_text()) for d in (one, two))
    assert a["states"] == b["states"]


def test_renders_on_two_workers_are_those_of_one():
    from dgli_vision.cli.render import _render_case

    options = {"nominal": False, "clean": False, "conditions": ("vga",), "layout": None}
    tasks = [(("02", 0), 4, options), (("11", 1), 4, options)]
    one = list(ordered_map(_render_case, tasks, jobs=1))
    two = list(ordered_map(_render_case, tasks, jobs=2))
    assert [s.name for s in two] == ["02_000", "11_001"]
    for a, b in zip(one, two):
        np.testing.assert_array_equal(a.result.color, b.result.color)
        np.testing.assert_array_equal(a.result.depth_mm, b.result.depth_mm)


def test_ordered_map_refuses_no_workers():
    with pytest.raises(ValueError, match="at least 1"):
        list(ordered_map(abs, [1], jobs=0))


def test_robustness_on_two_workers_scores_as_one():
    from dgli_vision.analysis.robustness import score_condition
    from dgli_vision.classifier.references import load_references

    refs = load_references()
    kw = {"per_class": 1, "seed": 77, "classes": ("02", "09")}
    one = score_condition("vga", refs, jobs=1, **kw)
    two = score_condition("vga", refs, jobs=2, **kw)
    assert one == two and one[0].n == 2
    assert [s.guesses for s in one] == [s.guesses for s in two]


def test_workers_start_with_one_thread_per_numerical_library(monkeypatch):
    """Before a pool of workers starts, one thread per numerical library is put in the
    environment the workers inherit (they read it when numpy loads, before any
    initializer runs); a value the user set is kept."""
    import os

    from dgli_vision.core.parallel import ONE_THREAD_VARIABLES, limit_library_threads

    for name in ONE_THREAD_VARIABLES:
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setenv("MKL_NUM_THREADS", "3")
    limit_library_threads()
    assert [os.environ[n] for n in ONE_THREAD_VARIABLES] == ["1", "1", "3"]
    monkeypatch.delenv("OMP_NUM_THREADS")
    limit_library_threads(4)  # (a worker of -j 2 on 8 cores)
    assert os.environ["OMP_NUM_THREADS"] == "4" and os.environ["OPENBLAS_NUM_THREADS"] == "1"
