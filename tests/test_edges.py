"""The edges of issue 38 besides `dgli label`: a damaged ROS 2 bag is one line in every
command that reads it; standard output that cannot take the answer is an error naming
its file, and a pipe closed by its reader ends the command quietly; files are written
whole or not at all; a resume re-classifies images captured again under the same names;
workers die with their parent; a rerun removes what the earlier run listed; labels rows
must name frames that exist; napkin sizes out of range are refused with the range."""

from __future__ import annotations

import csv
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from cli_runs import one_error_line, run_process
from click.testing import CliRunner

from dgli_vision.cli import main

ROOT = Path(__file__).resolve().parent.parent
SAMPLES = ROOT / "sample_images"


def run(*args: object):
    result = CliRunner().invoke(main, [str(a) for a in args])
    assert "Traceback" not in result.output, result.output
    return result




def sample_folder(root: Path, names: tuple[str, ...] = ("05_000", "09_000")) -> Path:
    """A labelled folder of a few sample pairs."""
    root.mkdir(parents=True)
    rows = []
    with (SAMPLES / "labels.csv").open() as fh:
        labels = {r["color"]: r for r in csv.DictReader(fh)}
    for name in names:
        for part in ("color", "depth"):
            shutil.copy(SAMPLES / f"{name}_{part}.png", root / f"{name}_{part}.png")
        row = labels[f"{name}_color.png"]
        rows.append(f"{row['color']},{row['depth']},{row['label']},{row['variant']}")
    shutil.copy(SAMPLES / "intrinsics.json", root / "intrinsics.json")
    (root / "labels.csv").write_text("color,depth,label,variant\n" + "\n".join(rows) + "\n")
    return root


# --- a ROS 2 sqlite bag with 4 KB of garbage inside ---------------------------------------


def _tiny_episode_bag(path: Path, frames: int = 30) -> Path:
    """A ROS 2 sqlite3 bag of ``frames`` small frames, 0.1 s apart."""
    pytest.importorskip("rosbags")
    from dgli_vision.core.camera import Intrinsics
    from dgli_vision.sources.bag_writer import write_bag

    rng = np.random.default_rng(0)
    intr = Intrinsics(64, 48, 60.0, 60.0, 32.0, 24.0)
    data = [
        (100.0 + k * 0.1, rng.integers(0, 255, (48, 64, 3), np.uint8),
         np.full((48, 64), 500 + k, np.uint16))
        for k in range(frames)
    ]
    return write_bag(path, iter(data), intr, fmt="ros2-sqlite3")


@pytest.fixture(scope="module")
def corrupt_bag(tmp_path_factory) -> Path:
    """A 30-frame ROS 2 sqlite3 bag with one 4 KB page overwritten by garbage, one that
    opens and then fails part-way (found by trying the pages in turn)."""
    from dgli_vision.core.errors import UnreadableInputError
    from dgli_vision.sources.recording import open_recording

    root = tmp_path_factory.mktemp("corrupt")
    bag = _tiny_episode_bag(root / "good")
    db3 = next(bag.glob("*.db3"))
    data = db3.read_bytes()
    garbage = np.random.default_rng(1).integers(0, 256, 4096, np.uint8).tobytes()
    for page in range(len(data) // 4096 // 3, len(data) // 4096):
        bad = root / "bad"
        shutil.rmtree(bad, ignore_errors=True)
        shutil.copytree(bag, bad)
        off = page * 4096
        (bad / db3.name).write_bytes(data[:off] + garbage + data[off + 4096 :])
        try:
            recording = open_recording(bad)
        except UnreadableInputError:
            continue  # the damage shows at once: not the case wanted
        n = 0
        try:
            for _ in recording.frames:
                n += 1
        except Exception:  # an UnreadableInputError (an apsw.CorruptError before)
            if n > 0:
                return bad
    pytest.fail("no page of the bag fails part-way")


def test_a_corrupt_db3_is_one_line_in_every_command_that_reads_it(corrupt_bag, tmp_path):
    labels = tmp_path / "labels.csv"
    labels.write_text("frame,label\n" + "".join(f"{k},01\n" for k in range(30)))
    for args in (
        ["track", corrupt_bag, "-j", "1"],
        ["watch", "--bag", corrupt_bag, "--fast"],
        ["evaluate", corrupt_bag, "--labels", labels, "-j", "1"],
        ["extract", corrupt_bag, tmp_path / "out"],
    ):
        line = one_error_line(run(*args))
        assert f"recording '{corrupt_bag}'" in line and "corrupt" in line, (args, line)


def test_extract_of_a_bag_that_fails_part_way_lists_what_it_wrote(corrupt_bag, tmp_path):
    out = tmp_path / "out"
    line = one_error_line(run("extract", corrupt_bag, out))
    with (out / "frames.csv").open() as fh:
        listed = [(r["color"], r["depth"]) for r in csv.DictReader(fh)]
    assert listed and f"the {len(listed)} frames read before it" in line
    on_disk = sorted(p.name for p in out.glob("frame_*.png"))
    assert on_disk == sorted(name for pair in listed for name in pair)  # nothing unlisted
    assert run("track", out, "-j", "1", "--json").exit_code in (0, 1)  # a folder to read


def test_extract_takes_the_run_lock_of_its_folder(tmp_path):
    """Two extracts into one folder were stopped only by the overwrite guard: now the
    second stops at once naming the first, as every writing command does."""
    from dgli_vision.core.run_lock import RunLock

    bag = _tiny_episode_bag(tmp_path / "bag", frames=3)
    out = tmp_path / "out"
    with RunLock(out, "dgli extract bag out"):
        r = run("extract", bag, out)
    line = one_error_line(r)
    assert "in use by another dgli run" in line and "dgli extract bag out" in line
    assert not (out / "frames.csv").exists() and not list(out.glob("*.png"))
    r = run("extract", bag, out)  # the lock released: the folder is written
    assert r.exit_code == 0, r.output
    assert len((out / "frames.csv").read_text().splitlines()) == 4


# --- standard output: flushed and checked, a closed pipe quiet ----------------------------


def _limited_to(n_bytes: int):
    """A child's start: files it writes may grow to ``n_bytes`` (RLIMIT_FSIZE), as on a
    disk with that much space left; a longer write is cut short, the next one fails."""

    def limit() -> None:
        import resource

        resource.setrlimit(resource.RLIMIT_FSIZE, (n_bytes, n_bytes))

    return limit


@pytest.mark.parametrize(
    "args",
    [
        ["classify", SAMPLES / "05_000_color.png", SAMPLES / "05_000_depth.png", "--json"],
        ["track", "{folder}", "--json", "-j", "1"],
        ["evaluate", "{folder}", "--json", "-j", "1"],
    ],
    ids=["classify", "track", "evaluate"],
)
def test_json_to_a_full_disk_is_one_line_naming_the_file(args, tmp_path):
    folder = sample_folder(tmp_path / "pairs")
    args = [str(a).replace("{folder}", str(folder)) for a in args]
    with open("/dev/full", "w") as full:
        proc = run_process(args, stdout=full)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr
    assert "cannot write to standard output: No space left on device" in proc.stderr
    # a disk that fills up part-way (the interpreter unbuffered, as under python -u):
    # exit 2, not 0 with the answer cut, and the error names the file
    out = tmp_path / "answer.json"
    with out.open("w") as fh:
        proc = run_process(
            args, stdout=fh, preexec_fn=_limited_to(200),
            env={**os.environ, "PYTHONUNBUFFERED": "1"},
        )
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert lines[-1] == f"error: cannot write to standard output ('{out}'): File too large"
    assert "Traceback" not in proc.stderr


def _first_line_then_close(args: list[object]) -> tuple[int, str]:
    """Run ``dgli ARGS``, read its first line of standard output and close the pipe, as
    ``| head -1`` does: the exit code and standard error."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "dgli_vision", *map(str, args)],
        cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
    )
    assert json.loads(proc.stdout.readline())["frame"] == 0
    proc.stdout.close()
    with proc.stderr:
        err = proc.stderr.read().decode()
    return proc.wait(timeout=60), err


def test_a_pipe_closed_by_its_reader_ends_quietly(tmp_path):
    """`dgli watch --jsonl | head -1`: no message, the exit code of a Unix tool that
    SIGPIPE ended."""
    folder = sample_folder(tmp_path / "pairs", ("05_000", "09_000", "01_000"))
    (folder / "frames.csv").write_text(
        "color,depth,time\n05_000_color.png,05_000_depth.png,0\n"
        "09_000_color.png,09_000_depth.png,1.5\n01_000_color.png,01_000_depth.png,3\n"
    )
    code, err = _first_line_then_close(["watch", "--bag", folder, "--jsonl"])
    assert code == 141 and err == "", err


def test_watch_into_a_closed_pipe_stops_the_realsense_playback_first(tmp_path):
    """The SDK's threads still playing when the process ends abort it ("FATAL: exception
    not rethrown", exit 134): the playback is stopped first, then the quiet end."""
    pytest.importorskip("pyrealsense2")
    import cv2

    from dgli_vision.core.camera import Intrinsics
    from dgli_vision.sources.frames import read_frame
    from dgli_vision.sources.realsense_writer import write_realsense_recording

    frame = read_frame(SAMPLES / "05_000_color.png", SAMPLES / "05_000_depth.png")
    color = cv2.resize(frame.color, (320, 180), interpolation=cv2.INTER_AREA)
    depth = cv2.resize(frame.depth_mm, (320, 180), interpolation=cv2.INTER_NEAREST)
    k = frame.intrinsics
    intr = Intrinsics(320, 180, k.fx / 4, k.fy / 4, k.cx / 4, k.cy / 4)
    data = ((1000.0 + i * 0.2, color, depth) for i in range(30))
    db3 = write_realsense_recording(tmp_path / "rs.db3", data, intr)
    code, err = _first_line_then_close(["watch", "--bag", db3, "--jsonl"])
    assert code == 141, err
    assert "FATAL" not in err and "error" not in err and "Traceback" not in err



def test_a_report_folder_on_a_disk_with_no_room_is_one_line_naming_the_file(tmp_path):
    """With 0 bytes free, the first file a run writes is its lock: the error named no
    path ('error: No space left on device') and left the empty lock file."""
    folder = sample_folder(tmp_path / "pairs")
    for command in ("evaluate", "track"):
        report = tmp_path / f"report_{command}"
        proc = run_process(
            [command, folder, "--report", report, "-j", "1"],
            stdout=subprocess.PIPE, preexec_fn=_limited_to(0),
        )
        assert proc.returncode == 2, proc.stderr
        assert proc.stderr.splitlines() == [
            f"error: cannot write '{report / '.dgli-lock'}': File too large; nothing was "
            "written"
        ]
        assert list(report.iterdir()) == []


@pytest.mark.parametrize(
    "command, files",
    [("evaluate", ("report.md", "report.html", "summary.json")),
     ("track", ("report.html", "timeline.json"))],
)
def test_the_report_is_written_when_standard_output_closes_early(tmp_path, command, files):
    """`dgli evaluate --report DIR | head -1` exited 141 leaving results.jsonl and no
    report: the report is the run's record, written all the same, then exit 141."""
    folder = sample_folder(tmp_path / "pairs")
    report = tmp_path / "report"
    proc = subprocess.Popen(
        [sys.executable, "-m", "dgli_vision", command, str(folder), "--report", str(report),
         "-j", "1"],
        cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
    )
    proc.stdout.close()  # the reader has gone before the first line
    with proc.stderr:
        err = proc.stderr.read().decode()
    assert proc.wait(timeout=120) == 141, err
    assert "Traceback" not in err and "report written to" in err
    for name in files:
        assert (report / name).stat().st_size > 0, name
    assert len((report / "results.jsonl").read_text().splitlines()) == 3  # header, 2 pairs


def test_results_lines_are_whole_when_the_disk_fills_up(tmp_path):
    """With 28 KB left, results.jsonl kept a torn last line: each line now goes in one
    write, and a write the disk takes only in part is cut back off."""
    folder = sample_folder(tmp_path / "pairs", ("05_000", "09_000", "01_000", "02_000"))
    report = tmp_path / "report"
    proc = run_process(
        ["evaluate", folder, "--report", report, "-j", "1"],
        stdout=subprocess.PIPE, preexec_fn=_limited_to(3000),  # a line is about 1.4 kB
    )
    assert proc.returncode == 2, proc.stderr
    (line,) = proc.stderr.splitlines()
    assert f"cannot write '{report / 'results.jsonl'}'" in line and "kept" in line
    data = (report / "results.jsonl").read_bytes()
    assert data.endswith(b"\n") and len(data) <= 3000
    assert [json.loads(x) for x in data.splitlines()]  # every line whole


# --- files written whole or not at all ------------------------------------------------------


def test_simulate_on_a_full_disk_is_one_line_and_leaves_no_partial_mesh(tmp_path):
    out = tmp_path / "db"
    proc = run_process(
        ["simulate", out, "--per-class", "1", "--in-progress", "0"],
        stdout=subprocess.PIPE, preexec_fn=_limited_to(100_000),  # a mesh is 324 kB
    )
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.splitlines() == [
        f"error: cannot write '{out / 'meshes' / '01_000.ply'}': File too large; "
        "nothing was written before it"
    ]  # no RPly lines
    assert [p.name for p in out.rglob("*") if p.is_file()] == []


def test_a_file_that_cannot_be_written_whole_leaves_the_earlier_one(tmp_path):
    """A report file replaced on a disk that fills up: the earlier file stays as it was
    (it was cut to what fitted, or removed)."""
    target = tmp_path / "summary.json"
    target.write_text("the earlier run's summary\n")
    code = (
        "import sys\n"
        "from dgli_vision.core.errors import OutputError\n"
        "from dgli_vision.core.io import write_text\n"
        "try:\n"
        f"    write_text({str(target)!r}, 'x' * 100_000)\n"
        "except OutputError as exc:\n"
        "    sys.exit(str(exc))\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, stderr=subprocess.PIPE, text=True,
        preexec_fn=_limited_to(50_000), timeout=60,
    )
    assert proc.stderr.strip() == f"cannot write '{target}': File too large"
    assert target.read_text() == "the earlier run's summary\n"
    assert [p.name for p in tmp_path.iterdir()] == ["summary.json"]


def test_meshes_are_the_ply_files_open3d_reads(tmp_path):
    import open3d as o3d

    from dgli_vision.core.io import mesh_ply_bytes, read_mesh_ply, write_mesh_ply

    xyz = np.random.default_rng(0).normal(size=(9, 3))
    tri = np.array([[0, 1, 2], [2, 3, 4], [6, 7, 8]], np.int32)
    write_mesh_ply(tmp_path / "m.ply", xyz, tri)
    v, t = read_mesh_ply(tmp_path / "m.ply")
    np.testing.assert_array_equal(v, xyz)
    np.testing.assert_array_equal(t, tri)
    mesh = o3d.geometry.TriangleMesh(
        o3d.utility.Vector3dVector(xyz), o3d.utility.Vector3iVector(tri)
    )
    o3d.io.write_triangle_mesh(str(tmp_path / "o.ply"), mesh, write_ascii=False)
    assert (tmp_path / "m.ply").read_bytes() == mesh_ply_bytes(xyz, tri)
    ours = mesh_ply_bytes(xyz, tri).replace(b"dgli_vision", b"Open3D")
    assert ours == (tmp_path / "o.ply").read_bytes()  # the layout Open3D writes


# --- workers die with their parent ---------------------------------------------------------


def _children(pid: int) -> set[int]:
    """The processes whose parent is ``pid`` (from /proc)."""
    found = set()
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
            except OSError:
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) == pid:
                found.add(int(entry.name))
    return found


def _alive(pid: int) -> bool:
    """Running (a zombie waiting for a parent to reap it has ended)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads /proc")
def test_workers_die_with_their_parent_killed_outright():
    """SIGKILL of `dgli evaluate -j 3` (as the out-of-memory killer sends it): its
    worker processes are gone within seconds (they lived on, 86-854 MB each)."""
    import signal
    import time

    proc = subprocess.Popen(
        [sys.executable, "-m", "dgli_vision", "evaluate", str(SAMPLES), "-j", "3"],
        cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )
    try:
        deadline = time.monotonic() + 60
        workers: set[int] = set()
        while time.monotonic() < deadline and proc.poll() is None:
            workers = {
                c for c in _children(proc.pid)
                if b"multiprocessing" in Path(f"/proc/{c}/cmdline").read_bytes()
            }
            if len(workers) >= 2:
                break
            time.sleep(0.05)
        assert len(workers) >= 2, "the workers did not start"
        time.sleep(1.0)  # at work (or still loading)
        descendants = workers | {g for w in workers for g in _children(w)}
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=10)
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline and any(_alive(p) for p in descendants):
            time.sleep(0.1)
        assert not [p for p in descendants if _alive(p)]
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


# --- a resume re-classifies images captured again under the same names ---------------------


def test_resume_classifies_again_the_pairs_captured_again(tmp_path, monkeypatch):
    from dgli_vision.analysis import evaluate as evaluate_module

    folder = sample_folder(tmp_path / "pairs", ("05_000", "09_000"))
    report = tmp_path / "report"
    assert run("evaluate", folder, "--report", report, "-j", "1").exit_code == 0
    summary = json.loads((report / "summary.json").read_text())
    assert summary["outcomes"]["right"] == 2
    for part in ("color", "depth"):  # 09_000 captured again: the flat napkin now
        shutil.copy(SAMPLES / f"01_000_{part}.png", folder / f"09_000_{part}.png")

    classified: list[str] = []
    real = evaluate_module.evaluate_pairs

    def recording(pairs, *args, **kwargs):
        def seen():
            for p in pairs:
                classified.append(Path(p.color).name)
                yield p

        return real(seen(), *args, **kwargs)

    monkeypatch.setattr(evaluate_module, "evaluate_pairs", recording)
    r = run("evaluate", folder, "--report", report, "--resume", "-j", "1")
    assert r.exit_code == 0, r.output
    assert classified == ["09_000_color.png"]  # the other pair's verdict is kept
    assert "note: 1 pair has changed since the interrupted run" in r.output
    summary = json.loads((report / "summary.json").read_text())
    assert summary["outcomes"]["right"] == 1 and summary["outcomes"]["wrong"] == 1


# --- a rerun removes what the earlier run listed; labels rows name frames that exist ------


def test_extract_again_with_every_3_leaves_no_earlier_frame(tmp_path):
    bag = _tiny_episode_bag(tmp_path / "ep")
    out = tmp_path / "out"
    assert run("extract", bag, out).exit_code == 0
    assert len(list(out.glob("frame_*_color.png"))) == 30
    assert run("extract", bag, out, "--every", "3").exit_code == 0
    with (out / "frames.csv").open() as fh:
        listed = {name for r in csv.DictReader(fh) for name in (r["color"], r["depth"])}
    assert len(listed) == 20
    assert {p.name for p in out.glob("frame_*.png")} == listed
    manifest = json.loads((out / ".dgli-outputs.json").read_text())["files"]
    assert not [n for n in manifest if n.startswith("frame_") and n not in listed]
    # a file the user put there, not listed by the earlier run, is left alone
    (out / "frame_999999_color.png").write_bytes(b"mine")
    edited = out / "frame_000003_color.png"  # listed, then changed by the user: theirs
    edited.write_bytes(edited.read_bytes() + b"\0")
    assert run("extract", bag, out, "--every", "5").exit_code == 0
    assert (out / "frame_999999_color.png").read_bytes() == b"mine"
    assert edited.exists() and len(list(out.glob("frame_*_depth.png"))) == 6
    (out / "frames.csv").write_text(  # the listing names it again; --overwrite removes it
        "color,depth,time\nframe_000003_color.png,frame_000003_depth.png,0.3\n"
    )
    assert run("extract", bag, out, "--every", "5", "--overwrite").exit_code == 0
    assert not edited.exists()
    assert (out / "frame_999999_color.png").read_bytes() == b"mine"  # never listed


def test_a_smaller_render_into_the_same_folder_leaves_no_earlier_pair(tmp_path):
    out = tmp_path / "r"
    assert run("render", out, "--sequence", "I", "--frames", "3", "--seed", "2").exit_code == 0
    edited = out / "I_002_color.png"  # the user's edit of a rendered image: theirs now
    edited.write_bytes(edited.read_bytes() + b"\0")
    assert run("render", out, "--sequence", "I", "--frames", "2", "--seed", "2").exit_code == 0
    on_disk = sorted(p.name for p in out.glob("*.png"))
    assert on_disk == [
        "I_000_color.png", "I_000_depth.png", "I_001_color.png", "I_001_depth.png",
        "I_002_color.png",  # kept: the user's now (--overwrite removes it: see extract)
    ]
    with (out / "labels.csv").open() as fh:
        assert [r["color"] for r in csv.DictReader(fh)] == ["I_000_color.png", "I_001_color.png"]


def test_labels_rows_naming_frames_that_do_not_exist_are_errors(tmp_path):
    bag = _tiny_episode_bag(tmp_path / "ep")
    labels = tmp_path / "labels.csv"
    labels.write_text("frame,label\n" + "".join(f"{k},01\n" for k in range(30)) + "999,02\n")
    line = one_error_line(run("track", bag, "--labels", labels, "-j", "1"))
    assert line == (
        f"error: labels file '{labels}' line 32: frame 999 does not exist; the recording "
        "has 30 frames (0 to 29)"
    )
    by_time = tmp_path / "by_time.csv"
    by_time.write_text("time,label\n" + "".join(f"{k * 0.1:.1f},01\n" for k in range(30))
                       + "12.5,02\n")
    line = one_error_line(run("evaluate", bag, "--labels", by_time, "-j", "1"))
    assert f"labels file '{by_time}' line 32: no frame of the recording within 20 ms of " \
        "time 12.5 s" in line


# --- napkin sizes out of range -------------------------------------------------------------


@pytest.mark.parametrize("command", ["render", "simulate", "stickers"])
@pytest.mark.parametrize("size", ["1e30", "100x1e30", "1e-30", "1001"])
def test_a_size_out_of_range_is_refused_with_the_range(command, size, tmp_path):
    out = tmp_path / ("kit.svg" if command == "stickers" else "out")
    line = one_error_line(run(command, "--size", size, out))
    assert line.startswith("Error: Invalid value for '--size': ")
    assert f"napkin size '{size}'" in line and "each side must be 240 to 1000 mm" in line
    assert not out.exists()
