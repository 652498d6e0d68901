"""Every ``--json`` output of every command round-trips through the schema of
docs/json.md: the keys its tables list (and not optional) are there with their types, no
key is missing from its table, the objects of a list have the keys its meaning names
where the tables say so, and the output reads back as the same strict JSON."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from dgli_vision.cli import main

ROOT = Path(__file__).resolve().parents[1]
SAMPLES = ROOT / "sample_images"
DOC = (ROOT / "docs" / "json.md").read_text()

#: A type word of the tables -> the Python types json.loads gives for it.
TYPES = {
    "integer": (int,),
    "number": (int, float),
    "string": (str,),
    "boolean": (bool,),
    "object": (dict,),
    "list": (list,),
    "null": (type(None),),
}


def tables(heading: str) -> list[dict[str, tuple[tuple[type, ...], bool, list[str]]]]:
    """The tables under ``## heading``: key -> (allowed types, optional, the backticked
    names in its meaning)."""
    assert f"\n## {heading}\n" in DOC, f"docs/json.md has no section '## {heading}'"
    section = DOC.split(f"\n## {heading}\n", 1)[1].split("\n## ", 1)[0]
    out, table = [], None
    for line in section.splitlines():
        row = line.startswith("|")
        cells = [c.strip() for c in line.strip().strip("|").split("|")] if row else []
        if len(cells) < 3 or cells[0] in ("key", "---"):
            if not row and table:
                out.append(table)
                table = None
            continue
        table = table if table is not None else {}
        kinds = tuple(t for word, ts in TYPES.items() if word in cells[1] for t in ts)
        assert kinds, f"{heading}: no type in {cells[1]!r}"
        meaning = "|".join(cells[2:])
        for key in re.findall(r"`(\w+)`", cells[0]):
            table[key] = (kinds, meaning.startswith("optional"), re.findall(r"`(\w+)`", meaning))
    if table:
        out.append(table)
    return out


def check(data: object, table: dict[str, tuple[tuple[type, ...], bool, list[str]]]) -> None:
    """``data`` is an object that agrees with ``table``."""
    assert isinstance(data, dict)
    required = {k for k, (_, optional, _) in table.items() if not optional}
    assert required <= set(data), f"missing {required - set(data)}"
    assert set(data) <= set(table), f"not documented: {set(data) - set(table)}"
    for key, value in data.items():
        kinds = table[key][0]
        ok = isinstance(value, kinds) and not (isinstance(value, bool) and bool not in kinds)
        assert ok, f"{key}: {type(value).__name__} is not {kinds}"


def round_trip(text: str) -> object:
    """The JSON of ``text``, checked to be strict and to read back the same."""
    data = json.loads(text, parse_constant=lambda c: pytest.fail(f"{c} in the JSON"))
    assert json.loads(json.dumps(data, allow_nan=False)) == data
    return data


def run(*args: object, code: tuple[int, ...] = (0,)) -> str:
    res = CliRunner().invoke(main, [str(a) for a in args])
    assert res.exit_code in code, res.output
    assert "Traceback" not in res.output
    return res.stdout


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


def test_classify() -> None:
    (table,) = tables("dgli classify --json")
    color, depth = SAMPLES / "05_000_color.png", SAMPLES / "05_000_depth.png"
    data = round_trip(run("classify", color, depth, "--json"))
    check(data, table)
    assert len(data["coordinates"]) == 28 and set(data["corners"]) == {"A", "B", "C", "D"}
    assert {"class", "variant", "distance"} == set(data["candidates"][0])


def test_coords() -> None:
    (table,) = tables("dgli coords --json")
    check(round_trip(run("coords", "--json")), table)


def test_evaluate(two_pairs) -> None:
    (table,) = tables("dgli evaluate --json")
    data = round_trip(run("evaluate", two_pairs, "--json", "-j", "1"))
    check(data, table)
    assert set(data["outcomes"]) == {"right", "cannot_tell", "wrong", "unreadable"}


def test_track(two_pairs) -> None:
    (table,) = tables("dgli track --json")
    data = round_trip(run("track", two_pairs, "--json", "-j", "1"))
    check(data, table)
    assert {"score", "outcomes", "coverage", "accuracy_answered"} <= set(data)  # labelled
    assert set(data["frames"][0]) == set(table["frames"][2])


def test_robustness(monkeypatch) -> None:
    from dgli_vision.analysis import robustness

    def fake_outcome(args):
        condition, _, k, class_id = args
        given = class_id if class_id != "05" else None
        return f"{class_id}_{k:03d}", f"{class_id}/x", given, "x", (condition,), (class_id, 0.6)

    monkeypatch.setattr(robustness, "_one", fake_outcome)
    (table,) = tables("dgli robustness --json")
    args = ["robustness", "--per-class", "1", "--conditions", "cast", "-j", "1", "--json"]
    data = round_trip(run(*args))
    check(data, table)
    assert set(data["rows"][0]) == set(table["rows"][2])


def test_verify_and_plan_with_verify() -> None:
    (table,) = tables("dgli verify --json")
    color, depth = SAMPLES / "05_000_color.png", SAMPLES / "05_000_depth.png"
    data = round_trip(run("verify", color, depth, "--expect", "05", "--json", code=(0, 1)))
    check(data, table)
    (plan,) = tables("dgli plan --json")
    start = SAMPLES / "02_000_color.png", SAMPLES / "02_000_depth.png"
    after = SAMPLES / "01_000_color.png", SAMPLES / "01_000_depth.png"
    both = round_trip(
        run("plan", *start, "--goal", "01", "--verify", *after, "--json", code=(0, 1))
    )
    assert set(both) == {"plan", "verify"}
    check(both["plan"], plan)
    check(both["verify"], table)


def test_plan() -> None:
    (table,) = tables("dgli plan --json")
    data = round_trip(run("plan", "--from", "02/A", "--goal", "05/AB/B", "--json"))
    check(data, table)
    named = set(table["steps"][2])
    for step in data["steps"]:
        assert set(step) - {"corner", "side"} == named - {"corner", "side"}


def test_plan_check(monkeypatch) -> None:
    from dgli_vision.planning import check as check_module
    from dgli_vision.planning.check import CheckRow

    def fake_pairs(refs, *, per_pair, seed, limit, on_row):
        rows = [
            CheckRow(("01", None), ("02", "A"), 1, ("01", None), ("02", "A"), ("02", "A"),
                     "right"),
            CheckRow(("01", None), ("11", "AB"), 1, None, None, None, "cannot tell", "few"),
        ]
        for row in rows:
            on_row(row)
            yield row

    monkeypatch.setattr(check_module, "check_pairs", fake_pairs)
    (table,) = tables("dgli plan --check --json")
    data = round_trip(run("plan", "--check", "--every", "50", "--json"))
    check(data, table)
    assert set(data["not_right"][0]) == set(table["not_right"][2])
    assert set(data["geometry"]) == set(table["geometry"][2])


def test_compare(monkeypatch, tmp_path) -> None:
    """The table of a (faked) database: its JSON, and table.json of --report, the same."""
    from dgli_vision.analysis import compare
    from dgli_vision.analysis.compare import REPRESENTATIONS, CompareTable, paper_columns
    from dgli_vision.sim import database_files

    names = tuple(REPRESENTATIONS)
    rows = {n: [0.5, 1e9 if n == "corners" else 0.25] for n in names}  # 1e9: no separation
    table = CompareTable(("database", "III"), rows, paper_columns(names))
    m = np.array([[0.0, 1.0], [1.0, 0.0]])
    monkeypatch.setattr(database_files, "read_database", lambda db: (None, None))
    monkeypatch.setattr(compare, "compare_count", lambda records: 1)
    monkeypatch.setattr(compare, "compare_database", lambda records, **kw: (
        table, {n: m for n in names}, ["01", "02"]))
    (doc,) = tables("dgli compare --json")
    data = round_trip(run("compare", tmp_path, "--json", "--report", tmp_path / "r"))
    check(data, doc)
    assert data["rows"]["corners"] == [0.5, None]
    assert json.loads((tmp_path / "r" / "table.json").read_text()) == data


def test_sequence() -> None:
    (table,) = tables("dgli sequence --json")
    check(round_trip(run("sequence", "III", "--json")), table)


def test_label(tmp_path) -> None:
    from dgli_vision.core.layout import default_layout
    from dgli_vision.labelling.export import remesh, write_npz
    from dgli_vision.sim.cloth.mesh import flat_mesh
    from dgli_vision.sim.cloth.states import sample_state

    mesh = remesh((400.0, 400.0), 800, np.random.default_rng(3))
    flat = flat_mesh(default_layout())
    corner = sample_state("02", "A", np.random.default_rng(3)).mesh
    write_npz(tmp_path / "ep.npz", mesh.positions([flat, corner]), faces=mesh.faces)
    top, frame = tables("dgli label --json")
    data = round_trip(run("label", tmp_path / "ep.npz", "--json"))
    check(data, top)
    (episode,) = data["episodes"]
    assert {"path", "n_frames", "frames", "changes"} <= set(episode)
    for f in episode["frames"]:
        check(f, frame)
    assert set(data["summary"]) == set(top["summary"][2])


def test_watch(two_pairs) -> None:
    line, summary = tables("dgli watch --jsonl")
    lines = [round_trip(t) for t in run("watch", "--bag", two_pairs, "--jsonl").splitlines()]
    assert lines and set(lines[-1]) == {"summary"}
    for data in lines[:-1]:
        check(data, line)
    check(lines[-1]["summary"], summary)


def test_every_command_with_json_has_a_section() -> None:
    """A command given --json later gets its table here, or this fails."""
    from dgli_vision.cli.main import main as group

    with_json = set()
    for name, command in group.commands.items():
        flags = {o for p in command.params for o in getattr(p, "opts", [])}
        if "--json" in flags or "--jsonl" in flags:
            with_json.add(name)
    documented = set(re.findall(r"\n## dgli (\S+) --json", DOC))
    assert with_json <= documented, with_json - documented
