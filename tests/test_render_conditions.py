"""``dgli render --conditions``: all of them together on every pair, as the help says;
``--per-condition``: a set per condition, each in its own folder under that one alone."""

from __future__ import annotations

from click.testing import CliRunner

from dgli_vision.cli import main, render


def _calls(monkeypatch) -> list[tuple[str, tuple]]:
    calls = []

    def fake(out, names, cases, provenance, options, **kw):
        assert provenance["conditions"] == list(options["conditions"])
        calls.append((out, options["conditions"]))

    monkeypatch.setattr(render, "_render_set", fake)
    return calls


def test_conditions_apply_together_unless_per_condition(tmp_path, monkeypatch):
    calls = _calls(monkeypatch)
    out = tmp_path / "out"
    args = ["render", str(out), "--per-class", "1", "--conditions", "jpeg,dim"]
    assert CliRunner().invoke(main, args).exit_code == 0
    assert calls == [(str(out), ("jpeg", "dim"))]
    calls.clear()
    assert CliRunner().invoke(main, [*args, "--per-condition"]).exit_code == 0
    assert calls == [(str(out / "jpeg"), ("jpeg",)), (str(out / "dim"), ("dim",))]


def test_the_help_says_how_conditions_combine():
    text = " ".join(CliRunner().invoke(main, ["render", "--help"]).output.split())
    assert "all of them applied together to every pair" in text
    assert "OUT/<condition>/" in text


def test_per_condition_without_conditions_is_a_usage_error(tmp_path, monkeypatch):
    _calls(monkeypatch)
    res = CliRunner().invoke(main, ["render", str(tmp_path / "o"), "--per-condition"])
    assert res.exit_code == 2 and "--per-condition needs --conditions" in res.output
