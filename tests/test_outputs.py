"""Nothing lost: no command replaces a file it did not write, unless told --overwrite."""

from __future__ import annotations

import hashlib
import os
import shutil
from pathlib import Path

import pytest
from click.testing import CliRunner

from dgli_vision.cli import main
from dgli_vision.cli.classify import classify_cmd
from dgli_vision.core.errors import OverwriteError
from dgli_vision.core.io import MANIFEST_NAME, guard_outputs, record_outputs, write_text

SAMPLES = Path(__file__).resolve().parent.parent / "sample_images"


def checksums(folder: Path) -> dict[str, str]:
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


@pytest.fixture()
def user_folder(tmp_path: Path) -> Path:
    """A folder of the user's own files, named as the commands' outputs would be."""
    folder = tmp_path / "mine"
    names = [
        "01_000_color.png",  # render
        "labels.csv",
        "index.json",  # simulate
        "refs.json",  # references build -o
        "colours.json",  # calibrate -o
        "report.md",  # evaluate --report
        "table.json",  # compare --report
        "timeline.json",  # sequence --report (what track --report writes)
        "overlay.png",  # classify --overlay
        "bench.md",  # bench --markdown
        "robustness.md",  # robustness --markdown
    ]
    for name in names:
        write_text(folder / name, f"the user's own {name}\n")
    return folder


@pytest.fixture(scope="module")
def database(tmp_path_factory) -> Path:
    db = tmp_path_factory.mktemp("db")
    res = CliRunner().invoke(main, ["simulate", str(db), "--per-class", "1", "--in-progress", "0"])
    assert res.exit_code == 0, res.output
    return db


def test_no_writing_command_replaces_a_users_file(user_folder, database):
    before = checksums(user_folder)
    color, depth = str(SAMPLES / "01_000_color.png"), str(SAMPLES / "01_000_depth.png")
    f = str(user_folder)
    commands = [
        (main, ["render", f, "--per-class", "1"], "01_000_color.png"),
        (main, ["simulate", f, "--per-class", "1", "--in-progress", "0"], "index.json"),
        (main, ["references", "build", str(database), "-o", f + "/refs.json"], "refs.json"),
        (main, ["calibrate", color, depth, "-o", f + "/colours.json"], "colours.json"),
        (main, ["evaluate", str(SAMPLES), "--report", f, "-j", "1"], "report.md"),
        (main, ["compare", str(database), "--report", f], "table.json"),
        (main, ["sequence", "I", "--report", f], "timeline.json"),
        (classify_cmd, [color, depth, "--overlay", f + "/overlay.png"], "overlay.png"),
        (main, ["bench", "--only", "dgli", "--markdown", f + "/bench.md"], "bench.md"),
        (
            main,
            ["robustness", "--per-class", "1", "--markdown", f + "/robustness.md"],
            "robustness.md",
        ),
    ]
    for cmd, argv, victim in commands:
        res = CliRunner().invoke(cmd, argv)
        assert res.exit_code == 2, (argv, res.output)
        lines = res.output.strip().splitlines()
        assert lines[-1].startswith("error: refusing to replace"), (argv, res.output)
        assert victim in lines[-1] and "--overwrite" in lines[-1]
        assert "Traceback" not in res.output
    assert checksums(user_folder) == before


def test_overwrite_replaces_and_own_output_needs_no_flag(tmp_path):
    folder = tmp_path / "set"
    write_text(folder / "labels.csv", "color,depth,label\n")
    # (two frames of a sequence: a dozen pairs of --per-class 1 cost six times as much)
    args = ["render", str(folder), "--sequence", "I", "--frames", "2", "--clean"]
    assert CliRunner().invoke(main, args).exit_code == 2
    res = CliRunner().invoke(main, [*args, "--overwrite"])
    assert res.exit_code == 0, res.output
    assert "I_000_color.png" in (folder / "labels.csv").read_text()
    # the tool's own output, untouched since, is replaced without the flag
    res = CliRunner().invoke(main, args)
    assert res.exit_code == 0, res.output
    # but not once the user has edited it
    (folder / "labels.csv").write_text("color,depth,label\nmine.png,mine_d.png,01\n")
    res = CliRunner().invoke(main, args)
    assert res.exit_code == 2 and "labels.csv" in res.output


def test_the_record_lists_what_was_written_with_checksums(tmp_path):
    out = tmp_path / "a.txt"
    write_text(out, "x\n")
    with pytest.raises(OverwriteError, match=r"a\.txt"):
        guard_outputs([out])
    record_outputs([out], "dgli test")
    guard_outputs([out])  # now it is the tool's own
    assert (tmp_path / MANIFEST_NAME).is_file()
    shutil.copy(out, tmp_path / "b.txt")
    with pytest.raises(OverwriteError, match=r"b\.txt"):
        guard_outputs([tmp_path / "b.txt"])
    with pytest.raises(OverwriteError, match="is a directory"):
        guard_outputs([tmp_path])


def _labelled(tmp_path: Path, rows: list[str]) -> Path:
    folder = tmp_path / "set"
    folder.mkdir()
    for name in ("01_000", "02_000"):
        for kind in ("color", "depth"):
            shutil.copy(SAMPLES / f"{name}_{kind}.png", folder / f"{name}_{kind}.png")
    shutil.copy(SAMPLES / "intrinsics.json", folder / "intrinsics.json")
    (folder / "labels.csv").write_text("color,depth,label,variant\n" + "\n".join(rows) + "\n")
    return folder


@pytest.mark.parametrize(
    ("row", "message"),
    [
        ("02_000_color.png,02_000_depth.png,13,", "line 3: class '13' is not a class: 01-12"),
        ("02_000_color.png,02_000_depth.png,02,AB", "line 3: variant 'AB' is not one of"),
        ("01_000_color.png,01_000_depth.png,01,", "line 3: the same pair as"),
    ],
)
def test_bad_label_rows_stop_the_run_unless_lenient(tmp_path, row, message):
    folder = _labelled(tmp_path, ["01_000_color.png,01_000_depth.png,01,", row])
    res = CliRunner().invoke(main, ["evaluate", str(folder), "-j", "1"])
    assert res.exit_code == 2 and message in res.output and "--lenient" in res.output
    assert "Traceback" not in res.output
    res = CliRunner().invoke(main, ["evaluate", str(folder), "-j", "1", "--lenient", "--json"])
    assert res.exit_code == 0, res.output
    out = res.output.strip().splitlines()
    data = __import__("json").loads(out[-1])
    assert data["n"] == 1 and len(data["skipped"]) == 1 and message in data["skipped"][0]
    assert sum(message in line for line in out) == 2  # listed once on stderr, once in JSON


@pytest.mark.parametrize("link", ["symbolic", "hard"])
def test_a_pair_listed_again_through_a_link_is_the_same_pair(tmp_path, link):
    """Duplicates are found by the files' identity (device and inode): a hard link was
    a second pair, scored twice."""
    folder = _labelled(tmp_path, ["01_000_color.png,01_000_depth.png,01,",
                                  "again_color.png,again_depth.png,01,"])
    for kind in ("color", "depth"):
        first, again = folder / f"01_000_{kind}.png", folder / f"again_{kind}.png"
        if link == "hard":
            os.link(first, again)
        else:
            again.symlink_to(first.name)
    res = CliRunner().invoke(main, ["evaluate", str(folder), "-j", "1"])
    assert res.exit_code == 2 and "Traceback" not in res.output
    assert "line 3: the same pair as" in res.output and "line 2" in res.output


def test_a_row_with_a_missing_file_is_reported_once_with_its_line(tmp_path):
    folder = _labelled(
        tmp_path,
        ["01_000_color.png,01_000_depth.png,01,", "gone_color.png,gone_depth.png,02,A"],
    )
    res = CliRunner().invoke(main, ["evaluate", str(folder), "-j", "1", "--json"])
    assert res.exit_code == 0, res.output
    data = __import__("json").loads(res.output.strip().splitlines()[-1])
    (failure,) = data["failures"]
    assert "does not exist" in failure["error"] and "line 3" in failure["error"]
    assert data["skipped"] == []
