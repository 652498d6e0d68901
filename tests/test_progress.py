"""Long work says what it does: ``plan --check`` counts its trials for a progress bar,
``bench`` names each group before timing it."""

from __future__ import annotations

import pytest
from click.testing import CliRunner

from dgli_vision.cli import main
from dgli_vision.planning import check


@pytest.mark.parametrize("limit, per_pair", [(None, 1), (5, 1), (7, 2)])
def test_the_check_counts_the_trials_it_runs(monkeypatch, limit, per_pair):
    monkeypatch.setattr(check, "run_pair", lambda *a, **k: None)
    rows = list(check.check_pairs(None, per_pair=per_pair, limit=limit))
    assert check.check_count(per_pair=per_pair, limit=limit) == len(rows) > 0


def test_plan_check_feeds_its_progress_bar_each_trial(monkeypatch):
    from dgli_vision.cli import plan

    ticks = []

    class Bar:
        def __enter__(self):
            return self

        def __exit__(self, *exc):
            return False

        def update(self, n):
            ticks.append(n)

    monkeypatch.setattr(plan, "progress_bar", lambda count, label, quiet: Bar())
    flat, corner = ("01", None), ("02", "A")
    monkeypatch.setattr(check, "run_pair", lambda *a, **k: check.CheckRow(
        flat, corner, 1, flat, corner, corner, "right"))
    res = CliRunner().invoke(main, ["plan", "--check", "--every", "50", "--json"])
    assert res.exit_code == 0, res.output
    assert len(ticks) == check.check_count(limit=50)


def test_bench_names_each_group_before_it_runs(monkeypatch):
    from dgli_vision.analysis import bench

    monkeypatch.setattr(bench, "run_dgli_benchmarks", lambda **kw: [])
    res = CliRunner().invoke(main, ["bench", "--only", "dgli", "--states", "10"])
    assert res.exit_code == 0
    assert "bench: dgli coordinates, 10 states, best of 5 ..." in res.stderr
