"""docs/json.md is the JSON of evaluate, track and robustness: every key it lists is in
the commands' output, and no top-level key of the output is missing from it."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import pytest
from click.testing import CliRunner

from dgli_vision.analysis import robustness
from dgli_vision.cli import main

ROOT = Path(__file__).resolve().parents[1]
SAMPLES = ROOT / "sample_images"


def documented(command: str) -> dict[str, tuple[bool, list[str]]]:
    """key -> (optional, the backticked names in its meaning) of the table under
    ``## dgli <command> --json``."""
    text = (ROOT / "docs" / "json.md").read_text()
    section = text.split(f"## dgli {command} --json", 1)[1].split("\n## ", 1)[0]
    out = {}
    for line in section.splitlines():
        m = re.match(r"\| `(\w+)` \| [^|]+ \| (.*) \|$", line)
        if m:
            meaning = m.group(2)
            out[m.group(1)] = (meaning.startswith("optional"), re.findall(r"`(\w+)`", meaning))
    return out


def check(data: dict, keys: dict[str, tuple[bool, list[str]]]) -> None:
    required = {k for k, (optional, _) in keys.items() if not optional}
    assert required <= set(data), required - set(data)
    assert set(data) <= set(keys), set(data) - set(keys)  # nothing undocumented


@pytest.fixture(scope="module")
def two_pairs(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("two")
    for name in ("01_000", "03_000"):
        for kind in ("color", "depth"):
            shutil.copy(SAMPLES / f"{name}_{kind}.png", folder / f"{name}_{kind}.png")
    shutil.copy(SAMPLES / "intrinsics.json", folder / "intrinsics.json")
    (folder / "labels.csv").write_text(
        "color,depth,label,variant\n01_000_color.png,01_000_depth.png,01,\n"
        "03_000_color.png,03_000_depth.png,03,A\n"
    )
    return folder


def test_evaluate_json_is_as_documented(two_pairs):
    res = CliRunner().invoke(main, ["evaluate", str(two_pairs), "--json", "-j", "1"])
    data = json.loads(res.stdout)
    check(data, documented("evaluate"))
    assert set(data["outcomes"]) == {"right", "cannot_tell", "wrong", "unreadable"}


def test_track_json_is_as_documented(two_pairs):
    res = CliRunner().invoke(main, ["track", str(two_pairs), "--json", "-j", "1"])
    data = json.loads(res.stdout)
    keys = documented("track")
    check(data, keys)
    assert {"score", "outcomes", "coverage", "accuracy_answered"} <= set(data)  # labelled
    assert set(data["frames"][0]) == set(keys["frames"][1])


def fake_outcome(args):
    condition, _, k, class_id = args
    given = class_id if class_id != "05" else None
    return f"{class_id}_{k:03d}", f"{class_id}/x", given, "x", (condition,), (class_id, 0.6)


def test_robustness_json_is_as_documented(monkeypatch):
    monkeypatch.setattr(robustness, "_one", fake_outcome)
    args = ["robustness", "--per-class", "1", "--conditions", "cast", "-j", "1", "--json"]
    data = json.loads(CliRunner().invoke(main, args).stdout)
    keys = documented("robustness")
    check(data, keys)
    assert set(data["rows"][0]) == set(keys["rows"][1])
    assert data["outcomes"] == {"right": 11, "cannot_tell": 1, "wrong": 0, "unreadable": 0}
