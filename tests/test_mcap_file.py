"""ROS 2 MCAP recordings read in place (sources.mcap_file): the same messages, in the
same order, as rosbags reads; images handed on as where they lie in the file; and what
is not read in place (compressed chunks) still read, through rosbags; and the workers of
`track -j N`, started before the references are loaded, are those that classify."""

from __future__ import annotations

import json
import struct
from binascii import crc32
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from guards import require_extra

from dgli_vision.cli import main
from dgli_vision.core.parallel import FileSpan, SharedSlots
from dgli_vision.sources import ros_bags
from dgli_vision.sources.bag_writer import write_bag
from dgli_vision.sources.mcap_file import plan
from dgli_vision.sources.recording import open_recording
from dgli_vision.sources.ros_bags import RosBag

require_extra("rosbags")  # the 'recordings' extra: skipped without it, failed in CI

STRING, IMAGE = "std_msgs/msg/String", "sensor_msgs/msg/Image"


def _mixed_bag(path: Path, compress: bool = False) -> Path:
    """Strings and images on three topics, times out of order and tied across topics,
    images large enough that chunks hold one to a few messages."""
    from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    rng = np.random.default_rng(7)
    writer = Writer(path, version=9, storage_plugin=StoragePlugin.MCAP)
    if compress:
        writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
    with writer as w:
        text = w.add_connection("/chatter", STRING, typestore=store)
        image = w.add_connection("/camera/image", IMAGE, typestore=store)
        other = w.add_connection("/other/image", IMAGE, typestore=store)
        times = [5, 3, 3, 9, 1, 9, 9, 2, 7, 7, 4, 8, 6, 6, 10, 0]
        for k, t in enumerate(times):
            conn = (text, image, other)[k % 3]
            if conn is text:
                msg = store.types[STRING](data=f"message {k}")
            else:
                side = int(rng.integers(200, 700))
                pixels = rng.integers(0, 255, side * side, dtype=np.uint8)
                header = store.types["std_msgs/msg/Header"](
                    stamp=store.types["builtin_interfaces/msg/Time"](sec=t, nanosec=k),
                    frame_id="f",
                )
                msg = store.types[IMAGE](
                    header=header, height=side, width=side, encoding="mono8",
                    is_bigendian=0, step=side, data=pixels,
                )
            w.write(conn, t * 1_000_000_000, store.serialize_cdr(msg, conn.msgtype))
    return path


def _rosbags_messages(path: Path, topics: dict[str, str]) -> list[tuple]:
    with RosBag(path) as bag:
        conns = [c for c in bag.reader.connections if c.topic in topics]
        return [(c.topic, t, bytes(raw)) for c, t, raw in bag.reader.messages(connections=conns)]


def _in_place_messages(path: Path, topics: dict[str, str]) -> list[tuple]:
    found = plan(path)
    assert found is not None
    return [
        (m.topic, m.log_time, bytes(FileSpan(m.path, m.offset, m.length).view()))
        for m in found.messages(topics)
    ]


@pytest.fixture(scope="module")
def mixed(tmp_path_factory) -> Path:
    return _mixed_bag(tmp_path_factory.mktemp("mcap") / "mixed")


def test_messages_in_place_are_those_rosbags_reads_in_its_order(mixed):
    every = {"/chatter": STRING, "/camera/image": IMAGE, "/other/image": IMAGE}
    for topics in (every, {"/camera/image": IMAGE}, {"/chatter": STRING, "/other/image": IMAGE}):
        expected = _rosbags_messages(mixed, topics)
        assert len(expected) > 3
        assert _in_place_messages(mixed, topics) == expected
    (single,) = mixed.glob("*.mcap")  # the bare file reads as its folder
    assert _in_place_messages(single, every) == _rosbags_messages(mixed, every)


def _chunk_crcs(path: Path, wrong: bool) -> None:
    """Write each chunk's checksum (as ros2 bag record does; rosbags writes none)."""
    data = bytearray(path.read_bytes())
    pos = 8 + 1 + 8 + struct.unpack_from("<Q", data, 9)[0]  # past the header record
    while data[pos] != 0x0F:  # up to Data End
        length = struct.unpack_from("<Q", data, pos + 1)[0]
        if data[pos] == 0x06:
            (n,) = struct.unpack_from("<I", data, pos + 37)
            records = pos + 41 + n + 8
            (size,) = struct.unpack_from("<Q", data, records - 8)
            struct.pack_into("<I", data, pos + 33, crc32(data[records : records + size]) ^ wrong)
        pos += 9 + length
    path.write_bytes(bytes(data))


def test_chunk_checksums_are_checked(mixed, tmp_path):
    from rosbags.rosbag2 import ReaderError

    topics = {"/chatter": STRING, "/camera/image": IMAGE}
    expected = _rosbags_messages(mixed, topics)
    (single,) = mixed.glob("*.mcap")
    good, bad = tmp_path / "good.mcap", tmp_path / "bad.mcap"
    good.write_bytes(single.read_bytes())
    bad.write_bytes(single.read_bytes())
    _chunk_crcs(good, wrong=False)
    _chunk_crcs(bad, wrong=True)
    assert _in_place_messages(good, topics) == expected == _rosbags_messages(good, topics)
    with pytest.raises(ValueError, match="checksum"):
        _in_place_messages(bad, topics)
    with pytest.raises(ReaderError, match="checksum"):  # as rosbags finds it
        _rosbags_messages(bad, topics)


def test_compressed_chunks_are_read_through_rosbags(tmp_path):
    bag = _mixed_bag(tmp_path / "zstd", compress=True)
    assert plan(bag) is None
    with RosBag(bag) as b:
        assert b.in_place is None
    topics = {"/camera/image": IMAGE}
    assert len(_rosbags_messages(bag, topics)) == 5


@pytest.fixture(scope="module")
def episode(tmp_path_factory) -> Path:
    """Six 1280 x 720 frames of the sample pairs as an MCAP bag (what `dgli track` reads)."""
    from dgli_vision.sources.frames import read_frame
    from dgli_vision.sources.labelled import find_pairs

    pairs = find_pairs(Path(__file__).resolve().parents[1] / "sample_images")[:3]
    frames = [read_frame(p.color, p.depth) for p in pairs]
    data = ((1.7e9 + k / 30, frames[k % 3].color, frames[k % 3].depth_mm) for k in range(6))
    return write_bag(tmp_path_factory.mktemp("ep") / "bag", data, frames[0].intrinsics)


def test_a_frames_pixels_go_to_its_worker_as_where_they_lie(episode):
    through_rosbags = []
    with RosBag(episode) as bag:
        topics = ros_bags.choose_topics(bag.types, bag.counts, str(episode))
        for item in ros_bags.read_bag_messages(bag, topics):
            if isinstance(item, ros_bags.BagMessage):
                through_rosbags.append(bytes(item.payload.data))
    frames = list(open_recording(episode).frames)
    assert len(frames) == 6
    slots = SharedSlots(2)
    try:
        for k, pair in enumerate(frames):
            assert isinstance(pair.color_payload.data, FileSpan)
            assert isinstance(pair.depth_payload.data, FileSpan)
            assert bytes(pair.color_payload.data.view()) == through_rosbags[2 * k]
            assert bytes(pair.depth_payload.data.view()) == through_rosbags[2 * k + 1]
            sent, slot = pair.shared(slots)
            assert sent is pair and slot is None  # nothing copied into a slot
        assert slots.path is None
    finally:
        slots.close()


def test_tracking_in_place_gives_what_reading_through_rosbags_gives(episode, monkeypatch):
    def track() -> str:
        r = CliRunner().invoke(main, ["track", str(episode), "-j", "2", "--json"])
        assert r.exit_code == 0, r.output
        return r.output

    in_place = track()
    monkeypatch.setattr(ros_bags, "in_place_reader", lambda bag, topics: None)
    through_rosbags = track()
    assert in_place == through_rosbags
    assert json.loads(in_place)["n_frames"] == 6


def test_a_corrupt_chunk_stops_with_one_line(episode, tmp_path):
    (single,) = episode.glob("*.mcap")
    data = bytearray(single.read_bytes())
    first = 8 + 1 + 8 + struct.unpack_from("<Q", data, 9)[0]
    while data[first] != 0x06:
        first += 9 + struct.unpack_from("<Q", data, first + 1)[0]
    (n,) = struct.unpack_from("<I", data, first + 37)
    record = first + 41 + n + 8
    while data[record] != 0x05:  # the first message record of the first chunk
        record += 9 + struct.unpack_from("<Q", data, record + 1)[0]
    struct.pack_into("<Q", data, record + 1, 1 << 40)  # its length now runs past the chunk
    cut = tmp_path / "corrupt.mcap"
    cut.write_bytes(bytes(data))
    r = CliRunner().invoke(main, ["track", str(cut), "-j", "1"])
    assert r.exit_code == 2
    (line,) = r.output.strip().splitlines()
    assert str(cut) in line and "truncated or corrupt" in line and "Traceback" not in line


def test_the_workers_started_before_the_references_load_are_those_used(episode, monkeypatch):
    from dgli_vision.analysis import evaluate, workers

    taken = []
    take = workers.take_early_workers

    def recording_take(*args):
        pool = take(*args)
        taken.append(pool)
        return pool

    monkeypatch.setattr(workers, "take_early_workers", recording_take)
    r = CliRunner().invoke(main, ["track", str(episode), "-j", "2", "--json"])
    assert r.exit_code == 0, r.output
    assert taken and taken[-1] is not None
    assert evaluate._POOL[1] is taken[-1]  # one start of the workers, not two

