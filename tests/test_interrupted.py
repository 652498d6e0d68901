"""Interrupted batches keep their work: Ctrl-C or a kill, then --resume, gives the report
of an uninterrupted run."""

from __future__ import annotations

import csv
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from click.testing import CliRunner

from dgli_vision.cli import main

SAMPLES = Path(__file__).resolve().parent.parent / "sample_images"
ROOT = Path(__file__).resolve().parent.parent
# the package of this checkout (an installed `dgli` may run another copy)
DGLI = [sys.executable, "-m", "dgli_vision"]
ENV = {**os.environ, "PYTHONPATH": str(ROOT)}
COPIES = 2  # 24 pairs: long enough to interrupt (after 4) on one core


@pytest.fixture(scope="module")
def batch(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("batch")
    with open(SAMPLES / "labels.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    out = ["color,depth,label,variant"]
    for c in range(COPIES):
        for row in rows:
            color, depth = f"c{c}_{row['color']}", f"c{c}_{row['depth']}"
            # copies: a hard link (as a symbolic one) is the same pair, listed twice
            shutil.copyfile(SAMPLES / row["color"], folder / color)
            shutil.copyfile(SAMPLES / row["depth"], folder / depth)
            out.append(f"{color},{depth},{row['label']},{row['variant']}")
    (folder / "labels.csv").write_text("\n".join(out) + "\n")
    os.link(SAMPLES / "intrinsics.json", folder / "intrinsics.json")
    return folder


def lines(path: Path) -> int:
    """Pairs in a results.jsonl (its first line records the run)."""
    return sum('"pair"' in line for line in path.read_text().splitlines()) if path.exists() else 0


def interrupt(args: list[str], results: Path, sig: int) -> subprocess.CompletedProcess:
    """Run dgli, and send ``sig`` once a few results are on disk."""
    proc = subprocess.Popen(
        [*DGLI, *args],
        env=ENV,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        # as from a terminal: a shell may start background jobs with Ctrl-C ignored,
        # and the test runner, and so dgli, would inherit that
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    deadline = time.monotonic() + 120
    while lines(results) < 4 and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.01)
    assert proc.poll() is None, "the batch ended before it could be interrupted"
    proc.send_signal(sig)
    out, err = proc.communicate(timeout=120)
    return subprocess.CompletedProcess(proc.args, proc.returncode, out, err)


def in_process(args: list[str]):
    """dgli in this process (click's runner): the runs that are not about a process of
    their own (the whole run, the refused rerun, the resume) skip the interpreter's and
    the libraries' start-up. ``output`` holds stderr as well."""
    return CliRunner().invoke(main, args)


def comparable(report: Path) -> dict:
    summary = json.loads((report / "summary.json").read_text())
    for volatile in ("seconds", "command", "jobs"):
        summary.pop(volatile)
    return {
        "summary": summary,
        "confusion": (report / "confusion.csv").read_text(),
        "per_class": (report / "per_class.csv").read_text(),
    }


@pytest.fixture(scope="module")
def uninterrupted(batch, tmp_path_factory) -> dict:
    report = tmp_path_factory.mktemp("whole") / "report"
    res = in_process(["evaluate", str(batch), "--report", str(report), "-j", "1"])
    assert res.exit_code == 0, res.output
    return comparable(report)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGKILL], ids=["SIGINT", "SIGKILL"])
def test_an_interrupted_batch_resumes_to_the_same_report(batch, uninterrupted, tmp_path, sig):
    report = tmp_path / "report"
    results = report / "results.jsonl"
    args = ["evaluate", str(batch), "--report", str(report), "-j", "1"]
    res = interrupt(args, results, sig)
    done = lines(results)
    assert 4 <= done < 12 * COPIES
    if sig == signal.SIGINT:
        assert res.returncode == 130
        assert f"interrupted: {done} of {12 * COPIES} pairs done" in res.stderr
        assert "--resume" in res.stderr and "Traceback" not in res.stderr
        partial = json.loads((report / "summary.json").read_text())
        assert partial["n"] == done  # the report of what is done
    else:
        assert res.returncode == -signal.SIGKILL
    again = in_process(args)
    assert again.exit_code == 2 and "--resume" in again.output  # never silently redone
    resumed = in_process([*args, "--resume"])
    assert resumed.exit_code == 0, resumed.output
    assert lines(results) == 12 * COPIES
    assert comparable(report) == uninterrupted


def test_ctrl_c_with_workers_stops_cleanly(batch, tmp_path):
    report = tmp_path / "report"
    args = ["evaluate", str(batch), "--report", str(report), "-j", "2"]
    res = interrupt(args, report / "results.jsonl", signal.SIGINT)
    assert res.returncode == 130 and "Traceback" not in res.stderr
    assert (report / "report.md").is_file()


def test_sigterm_on_evaluate_writes_the_report_of_what_is_done(batch, tmp_path):
    report = tmp_path / "report"
    args = ["evaluate", str(batch), "--report", str(report), "-j", "1"]
    res = interrupt(args, report / "results.jsonl", signal.SIGTERM)
    assert res.returncode == 143 and "Traceback" not in res.stderr
    done = lines(report / "results.jsonl")
    assert f"interrupted: {done} of {12 * COPIES} pairs done" in res.stderr
    assert json.loads((report / "summary.json").read_text())["n"] == done


@pytest.fixture(scope="module")
def recording(batch, tmp_path_factory) -> Path:
    """The first 24 pairs of the batch as the frames of a recording (a folder)."""
    folder = tmp_path_factory.mktemp("recording")
    rows = (batch / "labels.csv").read_text().splitlines()[: 1 + FRAMES]
    for row in rows[1:]:
        for name in row.split(",")[:2]:
            os.link(batch / name, folder / name)
    (folder / "labels.csv").write_text("\n".join(rows) + "\n")
    os.link(batch / "intrinsics.json", folder / "intrinsics.json")
    return folder


FRAMES = 24


@pytest.mark.parametrize("sig, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_interrupted_track_keeps_its_frames_and_resumes(recording, tmp_path, sig, code):
    report = tmp_path / "report"
    results = report / "results.jsonl"
    args = ["track", str(recording), "--report", str(report), "-j", "1"]
    res = interrupt(args, results, sig)
    assert res.returncode == code, res.stderr
    assert "Traceback" not in res.stderr and "Aborted" not in res.stderr
    done = lines(results)
    assert f"interrupted: {done} of {FRAMES} frames done" in res.stderr
    partial = json.loads((report / "timeline.json").read_text())
    assert partial["n_frames"] == done and partial["interrupted"]["frames_done"] == done
    if sig == signal.SIGINT:
        return
    resumed = in_process([*args, "--resume"])
    assert resumed.exit_code == 0, resumed.output
    assert lines(results) == FRAMES  # the frames done before were not classified again
    whole = json.loads((report / "timeline.json").read_text())
    assert whole["n_frames"] == FRAMES and "interrupted" not in whole


def test_a_stop_signal_never_cuts_a_kept_result_in_two():
    # The journal line and the count of a result are kept together: a Ctrl-C (or
    # SIGTERM) that comes between them interrupts only once both are done.
    import os

    from dgli_vision.cli.runs import stop_signals

    for sig, code in ((signal.SIGINT, 130), (signal.SIGTERM, 143)):
        kept = []
        with stop_signals() as stop:
            with pytest.raises(KeyboardInterrupt):
                with stop.holding():
                    kept.append("journal")
                    os.kill(os.getpid(), sig)
                    for _ in range(1000):  # the handler runs at the next bytecodes
                        pass
                    kept.append("count")
        assert kept == ["journal", "count"]
        assert stop.stopped and stop.exit_code == code


def test_a_stop_that_lands_inside_a_c_function_still_counts_as_the_stop():
    """A signal during a C call (np.fromfile checking its path) surfaces as a SystemError
    around the handler's KeyboardInterrupt: that is the stop, kept as such, not a crash."""
    from dgli_vision.cli.runs import Stop

    stop = Stop()
    try:
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as inner:
            raise SystemError("fspath returned a result with an exception set") from inner
    except SystemError as exc:
        wrapped = exc
    assert not stop.cut_short(wrapped)  # no stop came: a real error, raised on
    stop.stopped = True
    assert stop.cut_short(wrapped) and stop.cut_short(KeyboardInterrupt())
    assert not stop.cut_short(SystemError("something else"))


def listed_pairs(folder: Path) -> list[str]:
    """The colour images a labels.csv lists (none when there is no labels.csv yet)."""
    labels = folder / "labels.csv"
    if not labels.exists():
        return []
    with labels.open(newline="") as fh:
        return [row["color"] for row in csv.DictReader(fh)]


#: A recording's frames (rendered in one process), and a set of single pairs over workers
#: (six states outside the twelve: the path of a class set, half its pairs); VGA: a
#: quarter of the pixels to render
RENDERS = {
    "sequence": ["--sequence", "III", "--frames", "6", "--conditions", "vga", "--seed", "4"],
    "pairs-j2": [
        "--per-class", "0", "--outside", "6", "--conditions", "vga", "--seed", "4", "-j", "2",
    ],
}


@pytest.mark.parametrize("kind", list(RENDERS))
def test_a_killed_render_keeps_its_finished_pairs_and_resumes(tmp_path, kind):
    """SIGKILL in the middle of a render (the pairs were written only at the end: 0 kept,
    --resume rendered everything again): every pair finished is kept, listed in a
    labels.csv that names only complete pairs, and --resume renders only the rest."""
    args = RENDERS[kind]
    whole, out = tmp_path / "whole", tmp_path / "out"
    proc = subprocess.Popen([*DGLI, "render", str(out), *args], env=ENV,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while len(listed_pairs(out)) < 2 and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.01)
    assert proc.poll() is None, "the render ended before it could be killed"
    proc.kill()
    proc.communicate(timeout=60)
    assert proc.returncode == -signal.SIGKILL
    kept = listed_pairs(out)
    n = 6
    assert 2 <= len(kept) < n
    assert in_process(["render", str(whole), *args]).exit_code == 0
    for color in kept:  # each listed pair complete, as the whole render wrote it
        for name in (color, color.replace("_color", "_depth")):
            assert (out / name).read_bytes() == (whole / name).read_bytes()
    resumed = in_process(["render", str(out), *args, "--resume"])
    assert resumed.exit_code == 0, resumed.output
    assert f"resuming: {len(kept)} of {n} pairs kept" in resumed.output
    assert listed_pairs(out) == listed_pairs(whole)
    listings = ["labels.csv", "frames.csv"] if kind == "sequence" else ["labels.csv"]
    for name in (*listings, *(p.name for p in whole.glob("*.png"))):
        assert (out / name).read_bytes() == (whole / name).read_bytes(), name
