"""Run integrity: a resume continues the same run or nothing, one run per report folder,
reports linear in the pairs, JSON that other readers accept, honest exit codes, and
conflicts found before the work."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from dgli_vision.analysis import evaluate as evaluate_module
from dgli_vision.analysis.evaluate import PairOutcome, summarise
from dgli_vision.classifier.references import default_references_path
from dgli_vision.cli import main
from dgli_vision.core.run_lock import LOCK_NAME
from dgli_vision.sources.labelled import LabelledPair

SAMPLES = Path(__file__).resolve().parent.parent / "sample_images"


def run(*args: str):
    result = CliRunner().invoke(main, list(args))
    assert "Traceback" not in result.output, result.output
    return result


def strict_json(line: str):
    """JSON as any reader other than Python's takes it: NaN and Infinity are errors."""

    def refuse(name: str):
        raise ValueError(f"{name} is not JSON")

    return json.loads(line, parse_constant=refuse)


@pytest.fixture
def folder(tmp_path) -> Path:
    """Two labelled pairs (one with a sticker hidden by a fold)."""
    out = tmp_path / "pairs"
    out.mkdir()
    rows = ["color,depth,label,variant"]
    for name, label, variant in [("01_000", "01", ""), ("05_000", "05", "AB/B")]:
        for kind in ("color", "depth"):
            shutil.copy(SAMPLES / f"{name}_{kind}.png", out / f"{name}_{kind}.png")
        rows.append(f"{name}_color.png,{name}_depth.png,{label},{variant}")
    (out / "labels.csv").write_text("\n".join(rows) + "\n")
    shutil.copy(SAMPLES / "intrinsics.json", out / "intrinsics.json")
    return out


@pytest.fixture
def done_run(folder, tmp_path) -> Path:
    report = tmp_path / "report"
    r = run("evaluate", str(folder), "--report", str(report), "-j", "1")
    assert r.exit_code == 0, r.output
    return report


def no_classifying(monkeypatch):
    def refuse(*args, **kwargs):
        raise AssertionError("classified before checking its outputs")

    monkeypatch.setattr(evaluate_module, "evaluate_pairs", refuse)


# --- a resume is the same run or nothing ---------------------------------------------


def test_resume_after_references_changed_is_refused(folder, done_run, tmp_path):
    other = tmp_path / "other.json"
    data = json.loads(default_references_path().read_text())
    data["provenance"] = {**data.get("provenance", {}), "note": "rebuilt"}
    other.write_text(json.dumps(data))
    before = (done_run / "results.jsonl").read_bytes()
    r = run(
        "evaluate", str(folder), "--report", str(done_run), "--resume", "--references", str(other)
    )
    assert r.exit_code == 2
    assert len(r.output.strip().splitlines()) == 1
    assert "reference set changed" in r.output and "results.jsonl" in r.output
    assert (done_run / "results.jsonl").read_bytes() == before


def test_resume_after_labels_edited_is_refused(folder, done_run):
    labels = folder / "labels.csv"
    labels.write_text(labels.read_text().replace(",05,AB/B", ",02,A"))
    r = run("evaluate", str(folder), "--report", str(done_run), "--resume")
    assert r.exit_code == 2 and "labels changed" in r.output
    summary = json.loads((done_run / "summary.json").read_text())
    assert summary["labels"] == ["01", "05"]  # the report still tells of the run it had


def test_resume_of_results_that_record_no_run_is_refused(folder, tmp_path):
    report = tmp_path / "report"
    report.mkdir()
    (report / "results.jsonl").write_text('{"anything": 1}\n')
    r = run("evaluate", str(folder), "--report", str(report), "--resume")
    assert r.exit_code == 2 and "does not record which run wrote it" in r.output


def test_resume_into_a_folder_with_a_users_per_class_csv_keeps_it(folder, done_run, monkeypatch):
    mine = "class,my own notes\n"
    (done_run / "per_class.csv").write_text(mine)
    no_classifying(monkeypatch)
    r = run("evaluate", str(folder), "--report", str(done_run), "--resume")
    assert r.exit_code == 2 and "per_class.csv" in r.output and "refusing" in r.output
    assert (done_run / "per_class.csv").read_text() == mine


def test_resume_of_the_same_run_after_a_half_written_line_goes_on(folder, done_run):
    results = done_run / "results.jsonl"
    lines = results.read_text().splitlines(keepends=True)
    results.write_text(lines[0] + lines[1] + lines[2][:40])  # killed while writing
    r = run("evaluate", str(folder), "--report", str(done_run), "--resume", "-j", "1")
    assert r.exit_code == 0, r.output
    kept = [strict_json(line) for line in results.read_text().splitlines()]
    assert len(kept) == 3 and kept[0]["format"] == "dgli-run"
    assert json.loads((done_run / "summary.json").read_text())["n"] == 2


# --- one run per report folder --------------------------------------------------------


def test_a_second_run_into_a_busy_report_folder_is_refused_naming_the_first(
    folder, tmp_path, monkeypatch
):
    report = tmp_path / "report"
    holder = subprocess.Popen(  # another process at work in the folder
        [
            sys.executable,
            "-c",
            "import sys, time; from dgli_vision.core.run_lock import RunLock\n"
            f"with RunLock({str(report)!r}, 'dgli evaluate (the first run)'):\n"
            "    print('held', flush=True); time.sleep(60)",
        ],
        stdout=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONPATH": str(SAMPLES.parent)},
    )
    try:
        assert holder.stdout.readline().strip() == "held"
        no_classifying(monkeypatch)
        r = run("evaluate", str(folder), "--report", str(report), "--resume")
        t = run("track", str(folder), "--report", str(report))
    finally:
        holder.kill()
        holder.wait()
        holder.stdout.close()
    assert r.exit_code == 2 and f"pid {holder.pid}" in r.output
    assert "in use by another dgli run" in r.output and "the first run" in r.output
    assert len(r.output.strip().splitlines()) == 1
    assert t.exit_code == 2 and f"pid {holder.pid}" in t.output
    assert not (report / "results.jsonl").exists()
    monkeypatch.undo()  # classifying allowed again
    # its lock died with it: the folder is free, the run goes through
    again = run("evaluate", str(folder), "--report", str(report), "-j", "1")
    assert again.exit_code == 0, again.output
    assert "in use" not in again.output and again.exception is None
    assert json.loads((report / "summary.json").read_text())["n"] == 2
    assert not (report / LOCK_NAME).exists()


def test_a_stale_lock_of_a_killed_run_is_taken_over_and_released(folder, tmp_path):
    report = tmp_path / "report"
    report.mkdir()
    gone = subprocess.Popen([sys.executable, "-c", "pass"])
    gone.wait()
    (report / LOCK_NAME).write_text(json.dumps({"pid": gone.pid, "command": "dgli evaluate"}))
    r = run("evaluate", str(folder), "--report", str(report), "-j", "1")
    assert r.exit_code == 0, r.output
    assert f"took over the lock of a run that ended without releasing it (pid {gone.pid})" in (
        r.output
    )
    assert not (report / LOCK_NAME).exists()


# --- results other readers accept, honest exit codes ----------------------------------


def test_results_jsonl_holds_no_bare_nan(folder, done_run):
    items = [strict_json(line) for line in (done_run / "results.jsonl").read_text().splitlines()]
    coordinates = [c for item in items[1:] for c in item["coordinates"]]
    assert None in coordinates  # a coordinate of a hidden sticker's segment: null
    strict_json((done_run / "summary.json").read_text())


def test_evaluate_exits_non_zero_when_every_pair_failed(tmp_path):
    (tmp_path / "labels.csv").write_text(
        "color,depth,label,variant\na_color.png,a_depth.png,01,\nb_color.png,b_depth.png,02,A\n"
    )
    report = tmp_path / "report"
    r = run("evaluate", str(tmp_path), "--report", str(report), "-j", "1")
    assert r.exit_code == 2
    assert "error: none of the 2 pairs could be read" in r.output
    assert json.loads((report / "summary.json").read_text())["n"] == 2  # still reported


def test_evaluate_report_conflict_is_found_before_any_classifying(folder, tmp_path, monkeypatch):
    report = tmp_path / "report"
    report.mkdir()
    (report / "confusion.csv").write_text("my own table\n")
    no_classifying(monkeypatch)
    r = run("evaluate", str(folder), "--report", str(report))
    assert r.exit_code == 2 and "confusion.csv" in r.output


@pytest.mark.parametrize("name", ["timeline.csv", "timeline.png", "distances.png"])
def test_track_report_conflict_is_found_before_any_classifying(
    folder, tmp_path, monkeypatch, name
):
    report = tmp_path / "report"
    report.mkdir()
    (report / name).write_text("mine\n")
    no_classifying(monkeypatch)
    r = run("track", str(folder), "--report", str(report))
    assert r.exit_code == 2 and name in r.output


# --- reports linear in the pairs -------------------------------------------------------


def test_report_of_many_pairs_draws_a_sample_not_all_pairs(monkeypatch):
    from dgli_vision.analysis import evaluation_report

    sizes = []
    real = evaluation_report.sample_distance_matrix

    def spy(coords):
        sizes.append(len(coords))
        return real(coords)

    monkeypatch.setattr(evaluation_report, "sample_distance_matrix", spy)
    rng = np.random.default_rng(5)
    outcomes = [
        PairOutcome(
            LabelledPair(f"{k:05d}_color.png", f"{k:05d}_depth.png", label),
            label,
            coordinates=tuple(rng.normal(size=28)),
        )
        for k, label in enumerate(["01"] * 1500 + ["02"] * 20 + ["05"] * 480)
    ]
    files = evaluation_report.build_report(summarise(outcomes, 1.0), {}, None)
    assert sizes == [evaluation_report.HEATMAP_MAX]
    assert "300 of 2,000 samples" in files["report.md"]
    assert "distances.png" in files


# --- an interrupted render keeps its pairs and resumes ----------------------------------


def stopping_after(monkeypatch, n: int, how):
    """Make the next render stop (``how()``) when ``n`` frames are done."""
    from dgli_vision.sim import dataset

    real = dataset.render_sequence

    def stopped(*args, **kwargs):
        for k, sample in enumerate(real(*args, **kwargs)):
            yield sample
            if k + 1 == n:  # asked for the next one
                how()

    monkeypatch.setattr(dataset, "render_sequence", stopped)


def sigterm():
    import signal

    os.kill(os.getpid(), signal.SIGTERM)


def folder_content(folder: Path) -> dict[str, bytes]:
    return {
        p.name: p.read_bytes()
        for p in sorted(folder.iterdir())
        if p.name not in (".dgli-outputs.json", "truth.json")
    }


def test_interrupted_render_keeps_complete_pairs_and_resumes(tmp_path, monkeypatch):
    # VGA frames: a quarter of the pixels to render
    args = ["--sequence", "III", "--frames", "3", "--conditions", "vga", "--seed", "2"]
    whole, out = tmp_path / "whole", tmp_path / "out"
    assert run("render", str(whole), *args).exit_code == 0
    with monkeypatch.context() as m:
        stopping_after(m, 2, sigterm)
        r = run("render", str(out), *args)
    assert r.exit_code == 143
    assert "interrupted: 2 of 3 pairs written" in r.output and "--resume" in r.output
    labels = (out / "labels.csv").read_text().splitlines()
    assert labels[1:] == [f"III_00{k}_color.png,III_00{k}_depth.png,01," for k in range(2)]
    assert sorted(p.name for p in out.glob("*.png")) == sorted(
        f"III_00{k}_{kind}.png" for k in range(2) for kind in ("color", "depth")
    )
    other = run("render", str(out), *args[:-1], "3", "--resume")
    assert other.exit_code == 2 and "option seed changed" in other.output
    r = run("render", str(out), *args, "--resume")
    assert r.exit_code == 0, r.output
    assert "resuming: 2 of 3 pairs kept" in r.output
    assert folder_content(out) == folder_content(whole)
    truth = json.loads((out / "truth.json").read_text())
    assert list(truth["images"]) == [f"III_00{k}" for k in range(3)]


def test_the_heatmap_distances_are_the_pairwise_spearman_distances():
    from dgli_vision.analysis.evaluation_report import sample_distance_matrix
    from dgli_vision.core.distance import spearman_distance

    rng = np.random.default_rng(3)
    x = np.round(rng.normal(size=(40, 28)), 1)  # ties too
    hidden = [rng.random(28) < 0.2 for _ in range(4)] + [np.zeros(28, bool)]
    for k in range(40):
        x[k, hidden[k % 5]] = np.nan
    x[3, :26] = np.nan  # too little in common with anything
    x[4] = 1.0  # all equal: correlates with nothing
    d = sample_distance_matrix(x)
    for a in range(40):
        for b in range(40):
            want = 0.0 if a == b and a != 3 else spearman_distance(x[a], x[b], omit_nan=True)
            assert d[a, b] == pytest.approx(want, abs=1e-12, nan_ok=True), (a, b)
