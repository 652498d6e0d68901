"""Recorded episodes: ROS 1 and ROS 2 bags written with rosbags from rendered frames of a
folding sequence, read back by `dgli track`, `evaluate` and `extract`; the pairing of
colour and depth by time; image encodings; and the one-line errors of bad recordings."""

from __future__ import annotations

import csv
import json
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from guards import require_extra

from dgli_vision.analysis.evaluate import evaluate_pairs
from dgli_vision.classifier.references import load_references
from dgli_vision.cli import main
from dgli_vision.core.errors import InvalidInputError
from dgli_vision.sources.bag_writer import COLOR_TOPIC, DEPTH_TOPIC, INFO_TOPIC, write_bag
from dgli_vision.sources.frames import read_frame
from dgli_vision.sources.pairing import pair_by_time
from dgli_vision.sources.recording import open_recording, read_recording
from dgli_vision.sources.ros_bags import IMAGE, INFO, choose_topics
from dgli_vision.sources.ros_images import ImagePayload, decode_color, decode_depth

require_extra("rosbags")  # the 'recordings' extra: skipped without it, failed in CI

T0 = 1_700_000_000.0  # a driver's stamps: seconds since 1970


@pytest.fixture(scope="module")
def episode(tmp_path_factory) -> Path:
    """Sequence I (corner A over, then corner C), 12 frames as PNG pairs."""
    out = tmp_path_factory.mktemp("episode") / "I"
    r = CliRunner().invoke(
        main, ["render", str(out), "--sequence", "I", "--frames", "12", "--seed", "3"]
    )
    assert r.exit_code == 0, r.output
    return out


def _frames(folder: Path):
    rec = read_recording(folder)
    return [read_frame(p.color, p.depth) for p in rec.frames], [p.time for p in rec.frames]


@pytest.fixture(scope="module")
def bags(episode, tmp_path_factory) -> dict[str, Path]:
    """The episode as a bag of each kind, as drivers record it."""
    frames, times = _frames(episode)
    root = tmp_path_factory.mktemp("bags")
    kinds = {
        "ros1 rgb8 16UC1": (root / "ep.bag", "ros1", "rgb8", "16UC1"),
        "ros2 sqlite3 bgr8 32FC1": (root / "ep_sqlite", "ros2-sqlite3", "bgr8", "32FC1"),
        "ros2 mcap rgb8 16UC1": (root / "ep_mcap", "ros2-mcap", "rgb8", "16UC1"),
        "ros2 mcap jpeg 16UC1": (root / "ep_jpeg", "ros2-mcap", "jpeg", "16UC1"),
    }
    out = {}
    for name, (path, fmt, color, depth) in kinds.items():
        data = ((T0 + t, f.color, f.depth_mm) for f, t in zip(frames, times))
        out[name] = write_bag(
            path,
            data,
            frames[0].intrinsics,
            fmt=fmt,
            color_encoding=color,
            depth_encoding=depth,
            depth_offset_s=0.004,  # depth stamped 4 ms after colour
        )
    return out


_TRACKED: dict[tuple[str, ...], str] = {}


def _track(path: Path, *extra: str) -> dict:
    """``dgli track PATH --json``'s answer; a path the module's fixtures made (the episode,
    its bags) is tracked once and its answer reused by the tests that compare with it."""
    key = (str(path), *extra)
    if key not in _TRACKED:
        r = CliRunner().invoke(main, ["track", str(path), "-j", "2", "--json", *extra])
        assert r.exit_code == 0, r.output
        _TRACKED[key] = r.output
    return json.loads(_TRACKED[key])


def _timeline(data: dict) -> list[tuple]:
    return [(f["raw_class"], f["smoothed_class"], f["smoothed_variant"]) for f in data["frames"]]


@pytest.mark.parametrize(
    "kind",
    ["ros1 rgb8 16UC1", "ros2 sqlite3 bgr8 32FC1", "ros2 mcap rgb8 16UC1", "ros2 mcap jpeg 16UC1"],
)
def test_a_bag_gives_the_timeline_of_the_same_frames_as_png_pairs(episode, bags, kind):
    png = _track(episode)
    bag = _track(bags[kind])
    assert bag["n_frames"] == png["n_frames"] == 12
    assert _timeline(bag) == _timeline(png)
    assert [c["frame"] for c in bag["changes"]] == [c["frame"] for c in png["changes"]]
    assert [f["time"] for f in bag["frames"]] == pytest.approx([f["time"] for f in png["frames"]])
    assert bag["recording"]["kind"] == ("ROS 1 bag" if kind.startswith("ros1") else "ROS 2 bag")


def test_a_bare_mcap_file_is_read_like_its_bag_folder(bags):
    folder = bags["ros2 mcap rgb8 16UC1"]
    (single,) = folder.glob("*.mcap")
    assert _timeline(_track(single)) == _timeline(_track(folder))


def test_a_labelled_bag_scores_itself_like_the_labelled_folder(episode, bags, tmp_path):
    with (episode / "labels.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    labels = tmp_path / "labels.csv"  # by time (seconds from the start), as a user notes it
    labels.write_text(
        "time,label,variant\n"
        + "".join(f"{0.5 * k:.1f},{r['label']},{r['variant']}\n" for k, r in enumerate(rows))
    )
    png = _track(episode)
    bag = _track(bags["ros1 rgb8 16UC1"], "--labels", str(labels))
    assert bag["score"] == png["score"]
    r = CliRunner().invoke(
        main, ["evaluate", str(bags["ros1 rgb8 16UC1"]), "--labels", str(labels), "--json"]
    )
    assert r.exit_code == 0, r.output
    r_png = CliRunner().invoke(main, ["evaluate", str(episode), "--json"])
    got, want = json.loads(r.output), json.loads(r_png.output)
    assert (got["n"], got["accuracy"], got["confusion"]) == (
        want["n"],
        want["accuracy"],
        want["confusion"],
    )


def test_extract_writes_a_folder_that_tracks_like_the_bag(bags, tmp_path):
    bag = bags["ros2 sqlite3 bgr8 32FC1"]
    out = tmp_path / "frames"
    r = CliRunner().invoke(main, ["extract", str(bag), str(out)])
    assert r.exit_code == 0, r.output
    with (out / "frames.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert [r["color"] for r in rows] == [f"frame_{k:06d}_color.png" for k in range(12)]
    assert [float(r["time"]) for r in rows] == pytest.approx([0.5 * k for k in range(12)])
    assert _timeline(_track(out)) == _timeline(_track(bag))
    intr = json.loads((out / "intrinsics.json").read_text())
    assert (intr["width"], intr["height"]) == (1280, 720)


def test_extract_every_start_end(bags, tmp_path):
    out = tmp_path / "part"
    r = CliRunner().invoke(
        main,
        [
            "extract",
            str(bags["ros1 rgb8 16UC1"]),
            str(out),
            "--every",
            "2",
            "--start",
            "1.0",
            "--end",
            "4.0",
        ],
    )
    assert r.exit_code == 0, r.output
    names = sorted(p.name for p in out.glob("*_color.png"))
    assert names == [f"frame_{k:06d}_color.png" for k in (2, 4, 6, 8)]


def test_frames_are_read_as_they_are_classified(bags):
    """Streaming: only the frames in flight hold their pixels, never the whole episode."""
    import weakref

    rec = open_recording(bags["ros2 mcap rgb8 16UC1"])
    alive: list[weakref.ref] = []
    most = 0

    def frames():
        nonlocal most
        for pair in rec.frames:
            alive.append(weakref.ref(pair))
            most = max(most, sum(r() is not None for r in alive))
            yield pair
            del pair

    outcomes = list(evaluate_pairs(frames(), load_references(), jobs=2))
    assert len(outcomes) == 12
    assert most <= 8  # one worker's 6 queued, the one in hand, the one being read
    # an outcome keeps the frame's names, not its pixels
    assert all(type(o.pair).__name__ == "LabelledPair" for o in outcomes)


# --- pairing by time -------------------------------------------------------------------


def test_pairing_takes_the_nearest_depth_within_the_tolerance_and_lists_the_rest():
    events = [
        ("color", 0.000, "c0"),
        ("depth", 0.004, "d0"),
        ("color", 0.033, "c1"),
        ("depth", 0.036, "d1"),
        ("depth", 0.050, "d_extra"),  # no colour near it
        ("color", 0.066, "c2"),  # its depth never came
        ("color", 0.100, "c3"),
        ("depth", 0.099, "d3"),
    ]
    got = [(p.color, p.depth) for p in pair_by_time(events, 0.010)]
    assert got == [("c0", "d0"), ("c1", "d1"), (None, "d_extra"), ("c2", None), ("c3", "d3")]


def test_pairing_handles_depth_recorded_before_its_colour():
    events = [
        ("depth", 0.0, "d0"),
        ("depth", 0.033, "d1"),
        ("color", 0.001, "c0"),
        ("color", 0.034, "c1"),
    ]
    assert [(p.color, p.depth) for p in pair_by_time(events, 0.02)] == [("c0", "d0"), ("c1", "d1")]


def test_pairing_streams_an_endless_recording_with_a_few_frames_held():
    held = []

    def endless():
        k = 0
        while True:
            held.append(k)
            yield ("color", k / 30, k)
            yield ("depth", k / 30 + 0.002, k)
            k += 1

    stream = pair_by_time(endless(), 0.02)
    for k in range(1000):
        p = next(stream)
        assert (p.color, p.depth) == (k, k)
        assert len(held) - k <= 3  # pairs settle as soon as the next depth arrives


# --- image encodings -------------------------------------------------------------------


def _payload(encoding, pixels, *, pad=0, big=False):
    h, w = pixels.shape[:2]
    if big:
        pixels = pixels.astype(pixels.dtype.newbyteorder(">"))
    raw = np.ascontiguousarray(pixels).view(np.uint8).reshape(h, -1)
    rows = np.concatenate([raw, np.zeros((h, pad), np.uint8)], axis=1)
    return ImagePayload(encoding, w, h, rows.shape[1], big, rows.tobytes())


def test_colour_encodings_decode_to_the_same_rgb():
    rng = np.random.default_rng(0)
    rgb = rng.integers(0, 256, (5, 7, 3), dtype=np.uint8)
    alpha = np.full((5, 7, 1), 255, np.uint8)
    for enc, pixels in [
        ("rgb8", rgb),
        ("bgr8", rgb[:, :, ::-1]),
        ("rgba8", np.concatenate([rgb, alpha], 2)),
        ("bgra8", np.concatenate([rgb[:, :, ::-1], alpha], 2)),
    ]:
        got = decode_color(_payload(enc, pixels, pad=3), "test")  # rows padded (step)
        np.testing.assert_array_equal(got, rgb, err_msg=enc)


def test_depth_encodings_decode_to_millimetres():
    mm = np.array([[0, 1, 500], [999, 1500, 65535]], np.uint16)
    np.testing.assert_array_equal(decode_depth(_payload("16UC1", mm), "t"), mm)
    np.testing.assert_array_equal(decode_depth(_payload("16UC1", mm, big=True), "t"), mm)
    metres = np.array([[np.nan, 0.001, 0.5], [-1.0, 1.5, np.inf]], np.float32)
    want = np.array([[0, 1, 500], [0, 1500, 0]], np.uint16)
    np.testing.assert_array_equal(decode_depth(_payload("32FC1", metres), "t"), want)


def test_compressed_depth_png_is_read():
    import cv2

    mm = np.arange(12, dtype=np.uint16).reshape(3, 4) * 300
    _, png = cv2.imencode(".png", mm)
    data = bytes(12) + png.tobytes()  # compressed_depth_image_transport's header first
    p = ImagePayload("compressed:16UC1; compressedDepth png", 0, 0, 0, False, data)
    np.testing.assert_array_equal(decode_depth(p, "t"), mm)


def test_unknown_encodings_and_short_data_are_named():
    with pytest.raises(InvalidInputError, match=r"^ep.bag /c at 1.0 s: colour encoding 'yuv422'"):
        decode_color(ImagePayload("yuv422", 2, 2, 4, False, bytes(8)), "ep.bag /c at 1.0 s")
    with pytest.raises(InvalidInputError, match="too few"):
        decode_depth(ImagePayload("16UC1", 4, 4, 8, False, bytes(10)), "x")


# --- topics ----------------------------------------------------------------------------


def _types(*topics):
    return {t: (INFO if t.endswith("camera_info") else IMAGE) for t in topics}


def test_a_realsense_drivers_topics_are_found():
    types = _types(
        COLOR_TOPIC,
        DEPTH_TOPIC,
        INFO_TOPIC,
        "/camera/depth/image_rect_raw",
        "/camera/depth/camera_info",
        "/camera/infra1/image_rect_raw",
    )
    types[COLOR_TOPIC + "/compressed"] = "sensor_msgs/msg/CompressedImage"
    got = choose_topics(types, {}, "ep.bag")
    assert (got.color, got.depth, got.info) == (COLOR_TOPIC, DEPTH_TOPIC, INFO_TOPIC)


def test_ambiguous_or_missing_topics_are_one_line_errors():
    two = _types("/left/color/image_raw", "/right/color/image_raw", "/left/depth/image_raw")
    with pytest.raises(InvalidInputError, match=r"several colour topics .*--color-topic"):
        choose_topics(two, {}, "ep.bag")
    got = choose_topics(two, {}, "ep.bag", color="/right/color/image_raw")
    assert got.color == "/right/color/image_raw"
    with pytest.raises(InvalidInputError, match="no depth image topic"):
        choose_topics(_types("/cam/color/image_raw"), {}, "ep.bag")
    with pytest.raises(InvalidInputError, match="has no image topic"):
        choose_topics({"/chatter": "std_msgs/msg/String"}, {}, "ep.bag")
    with pytest.raises(InvalidInputError, match="carries sensor_msgs/msg/CameraInfo"):
        choose_topics(_types(COLOR_TOPIC, DEPTH_TOPIC, INFO_TOPIC), {}, "e", color=INFO_TOPIC)


# --- bad recordings, from the command line -----------------------------------------------


def _one_line_error(args, *words):
    r = CliRunner().invoke(main, args)
    assert r.exit_code == 2, r.output
    lines = r.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), r.output
    for w in words:
        assert w in lines[0], lines[0]
    return lines[0]


def _tiny_bag(path, color_shape=(48, 64), depth_shape=(48, 64), color_encoding="rgb8"):
    """A two-frame ROS 2 bag written message by message (encodings a driver might use)."""
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    T = store.types
    with Writer(path, version=9) as w:
        cc = w.add_connection(COLOR_TOPIC, IMAGE, typestore=store)
        cd = w.add_connection(DEPTH_TOPIC, IMAGE, typestore=store)
        for k in range(2):
            stamp = T["builtin_interfaces/msg/Time"](sec=100 + k, nanosec=0)
            hdr = T["std_msgs/msg/Header"](stamp=stamp, frame_id="c")
            for conn, (h, wd), enc, ch in [
                (cc, color_shape, color_encoding, 3),
                (cd, depth_shape, "16UC1", 2),
            ]:
                data = np.zeros(h * wd * ch, np.uint8)
                msg = T[IMAGE](
                    header=hdr,
                    height=h,
                    width=wd,
                    encoding=enc,
                    is_bigendian=0,
                    step=wd * ch,
                    data=data,
                )
                w.write(conn, (100 + k) * 10**9, store.serialize_cdr(msg, IMAGE))
    return path


def test_depth_not_aligned_to_colour_stops_with_one_line(tmp_path):
    bag = _tiny_bag(tmp_path / "b", depth_shape=(24, 32))
    _one_line_error(["track", str(bag)], "not aligned to colour", DEPTH_TOPIC, str(bag))


def test_an_unknown_encoding_stops_with_one_line(tmp_path):
    bag = _tiny_bag(tmp_path / "b", color_encoding="yuv422")
    _one_line_error(["track", str(bag)], "yuv422", COLOR_TOPIC, str(bag))


def test_a_truncated_bag_stops_with_one_line(bags, tmp_path):
    data = bags["ros1 rgb8 16UC1"].read_bytes()
    cut = tmp_path / "cut.bag"
    cut.write_bytes(data[: len(data) // 2])
    _one_line_error(["track", str(cut)], str(cut), "truncated")
    mcap = next(bags["ros2 mcap rgb8 16UC1"].glob("*.mcap"))
    cut2 = tmp_path / "cut.mcap"
    cut2.write_bytes(mcap.read_bytes()[: mcap.stat().st_size // 2])
    _one_line_error(["extract", str(cut2), str(tmp_path / "o")], str(cut2))


def test_a_bag_without_images_stops_with_one_line(tmp_path):
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    with Writer(tmp_path / "talk.bag") as w:
        c = w.add_connection("/chatter", "std_msgs/msg/String", typestore=store)
        msg = store.types["std_msgs/msg/String"](data="hello")
        w.write(c, 1, store.serialize_ros1(msg, "std_msgs/msg/String"))
    _one_line_error(["track", str(tmp_path / "talk.bag")], "no image topic", "/chatter")


def test_evaluating_a_bag_needs_labels(bags):
    _one_line_error(["evaluate", str(bags["ros1 rgb8 16UC1"])], "--labels")


def test_without_the_extra_the_error_names_it(bags, monkeypatch):
    monkeypatch.setitem(sys.modules, "rosbags", None)  # as if not installed
    _one_line_error(["track", str(bags["ros1 rgb8 16UC1"])], "dgli_vision[recordings]")


def test_a_colour_frame_without_depth_is_a_gap_and_a_lone_depth_is_listed(episode, tmp_path):
    frames, times = _frames(episode)
    rows = [(T0 + t, f.color, f.depth_mm) for f, t in zip(frames[:4], times)]
    late = _write_with_late_depth(tmp_path / "late.bag", rows, frames[0].intrinsics, 2)
    r = CliRunner().invoke(main, ["track", str(late), "-j", "1"])
    assert r.exit_code == 0, r.output
    assert "gap: frame 2" in r.output and "no depth frame within 20 ms" in r.output
    assert "no colour frame within 20 ms (not used)" in r.output
    data = _track(late)
    assert [g["frame"] for g in data["gaps"]] == [2]
    assert data["n_frames"] == 4
    r = CliRunner().invoke(main, ["extract", str(late), str(tmp_path / "out")])
    assert r.exit_code == 0 and "skipped: " in r.output and "wrote 3 frames" in r.output


def _write_with_late_depth(path, rows, intr, late_frame):
    """A ROS 1 bag of ``rows`` whose depth of frame ``late_frame`` is stamped 60 ms late."""
    from rosbags.highlevel import AnyReader
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    src = write_bag(path.with_suffix(".src.bag"), iter(rows), intr, fmt="ros1")
    store = get_typestore(Stores.ROS1_NOETIC)
    with AnyReader([src]) as reader, Writer(path) as w:
        conns = {
            c.topic: w.add_connection(c.topic, c.msgtype, typestore=store)
            for c in reader.connections
        }
        depth_seen = 0
        for conn, ns, raw in reader.messages():
            if conn.topic == DEPTH_TOPIC:
                if depth_seen == late_frame:
                    msg = reader.deserialize(raw, conn.msgtype)
                    msg.header.stamp.nanosec += 60_000_000
                    raw = store.serialize_ros1(msg, conn.msgtype)
                depth_seen += 1
            w.write(conns[conn.topic], ns, raw)
    return path


def test_lens_distortion_is_noted(episode, tmp_path):
    frames, times = _frames(episode)
    bag = write_bag(
        tmp_path / "d.bag",
        ((T0 + t, f.color, f.depth_mm) for f, t in zip(frames[:2], times)),
        frames[0].intrinsics,
        fmt="ros1",
        distortion=(0.1, -0.05, 0.0, 0.0, 0.0),
    )
    data = _track(bag)
    assert any("non-zero plumb_bob distortion" in n for n in data["recording"]["notes"])


def test_a_file_that_is_not_a_realsense_recording_is_refused_in_one_line(tmp_path):
    from dgli_vision.sources.realsense import is_realsense_recording

    require_extra("pyrealsense2")  # the 'realsense' extra
    fake = tmp_path / "rs.bag"
    fake.write_bytes(b"#ROSBAG V2.0\n" + b"\0" * 64 + b"/device_0/sensor_0/Depth_0" + b"\0" * 64)
    assert is_realsense_recording(fake)
    _one_line_error(["track", str(fake)], "RealSense recording", str(fake))


def test_an_image_given_as_a_recording_is_one_line_naming_what_a_recording_is(tmp_path):
    from click.testing import CliRunner

    from dgli_vision.cli import main

    png = Path(__file__).resolve().parent.parent / "sample_images" / "05_000_color.png"
    for args in (["track", str(png)], ["watch", "--bag", str(png)]):
        res = CliRunner().invoke(main, args)
        assert res.exit_code == 2
        (line,) = res.output.strip().splitlines()
        assert "is not a recording" in line and ".bag" in line and "PNG pairs" in line
