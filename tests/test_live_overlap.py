"""The live path's decoding (issue 40): played as fast as classified, each frame is
decoded by the capture thread while the worker classifies the one before; a RealSense
frame's depth in another unit is converted by a table exactly as by the formula."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest


class _Pair:
    """A frame whose ``load`` notes the thread that decoded it and when."""

    def __init__(self, k: int, frame: object, log: list) -> None:
        self.time, self.frame, self.log, self.k = k / 30, frame, log, k

    def load(self) -> object:
        self.log.append(("load", self.k, threading.current_thread().name, time.perf_counter()))
        time.sleep(0.05)  # decoding takes a while
        return self.frame


def test_fast_decodes_the_next_frame_while_one_is_classified(monkeypatch) -> None:
    from dgli_vision.analysis import live

    log: list = []

    def classify(pair, references, colours=None):
        frame = pair.load()
        log.append(("start", frame, threading.current_thread().name, time.perf_counter()))
        time.sleep(0.05)
        log.append(("end", frame, threading.current_thread().name, time.perf_counter()))
        return frame, None, None, None, (), "test"

    monkeypatch.setattr(live, "classify_live", classify)
    monkeypatch.setattr(live, "OnlineSmoother", _Smoother)
    summary = live.watch([_Pair(k, k, log) for k in range(4)], None, realtime=False)
    assert summary.classified == 4 and summary.dropped == 0
    loads = [e for e in log if e[0] == "load"]
    assert {e[2] for e in loads} == {"dgli-capture"}  # decoded by the capture thread
    # frame 1's decoding began before frame 0's classifying ended
    end0 = next(e[3] for e in log if e[0] == "end" and e[1] == 0)
    load1 = next(e[3] for e in loads if e[1] == 1)
    assert load1 < end0


class _Smoother:
    def __init__(self, *a, **k) -> None:
        pass

    def update(self, distances):
        return ("01", None)

    def path(self):
        return []


@pytest.mark.parametrize("scale_m", [1e-4, 9.999999747378752e-05, 2.5e-4, 5e-4, 2e-3])
def test_a_depth_unit_table_gives_the_formula_s_depths(scale_m) -> None:
    from dgli_vision.sources.realsense import _depth_table

    raw = np.arange(65536, dtype=np.uint16)
    want = np.clip(np.rint(raw.astype(np.float32) * np.float32(scale_m * 1000.0)), 0, 65535)
    assert np.array_equal(_depth_table(scale_m), want.astype(np.uint16))


@pytest.mark.parametrize("fmt", ["rgb8", "bgr8", "rgba8", "bgra8"])
def test_colour_frames_of_every_format_read_as_rgb(fmt) -> None:
    from dgli_vision.sources.realsense import _COLOUR_FORMATS, _colour_array

    rng = np.random.default_rng(1)
    n = 4 if fmt.endswith("a8") else 3
    pixels = rng.integers(0, 256, (5, 7, n), dtype=np.uint8)

    class Frame:
        def get_profile(self):
            return self

        def format(self):
            return f"format.{fmt}"

        def get_data(self):
            return pixels

    got = _colour_array(None, Frame())
    assert got.flags["C_CONTIGUOUS"] and got.dtype == np.uint8
    assert np.array_equal(got, pixels[:, :, list(_COLOUR_FORMATS[fmt])])


def test_live_takes_the_pipelines_distances(monkeypatch) -> None:
    """classify_live gives the distances the pipeline ranked the references by, without
    working them out a second time (they are the same figures)."""
    from pathlib import Path

    from dgli_vision.analysis import live
    from dgli_vision.classifier import classify
    from dgli_vision.classifier.pipeline import classify_frame
    from dgli_vision.classifier.references import load_references
    from dgli_vision.sources.frames import read_frame, read_intrinsics

    root = Path(__file__).resolve().parents[1] / "sample_images"
    intr = read_intrinsics(root / "intrinsics.json")
    frame = read_frame(root / "05_000_color.png", root / "05_000_depth.png", intr)
    refs = load_references(None)
    want = classify_frame(frame, refs).distances
    assert want is not None

    class _Loaded:
        time = 0.0

        def load(self):
            return frame

    def again(*args, **kwargs):
        raise AssertionError("distances worked out a second time")

    monkeypatch.setattr(classify, "reference_distances", again)
    _, _, _, _, got, _ = live.classify_live(_Loaded(), refs)
    assert got == tuple(round(float(v), 6) for v in want)


def test_at_the_recorded_pace_the_capture_thread_decodes(monkeypatch) -> None:
    """At the recorded pace too, a frame is decoded as it comes (by the capture thread),
    so that one waiting while the worker is busy is ready when the worker takes it."""
    from dgli_vision.analysis import live

    log: list = []

    def classify(pair, references, colours=None):
        frame = pair.load()
        time.sleep(0.05)
        return frame, None, None, None, (), "test"

    monkeypatch.setattr(live, "classify_live", classify)
    monkeypatch.setattr(live, "OnlineSmoother", _Smoother)
    summary = live.watch([_Pair(k, k, log) for k in range(3)], None, realtime=True)
    assert summary.classified + summary.dropped == 3
    assert {e[2] for e in log if e[0] == "load"} == {"dgli-capture"}


def test_worker_processes_give_the_answers_of_one_thread_in_frame_order() -> None:
    """-j 2: the frames are classified in two worker processes, side by side; the
    answers are reported in frame order and are those of the in-process worker (states,
    confidences, the whole path); a failing ``on_update`` (a closed pipe) stops the run
    and is raised, the processes ended."""
    from pathlib import Path

    from dgli_vision.analysis import live
    from dgli_vision.classifier.references import load_references
    from dgli_vision.sources.recording import read_recording

    refs = load_references(None)
    samples = Path(__file__).parent.parent / "sample_images"
    pairs = list(read_recording(samples).frames)[:4]
    got: dict[int, list] = {1: [], 2: []}
    summaries = {}
    for jobs in (1, 2):
        summaries[jobs] = live.watch(
            pairs, refs, jobs=jobs,
            on_update=lambda u, f, r, jobs=jobs: got[jobs].append(
                (u.frame, u.state, u.confidence, u.smoothed, (f is None, r is None))
            ),
        )
    assert [g[0] for g in got[2]] == list(range(4))
    assert [g[:4] for g in got[2]] == [g[:4] for g in got[1]]
    assert any(g[1] is not None for g in got[2])
    assert {g[4] for g in got[1]} == {(False, False)} and {g[4] for g in got[2]} == {(True, True)}
    assert summaries[2].path == summaries[1].path and summaries[2].dropped == 0

    def closed(*_):
        raise BrokenPipeError("reader gone")

    before = {t.name for t in threading.enumerate()}
    with pytest.raises(BrokenPipeError):
        live.watch(pairs, refs, jobs=2, on_update=closed)
    import multiprocessing

    assert not [p for p in multiprocessing.active_children() if p.name.startswith("dgli-watch")]
    assert not {t.name for t in threading.enumerate()} - before - {"dgli-capture"}


def test_overlays_need_the_frames_here(tmp_path) -> None:
    """--overlay-dir draws from each frame's whole result, which a worker process keeps:
    with -j 2 it stops at once with one line; without -j it classifies here."""
    from pathlib import Path

    from click.testing import CliRunner

    from dgli_vision.cli import main

    samples = Path(__file__).parent.parent / "sample_images"
    ov = tmp_path / "ov"
    r = CliRunner().invoke(main, ["watch", "--bag", str(samples), "--overlay-dir", str(ov),
                                  "-j", "2"])
    assert r.exit_code == 2 and "use -j 1" in r.output and "Traceback" not in r.output
    assert len(r.output.strip().splitlines()) == 1 and not ov.exists()
