"""RealSense recordings written by the RealSense SDK itself (a software device recorded
by the SDK's recorder, from rendered frames): read back through the SDK with depth aligned
to colour, the depth scale and the colour intrinsics; the same timeline as the same frames
as PNG pairs; one line for a truncated or foreign file, and for a missing SDK."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from guards import require_extra

from dgli_vision.cli import main
from dgli_vision.core.camera import Intrinsics

DATA = Path(__file__).parent / "data"

#: The colour camera of the small pattern recordings (80 x 60, depth 40 x 30).
PATTERN_INTRINSICS = Intrinsics(80, 60, 70.0, 71.0, 39.2, 29.6)


def pattern_frames() -> list[tuple[float, np.ndarray, np.ndarray]]:
    """Four small frames whose every pixel says where it is: red grows along x, green
    along y, blue with the frame; depth 600 mm + 5 mm per frame + 1 mm per two columns."""
    y, x = np.mgrid[0:60, 0:80]
    out = []
    for k in range(4):
        rgb = np.stack([x * 3, y * 4, np.full_like(x, 40 * k + 10)], axis=-1).astype(np.uint8)
        depth = (600 + 5 * k + x // 2).astype(np.uint16)
        out.append((5.0 + k / 30, rgb, depth))
    return out


def _same_camera(a: Intrinsics, b: Intrinsics) -> None:
    assert (a.width, a.height, a.distortion) == (b.width, b.height, b.distortion)
    assert [a.fx, a.fy, a.cx, a.cy] == pytest.approx([b.fx, b.fy, b.cx, b.cy], abs=1e-5)


def _read(path: Path):
    from dgli_vision.sources.realsense import RealSensePlayback

    with RealSensePlayback(path) as rec:
        return rec, list(rec.frames())


def _one_line_error(args: list[str], *needles: str) -> str:
    r = CliRunner().invoke(main, args)
    assert r.exit_code == 2, r.output
    lines = [ln for ln in r.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and "Traceback" not in r.output, r.output
    for needle in needles:
        assert needle in lines[0], lines[0]
    return lines[0]


@pytest.fixture(scope="module")
def rs():
    return require_extra("pyrealsense2")  # the 'realsense' extra: failed in CI if missing


@pytest.fixture(scope="module")
def pattern_db3(rs, tmp_path_factory) -> Path:
    from dgli_vision.sources.realsense_writer import write_realsense_recording

    path = tmp_path_factory.mktemp("rs") / "pattern.db3"
    return write_realsense_recording(path, pattern_frames(), PATTERN_INTRINSICS, paced=True)


def _check_pattern(frames) -> None:
    want = pattern_frames()
    assert len(frames) == len(want)
    for got, (t, rgb, depth) in zip(frames, want):
        assert got.time == pytest.approx(t, abs=1e-6)
        np.testing.assert_array_equal(got.color, rgb)  # RGB order kept through the SDK
        assert got.depth_mm.shape == depth.shape  # aligned to colour: colour's size
        seen = got.depth_mm > 0
        assert seen.mean() > 0.9
        # in mm (the file holds 0.1 mm units), each pixel where colour sees it
        assert np.abs(got.depth_mm[seen].astype(int) - depth[seen]).max() <= 1


def test_an_sdk_recording_is_read_with_depth_aligned_scaled_and_the_colour_intrinsics(
    pattern_db3,
):
    rec, frames = _read(pattern_db3)
    assert rec.depth_scale_m == pytest.approx(0.0001)
    _same_camera(rec.intrinsics, PATTERN_INTRINSICS)
    assert rec.count == 4
    _check_pattern(frames)


def test_a_ros1_bag_of_an_older_sdk_reads_like_the_db3_of_this_one(rs, pattern_db3):
    """tests/data/realsense_sdk2.56.bag: the same frames recorded by SDK 2.56 (ROS 1
    layout, as the RealSense Viewer writes; scripts/realsense_fixture.py)."""
    bag = DATA / "realsense_sdk2.56.bag"
    rec, frames = _read(bag)
    _same_camera(rec.intrinsics, PATTERN_INTRINSICS)
    assert rec.depth_scale_m == pytest.approx(0.0001)
    _check_pattern(frames)
    _, again = _read(pattern_db3)
    for a, b in zip(frames, again):
        np.testing.assert_array_equal(a.depth_mm, b.depth_mm)


@pytest.fixture(scope="module")
def episode(rs, tmp_path_factory) -> tuple[Path, Path]:
    """Sequence I, 6 rendered frames, as PNG pairs and as an SDK recording (depth at
    half the colour resolution, in 0.1 mm units)."""
    from dgli_vision.sources.frames import read_frame
    from dgli_vision.sources.realsense_writer import write_realsense_recording
    from dgli_vision.sources.recording import read_recording

    root = tmp_path_factory.mktemp("rs_episode")
    r = CliRunner().invoke(
        main, ["render", str(root / "I"), "--sequence", "I", "--frames", "6", "--seed", "3"]
    )
    assert r.exit_code == 0, r.output
    rec = read_recording(root / "I")
    frames = [read_frame(p.color, p.depth) for p in rec.frames]
    data = ((1000.0 + p.time, f.color, f.depth_mm) for p, f in zip(rec.frames, frames))
    db3 = write_realsense_recording(root / "I.db3", data, frames[0].intrinsics)
    return root / "I", db3


def _track(path: Path) -> dict:
    r = CliRunner().invoke(main, ["track", str(path), "-j", "1", "--json"])
    assert r.exit_code == 0, r.output
    return json.loads(r.output)


def _timeline(data: dict) -> list[tuple]:
    return [(f["raw_class"], f["smoothed_class"], f["smoothed_variant"]) for f in data["frames"]]


def test_track_on_an_sdk_recording_gives_the_timeline_of_the_png_pairs(episode):
    folder, db3 = episode
    png, rs_data = _track(folder), _track(db3)
    assert rs_data["n_frames"] == png["n_frames"] == 6
    assert _timeline(rs_data) == _timeline(png)
    assert [c["frame"] for c in rs_data["changes"]] == [c["frame"] for c in png["changes"]]
    assert [c["frame"] for c in png["changes"]]  # the sequence folds: changes to compare
    times = [f["time"] for f in rs_data["frames"]]
    assert times == pytest.approx([f["time"] for f in png["frames"]], abs=1e-3)
    assert rs_data["recording"]["kind"] == "RealSense recording"
    assert any("aligned to colour as the SDK aligns" in n for n in rs_data["recording"]["notes"])


def test_extract_of_a_640x480_recording_uses_its_own_intrinsics(rs, tmp_path):
    """The reported bug: a 640x480 RealSense .db3 stopped at frame 0 with the nominal
    1280x720 intrinsics."""
    from dgli_vision.sources.realsense_writer import write_realsense_recording

    intr = Intrinsics(640, 480, 610.0, 611.0, 318.5, 241.25)
    y, x = np.mgrid[0:480, 0:640]
    frames = [
        (2.0 + k / 30, np.dstack([x % 256, y % 256, x * 0 + k]).astype(np.uint8),
         np.full((480, 640), 700, np.uint16))
        for k in range(5)
    ]
    db3 = write_realsense_recording(tmp_path / "vga.db3", frames, intr, compress=False)
    r = CliRunner().invoke(main, ["extract", str(db3), str(tmp_path / "out")])
    assert r.exit_code == 0, r.output
    assert "wrote 5 frames" in r.output
    written = json.loads((tmp_path / "out" / "intrinsics.json").read_text())
    assert (written["width"], written["height"]) == (640, 480)
    assert written["intrinsic_matrix"] == pytest.approx([610, 0, 0, 0, 611, 0, 318.5, 241.25, 1])


def test_a_truncated_recording_is_one_line_and_exit_2(pattern_db3, tmp_path):
    bag = tmp_path / "cut.bag"
    bag.write_bytes((DATA / "realsense_sdk2.56.bag").read_bytes()[:3000])
    _one_line_error(["track", str(bag)], str(bag))
    db3 = tmp_path / "cut.db3"
    db3.write_bytes(pattern_db3.read_bytes()[:9000])
    _one_line_error(["track", str(db3)], str(db3))


def test_a_foreign_file_named_like_a_realsense_bag_is_one_line(rs, tmp_path):
    fake = tmp_path / "rs.bag"
    fake.write_bytes(b"#ROSBAG V2.0\n" + b"\0" * 64 + b"/device_0/sensor_0/Depth_0" + b"\0" * 64)
    _one_line_error(["extract", str(fake), str(tmp_path / "o")], "RealSense recording", str(fake))


def test_without_the_sdk_every_realsense_command_says_what_to_install(
    pattern_db3, tmp_path, monkeypatch
):
    monkeypatch.setitem(sys.modules, "pyrealsense2", None)  # import pyrealsense2 fails
    hint = "pip install 'dgli_vision[realsense]'"
    _one_line_error(["track", str(pattern_db3)], hint)
    _one_line_error(["extract", str(pattern_db3), str(tmp_path / "o")], hint)
    _one_line_error(["evaluate", str(pattern_db3), "--labels", str(tmp_path / "l.csv")], hint)
    _one_line_error(["watch", "--bag", str(pattern_db3)], hint)
    _one_line_error(["watch", "--realsense"], hint)
    _one_line_error(["watch", "--realsense", "123456789"], hint)


def _watch(*args: str) -> tuple[list[dict], dict]:
    r = CliRunner().invoke(main, ["watch", *args, "--jsonl"])
    assert r.exit_code == 0, r.output
    lines = [json.loads(ln) for ln in r.stdout.splitlines()]
    assert "summary" in lines[-1]
    return lines[:-1], lines[-1]["summary"]


def test_watch_plays_a_recording_through_the_live_path_with_the_states_of_track(episode):
    _, db3 = episode
    tracked = _track(db3)
    frames, summary = _watch("--bag", str(db3), "--fast", "-j", "2")  # worker processes
    assert [f["frame"] for f in frames] == list(range(6))  # as fast as classified: none lost
    assert summary["dropped"] == 0 and all(f["dropped"] == 0 for f in frames)
    raw = [f["state"]["class"] if f["state"] else None for f in frames]
    assert raw == [f["raw_class"] for f in tracked["frames"]]
    # the whole path settled by all frames is track's timeline; the online state of the
    # last frame is its last state
    assert [(s["class"], s["variant"]) for s in summary["path"]] == [
        (f["smoothed_class"], f["smoothed_variant"]) for f in tracked["frames"]
    ]
    last = tracked["frames"][-1]
    assert frames[-1]["smoothed"] == {
        "class": last["smoothed_class"], "variant": last["smoothed_variant"]
    }
    changed = [f["frame"] for f in frames if f["change"]]
    assert changed and changed[-1] == tracked["changes"][-1]["frame"]
    assert all(f["latency_ms"] > 0 and 0 <= f["confidence"] <= 1 for f in frames)


def test_frames_that_come_while_one_is_classified_are_dropped_and_counted(
    episode, tmp_path, monkeypatch
):
    """Played at its pace, a recording whose frames come 1 ms apart: the worker cannot
    keep up, and frames are dropped (never queued), the newest always classified. (The
    classification is made to take 0.5 s, so that it is slower than decoding the next
    frames however busy the machine: decoding overlaps classifying.)"""
    import time

    from dgli_vision.analysis import live
    from dgli_vision.sources.recording import read_recording

    real = live.classify_live
    monkeypatch.setattr(live, "classify_live", lambda *a, **k: time.sleep(0.5) or real(*a, **k))

    folder, _ = episode
    fast = tmp_path / "fast"
    fast.mkdir()
    pairs = read_recording(folder).frames
    rows = [f"{p.color},{p.depth},{k * 0.001:.3f}" for k, p in enumerate(pairs)]
    (fast / "frames.csv").write_text("color,depth,time\n" + "\n".join(rows) + "\n")
    frames, summary = _watch("--bag", str(fast), "--realtime", "-j", "1")  # patched here
    done = [f["frame"] for f in frames]
    assert summary["dropped"] >= 1 and frames[-1]["dropped"] == summary["dropped"]
    assert summary["classified"] + summary["dropped"] == summary["arrived"] == 6
    assert done == sorted(done) and done[-1] == 5  # the newest is never dropped


def test_watch_every_n_frames_with_overlays(episode, tmp_path):
    _, db3 = episode
    frames, summary = _watch("--bag", str(db3), "--fast", "--every", "2",
                             "--overlay-dir", str(tmp_path / "ov"))
    assert [f["frame"] for f in frames] == [0, 2, 4]
    assert summary["skipped"] == 3 and summary["dropped"] == 0
    assert sorted(p.name for p in (tmp_path / "ov").iterdir()) == [
        "frame_000000.png", "frame_000002.png", "frame_000004.png"
    ]


def test_ctrl_c_stops_watch_cleanly_with_a_summary(episode, tmp_path):
    import signal
    import subprocess

    folder, _ = episode
    slow = tmp_path / "slow"  # a frame every 2 s: still watching when Ctrl-C comes
    slow.mkdir()
    from dgli_vision.sources.recording import read_recording

    rows = [f"{p.color},{p.depth},{k * 2.0}" for k, p in enumerate(read_recording(folder).frames)]
    (slow / "frames.csv").write_text("color,depth,time\n" + "\n".join(rows) + "\n")
    proc = subprocess.Popen(
        [sys.executable, "-m", "dgli_vision", "watch", "--bag", str(slow), "--jsonl"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )
    first = proc.stdout.readline()  # the first frame's answer: watching
    assert json.loads(first)["frame"] == 0
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err
    summary = json.loads(out.splitlines()[-1])["summary"]
    assert summary["stopped"] is True and summary["classified"] < 6
    assert "Traceback" not in err and err.strip().splitlines()[-1].startswith("stopped: ")


def test_the_camera_path_gives_aligned_frames_in_mm_with_the_stream_intrinsics(pattern_db3):
    """The pipeline a live camera streams through, fed from an SDK recording (the SDK
    plays a file through the same pipeline API as a camera; recorded at the frames'
    pace, it plays like one)."""
    from dgli_vision.sources.realsense import _camera_frames

    rs = require_extra("pyrealsense2")
    config = rs.config()
    config.enable_device_from_file(str(pattern_db3), repeat_playback=True)  # endless
    pipeline = rs.pipeline()
    frames = _camera_frames(rs, pipeline, pipeline.start(config))
    got = [next(frames), next(frames)]
    got = [f.decode() for f in got]  # both held: the second came before the first is aligned
    frames.close()  # stops the pipeline
    want = {rgb[0, 0, 2]: depth for _, rgb, depth in pattern_frames()}
    for f in got:
        _same_camera(f.intrinsics, PATTERN_INTRINSICS)
        assert f.color.shape == (60, 80, 3) and f.color[0, 0, 2] in want
        seen = f.depth_mm > 0
        near = [np.abs(f.depth_mm[seen].astype(int) - d[seen]).max() for d in want.values()]
        assert seen.mean() > 0.9 and min(near) <= 1  # in mm, aligned: one frame's depth


def test_online_smoothing_is_tracks_smoothing_one_frame_at_a_time():
    """After each frame the online state is the last state of track's path over the
    frames so far; the kept path is track's path (with gaps)."""
    from dgli_vision.analysis.live import OnlineSmoother
    from dgli_vision.analysis.track import smooth
    from dgli_vision.classifier.references import default_references_path, load_references

    refs = load_references(default_references_path())
    rng = np.random.default_rng(28)
    owners = [(r.class_id, r.variant) for r in refs.references]
    story = [("01", None)] * 6 + [("02", "A")] * 6 + [("06", "AC")] * 6
    d = rng.uniform(0.3, 0.6, (len(story), len(refs)))
    for t, key in enumerate(story):  # each frame near its state, one frame far off
        d[t, [k for k, o in enumerate(owners) if o == key]] = rng.uniform(0.05, 0.2)
    d[[4, 10]] = np.nan  # two gaps
    d[8, :] = rng.uniform(0.3, 0.6, len(refs))
    d[8, [k for k, o in enumerate(owners) if o == ("11", "AB")]] = 0.05
    online = OnlineSmoother(refs)
    for t in range(len(story)):
        row = None if np.isnan(d[t]).all() else d[t]
        assert online.update(row) == smooth(d[: t + 1], refs)[0][-1]
    assert online.path() == smooth(d, refs)[0]
    assert online.path()[8] == ("02", "A")  # the odd frame smoothed away


def test_a_recording_of_colour_alone_is_one_line(rs, tmp_path):
    """A camera recorded with its depth stream off: nothing to lift the stickers with."""
    dev = rs.software_device()
    sensor = dev.add_sensor("RGB Camera")
    vs = rs.video_stream()
    vs.type, vs.index, vs.uid, vs.fmt = rs.stream.color, 0, 1, rs.format.rgb8
    vs.width, vs.height, vs.fps, vs.bpp = 64, 48, 30, 3
    intr = rs.intrinsics()
    intr.width, intr.height, intr.fx, intr.fy, intr.ppx, intr.ppy = 64, 48, 50, 50, 31.5, 23.5
    vs.intrinsics = intr
    profile = sensor.add_video_stream(vs).as_video_stream_profile()
    path = tmp_path / "colour.db3"
    recorder = rs.recorder(str(path), dev, False)
    queue = rs.frame_queue(4)
    sensor.open(profile)
    sensor.start(queue)
    for n in range(2):
        frame = rs.software_video_frame()
        frame.pixels, frame.bpp, frame.stride = np.zeros((48, 64, 3), np.uint8), 3, 192
        frame.timestamp, frame.frame_number, frame.profile = n * 33.3, n, profile
        frame.domain = rs.timestamp_domain.hardware_clock
        sensor.on_video_frame(frame)
    sensor.stop()
    sensor.close()
    del recorder
    _one_line_error(["track", str(path)], str(path), "no Z16 depth stream")
