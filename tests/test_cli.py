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


def test_bench_reports_figures_and_writes_markdown(tmp_path):
    out = tmp_path / "RESULTS.md"
    result = run(
        ["bench", "--states", "300", "--repeats", "1", "--only", "dgli", "--markdown", str(out)]
    )
    # exit 1 exactly when a budget is missed (a busy machine may miss one), 0 otherwise
    assert result.exit_code == (1 if "MISSED" in result.output else 0), result.output
    assert "pairs/s" in result.output and "numpy per-pair loop" in result.output
    assert out.read_text().startswith("| benchmark |")


def test_bench_finds_the_shipped_samples_from_any_folder(tmp_path, monkeypatch):
    from dgli_vision.cli.bench import _samples_folder

    monkeypatch.chdir(tmp_path)
    found = Path(_samples_folder(None))
    assert (found / "labels.csv").is_file() and found.name == "sample_images"
    assert _samples_folder("mine") == "mine"


@pytest.mark.slow
def test_every_bench_group_runs(tmp_path):
    # a minute and more: run with -m slow; `dgli bench` itself runs these for RESULTS.md
    result = run(["bench", "--states", "300", "--repeats", "1", "--per-condition", "1"])
    assert result.exit_code == (1 if "MISSED" in result.output else 0), result.output
    assert "frames/s" in result.output and "evaluate speed-up" in result.output


def test_unknown_command_is_usage_error():
    result = run(["no-such-command"])
    assert result.exit_code == 2
