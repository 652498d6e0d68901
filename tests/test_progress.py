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


def test_render_off_a_terminal_says_a_line_per_tenth_of_the_pairs(tmp_path):
    res = CliRunner().invoke(
        main, ["render", str(tmp_path / "seq"), "--sequence", "I", "--frames", "3", "--clean"]
    )
    assert res.exit_code == 0, res.output
    lines = [ln for ln in res.stderr.splitlines() if ln.startswith("rendering: ")]
    assert [ln.split(" done")[0] for ln in lines] == [
        "rendering: 1 of 3", "rendering: 2 of 3", "rendering: 3 of 3"
    ]
    assert "s left)" in lines[0] and lines[-1].endswith(" s)")


def test_progress_lines_come_every_nth_item_and_after_the_last(capsys):
    from dgli_vision.cli.output import progress_lines

    assert list(progress_lines(list(range(25)), "work")) == list(range(25))
    said = capsys.readouterr().err.splitlines()
    assert [ln.split(" done")[0] for ln in said] == [
        f"work: {k} of 25" for k in (3, 6, 9, 12, 15, 18, 21, 24, 25)
    ]


def test_the_time_left_counts_from_the_first_item_done(monkeypatch):
    """A job whose workers take 40 s to start and then do an item a second: after its
    second item the time left is 10 s for the 10 left (not 40 s x 10 / 2), and none is
    shown before a rate is known."""
    import io
    import time

    import click

    from dgli_vision.cli.output import _FromFirstItem

    now = [1000.0]
    monkeypatch.setattr(time, "time", lambda: now[0])
    with _FromFirstItem(click.progressbar(length=12, file=io.StringIO(), show_eta=True)) as bar:
        now[0] += 40.0
        bar.update(1)
        assert not bar.bar.eta_known
        now[0] += 1.0
        bar.update(1)
        assert bar.bar.eta_known and bar.bar.eta == pytest.approx(10.0)
        now[0] += 1.0
        bar.update(1)
        assert bar.bar.eta == pytest.approx(9.0, abs=1.0)
