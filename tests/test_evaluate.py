"""dgli evaluate: a hand-computable small case, broken pairs, -j 1 == -j 2, the report."""

from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest
from click.testing import CliRunner

from dgli_vision.analysis.evaluate import PairOutcome, summarise
from dgli_vision.cli import main
from dgli_vision.sources.labelled import LabelledPair, find_pairs

SAMPLES = Path(__file__).resolve().parent.parent / "sample_images"


def run(args):
    result = CliRunner().invoke(main, ["evaluate", *args])
    assert "Traceback" not in result.output
    return result


@pytest.fixture
def small_folder(tmp_path):
    """5 pairs of 3 classes: one broken, one labelled wrongly (so misclassified)."""
    rows = []
    for name, label, variant in [
        ("01_000", "01", ""),
        ("02_000", "02", "C"),
        ("03_000", "03", "C"),
        ("05_000", "02", "C"),
    ]:
        for kind in ("color", "depth"):
            shutil.copy(SAMPLES / f"{name}_{kind}.png", tmp_path / f"{name}_{kind}.png")
        rows.append((f"{name}_color.png", f"{name}_depth.png", label, variant))
    shutil.copy(SAMPLES / "intrinsics.json", tmp_path / "intrinsics.json")
    (tmp_path / "bad_color.png").write_bytes(b"not an image")
    cv2.imwrite(str(tmp_path / "bad_depth.png"), np.ones((720, 1280), np.uint16))
    rows.append(("bad_color.png", "bad_depth.png", "03", "A"))
    with open(tmp_path / "labels.csv", "w", newline="") as fh:
        csv.writer(fh).writerows([("color", "depth", "label", "variant"), *rows])
    return tmp_path


def test_hand_computable_case(small_folder, tmp_path):
    report = tmp_path / "report"
    result = run([str(small_folder), "--json", "-j", "1", "--report", str(report)])
    assert result.exit_code == 0, result.output
    data = json.loads(result.output.splitlines()[0])
    assert data["n"] == 5 and data["classified"] == 4
    # Correct: 01, 02, 03 (3 of 5); the 05 image labelled 02 is predicted 05.
    assert data["accuracy"] == pytest.approx(3 / 5)
    assert data["variant_accuracy"] == pytest.approx(3 / 5)
    assert data["labels"] == ["01", "02", "03", "05"]
    assert data["confusion"] == [
        [1, 0, 0, 0, 0],
        [0, 1, 0, 1, 0],
        [0, 0, 1, 0, 1],
        [0, 0, 0, 0, 0],
    ]
    # 02: predicted twice? no: once right (precision 1/1), recall 1/2.
    assert data["per_class"]["02"] == {
        "precision": 1.0,
        "recall": 0.5,
        "f1": pytest.approx(0.6667, abs=1e-4),
        "support": 2,
    }
    assert data["per_class"]["03"]["recall"] == 0.5
    assert data["per_class"]["05"] == {"precision": 0.0, "recall": 0.0, "f1": 0.0, "support": 0}
    # failures: the wrong answer and the pair not read; no pair answered "cannot tell"
    wrong, failure = data["failures"]
    assert wrong["color"].endswith("05_000_color.png")
    assert wrong["error"] == "wrong: labelled 02, answered 05"
    assert failure["color"].endswith("bad_color.png") and "not an image" in failure["error"]
    assert data["cannot_tell"] == []
    # The report.
    for name in (
        "report.md",
        "confusion.csv",
        "per_class.csv",
        "summary.json",
        "confusion.png",
        "distances.png",
        "overlays/05_000_overlay.png",
    ):
        assert (report / name).exists(), name
    summary = json.loads((report / "summary.json").read_text())
    assert summary["references_sha256"] and summary["command"].startswith("dgli evaluate")
    assert summary["accuracy"] == data["accuracy"]
    md = (report / "report.md").read_text()
    assert "| 02 corner-over | 0 | 1 | 0 | 1 | 0 | 0 |" in md
    assert "| 03 corner-under | 0 | 0 | 1 | 0 | 0 | 1 |" in md  # not read, not "cannot tell"
    assert "- pairs: **5**: 3 right, 0 cannot tell, 1 wrong, 1 unreadable" in md
    assert "failures" not in md
    confusion = (report / "confusion.csv").read_text().splitlines()
    assert confusion[0].endswith(",cannot tell,not read")
    assert "bad_color.png" in md and "not an image" in md
    per_class = list(csv.DictReader((report / "per_class.csv").read_text().splitlines()))
    assert per_class[1]["class"] == "02" and per_class[1]["recall"] == "0.5"


def test_jobs_1_and_2_give_identical_results(small_folder):
    one = json.loads(run([str(small_folder), "--json", "-j", "1"]).output)
    two = json.loads(run([str(small_folder), "--json", "-j", "2"]).output)
    one.pop("seconds")
    two.pop("seconds")
    assert one == two


def test_plain_output_lists_failures(small_folder):
    result = run([str(small_folder), "-j", "1"])
    assert result.exit_code == 0
    assert "5 pairs: 3 right, 0 cannot tell, 1 wrong, 1 unreadable" in result.output
    assert "failed" not in result.output
    assert "unreadable: " in result.output and "bad_color.png" in result.output
    assert "wrong: " in result.output and "labelled 02, answered 05" in result.output


def test_class_folders_label_pairs(tmp_path):
    for name, folder in [("02_000", "02_corner-over"), ("09_000", "09_strip-over")]:
        (tmp_path / folder / "take1").mkdir(parents=True)
        for kind in ("color", "depth"):
            shutil.copy(
                SAMPLES / f"{name}_{kind}.png", tmp_path / folder / "take1" / f"x_{kind}.png"
            )
    pairs = find_pairs(tmp_path)
    assert [(p.label, Path(p.color).parent.parent.name) for p in pairs] == [
        ("02", "02_corner-over"),
        ("09", "09_strip-over"),
    ]
    data = json.loads(run([str(tmp_path), "--json", "-j", "1"]).output)
    assert data["accuracy"] == 1.0
    assert data["variant_accuracy"] is None  # no pair has a known variant: nothing to score


def test_folder_errors_are_one_line(tmp_path):
    result = run([str(tmp_path / "missing")])
    assert result.exit_code == 2 and "does not exist" in result.output
    (tmp_path / "labels.csv").write_text("a,b\n1,2\n")
    result = run([str(tmp_path)])
    assert result.exit_code == 2 and "lacks column(s) color, depth, label" in result.output
    assert result.output.strip().count("\n") == 0


def test_summary_of_outcomes_without_images():
    pair = LabelledPair("a_color.png", "a_depth.png", "04", "AB")
    outs = [
        PairOutcome(pair, "04", "AB", 0.1),
        PairOutcome(pair, "04", "BC", 0.2),
        PairOutcome(pair, error="broken"),
    ]
    s = summarise(outs, 1.0)
    assert s.accuracy == round(2 / 3, 4) and s.variant_accuracy == round(1 / 3, 4)
    assert s.confusion == [[2, 1]]


def test_workers_start_cleanly_after_threads_in_the_parent():
    # The parent has run Open3D's raycaster and threaded PNG decoding; forked workers
    # could inherit a held lock and hang. Workers are spawned.
    from dgli_vision.analysis.evaluate import evaluate_pairs
    from dgli_vision.classifier.references import load_references
    from dgli_vision.core.camera import look_at_table
    from dgli_vision.sim.cloth import sample_state
    from dgli_vision.sim.render import SensorModel, render
    from dgli_vision.sources.frames import read_frame

    render(sample_state("01", rng=0), look_at_table(0.5), sensor=SensorModel(enabled=False))
    pairs = find_pairs(SAMPLES)[:3]
    read_frame(pairs[0].color, pairs[0].depth)
    outs = list(evaluate_pairs(pairs, load_references(), jobs=2))
    assert [o.predicted for o in outs] == [p.label for p in pairs]


def test_the_workers_stay_up_between_batches_with_the_same_references():
    from dgli_vision.analysis import evaluate
    from dgli_vision.classifier.references import load_references

    pairs = find_pairs(SAMPLES)
    refs = load_references()
    first = list(evaluate.evaluate_pairs(pairs, refs, jobs=2, distances=True))
    pool = evaluate._POOL[1]
    again = list(evaluate.evaluate_pairs(pairs[::-1], refs, jobs=2, distances=True))
    assert evaluate._POOL[1] is pool  # not started again
    # in input order, the same outcomes as in one process, whoever classified each pair
    alone = list(evaluate.evaluate_pairs(pairs, refs, jobs=1, distances=True))

    def as_json(outcomes):  # NaN (unknown coordinates) compares equal as JSON text
        return [json.dumps(o.to_json()) + str(o.distances) for o in outcomes]

    assert as_json(first) == as_json(alone) and as_json(again) == as_json(alone[::-1])
    other = load_references()  # another set: the workers must not keep the old one
    list(evaluate.evaluate_pairs(pairs[:2], other, jobs=2))
    assert evaluate._POOL[1] is not pool


def test_the_tail_of_a_batch_is_taken_back_from_a_busy_worker():
    """At the end of a batch this process takes back the queued pairs no worker has
    started (the latest first), and leaves running ones alone."""
    from concurrent.futures import Future

    from dgli_vision.analysis.evaluate import _take_back

    running, queued_early, queued_late = Future(), Future(), Future()
    running.set_running_or_notify_cancel()
    pending = {running: 3, queued_early: 4, queued_late: 5}
    assert _take_back(pending) == 5
    assert queued_late.cancelled() and queued_late not in pending
    assert _take_back(pending) == 4
    assert _take_back(pending) is None  # only the running pair is left
    assert pending == {running: 3} and not running.cancelled()


def test_cannot_tell_is_counted_as_an_answer_apart_from_unreadable_pairs(tmp_path):
    """Right, "cannot tell", wrong and unreadable are four counts (text, JSON, report);
    coverage and the accuracy of the answers given follow from them."""
    from dgli_vision.sim.dataset import render_sample
    from dgli_vision.sources.labelled import write_labelled_folder

    clean = render_sample("02", 0, 9090)
    held = render_sample("01", 0, 9090, conditions=("gripper",))  # a corner under it
    labels = write_labelled_folder(tmp_path / "set", [clean, held], {"command": "test"})
    (labels.parent / "bad_depth.png").write_bytes(b"not a png")
    with labels.open("a", newline="") as f:
        csv.writer(f).writerow([f"{clean.name}_color.png", "bad_depth.png", "02", "A"])
    report = tmp_path / "report"
    as_json = run([str(labels.parent), "--json", "-j", "1", "--lenient"])
    data = json.loads(as_json.output)
    assert data["outcomes"] == {"right": 1, "cannot_tell": 1, "wrong": 0, "unreadable": 1}
    assert data["coverage"] == 0.5 and data["accuracy_answered"] == 1.0
    text = run([str(labels.parent), "-j", "1", "--lenient", "--report", str(report)])
    assert "3 pairs: 1 right, 1 cannot tell, 0 wrong, 1 unreadable; answered 50% of the " \
        "pairs read, 100.00% of the answers right" in text.output
    assert "right 1, cannot tell 1, wrong 0" not in text.output  # the counts said once
    md = (report / "report.md").read_text()
    told = md.split("## Cannot tell")[1].split("## Not read")
    assert held.name in told[0] and "bad_depth.png" not in told[0]
    assert "bad_depth.png" in told[1]
    # its overlay shows where the stickers under the gripper would be (orange: unknown)
    (overlay,) = (report / "overlays").glob(f"{held.name}*.png")
    drawn = cv2.imread(str(overlay))
    assert np.all(drawn == (0, 140, 255), axis=2).sum() > 20


def test_the_html_report_is_one_page_whose_images_all_exist(tmp_path):
    """report.html: well-formed, the outcome counts, and every image it shows (the
    confusion, the overlays of the wrong and "cannot tell" pairs) is in the folder."""
    from html.parser import HTMLParser

    from dgli_vision.sim.dataset import render_sample
    from dgli_vision.sources.labelled import write_labelled_folder

    samples = [render_sample("02", 0, 9090), render_sample("01", 0, 9090, conditions=("gripper",))]
    labels = write_labelled_folder(tmp_path / "set", samples, {"command": "test"})
    report = tmp_path / "report"
    res = run([str(labels.parent), "-j", "1", "--report", str(report)])
    assert res.exit_code == 0
    assert f"report written to {report / 'report.html'}" in res.stderr  # the page named
    page = (report / "report.html").read_text()

    class Page(HTMLParser):
        def __init__(self) -> None:
            super().__init__()
            self.images: list[str] = []
            self.open: list[str] = []

        def handle_starttag(self, tag, attrs):
            if tag == "img":
                self.images.append(dict(attrs)["src"])
            elif tag not in {"meta", "br", "line", "rect", "polyline", "text"}:
                self.open.append(tag)

        def handle_endtag(self, tag):
            if tag in {"line", "rect", "polyline", "text"}:
                return
            assert self.open and self.open.pop() == tag, tag

    parser = Page()
    parser.feed(page)
    assert parser.open == []  # every element closed, in order
    # the charts are Matplotlib's SVG, each linking to the same chart as PNG
    assert parser.images == ["confusion.svg", "risk_coverage.svg",
                             "overlays/01_000_overlay.png", "distances.svg"]
    assert all((report / src).is_file() for src in parser.images)
    for chart in ("confusion", "risk_coverage", "distances"):
        assert f'<a href="{chart}.png">' in page and (report / f"{chart}.png").is_file()
        svg = (report / f"{chart}.svg").read_text()
        assert "matplotlib" in svg.lower() and 'id="xtick_1"' in svg  # axes with ticks
    assert ">predicted class<" in (report / "confusion.svg").read_text()
    assert "right 1, cannot tell 1, wrong 0, unreadable 0" in page


def test_a_bug_met_on_one_pair_is_that_pairs_failure_and_the_batch_goes_on(
    small_folder, monkeypatch
):
    from dgli_vision.classifier import pipeline

    real = pipeline.classify_frame

    def buggy(frame, *args, **kwargs):
        if "02_000" in frame.color_path:
            raise ZeroDivisionError("division by zero")
        return real(frame, *args, **kwargs)

    monkeypatch.setattr(pipeline, "classify_frame", buggy)
    data = json.loads(run([str(small_folder), "--json", "-j", "1"]).output.splitlines()[0])
    assert data["n"] == 5 and data["classified"] == 3  # the three others as before
    errors = {Path(f["color"]).name: f["error"] for f in data["failures"]}
    bad = errors["02_000_color.png"]
    assert "internal error (ZeroDivisionError: division by zero)" in bad
    assert "please report it" in bad and "labels.csv line" in bad and "\n" not in bad
