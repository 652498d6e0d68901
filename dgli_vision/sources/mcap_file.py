"""The messages of a ROS 2 MCAP recording read in place, per the MCAP specification
(https://mcap.dev/spec), when its chunks are stored uncompressed (as ``rosbags`` and
``ros2 bag record`` without compression write them).

A raw image is 4.6 MB at 1280 x 720: rather than reading each message's bytes (which
``rosbags`` copies three times), only the records' headers are read, and each message
is given as where its bytes lie in the file (:class:`McapMessage`), so that the process
that classifies the frame maps them itself. Messages come in the order ``rosbags``
gives them: by log time, a tie by the chunk's place in the file, then the chunk's
order; a chunk's messages outside its indexed time range, and chunks whose message
index lists none of the channels read, are left out as ``rosbags`` leaves them out.

The file's summary (its schemas, channels and chunk indexes) is read by the ``mcap``
package (the MCAP project's own reader, in the ``recordings`` extra). The records of a
chunk are walked here: the ``mcap`` reader hands out each message's bytes, copied out
of the file, and not where they lie, which is what lets a frame's pixels go to a worker
process without being read in this one.

Anything else (compressed chunks, no summary section, a bag folder compressed as a
whole or per message, several channels on one topic, no ``mcap`` package) is not read
here: :func:`plan` returns None and the caller reads the recording through
``rosbags`` (which decompresses zstd and lz4 chunks).
"""

from __future__ import annotations

import heapq
import os
import struct
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from ..core.errors import McapError

__all__ = ["McapError", "McapMessage", "McapPlan", "plan"]

MAGIC = b"\x89MCAP0\r\n"
_MESSAGE, _CHUNK = 0x05, 0x06
_U32, _U64 = struct.Struct("<I"), struct.Struct("<Q")
_RECORD = struct.Struct("<BQ")  # opcode, length
_MESSAGE_HEAD = struct.Struct("<BQHIQQ")  # opcode, length, channel, sequence, log, publish
_CHUNK_HEAD = struct.Struct("<BQQQQI")  # opcode, length, start, end, size, crc


@dataclass(frozen=True)
class McapMessage:
    """One message: its topic and type, its log time (ns), and its serialised bytes as
    ``length`` bytes at ``offset`` of ``path``."""

    topic: str
    msgtype: str
    log_time: int
    path: str
    offset: int
    length: int


@dataclass(frozen=True)
class _Chunk:
    start: int
    end: int
    offset: int
    channels: frozenset[int]  # the channels its message index lists messages of


@dataclass(frozen=True)
class _File:
    path: str
    channels: dict[int, tuple[str, str]]  # id: (topic, schema name)
    chunks: tuple[_Chunk, ...]


@dataclass(frozen=True)
class McapPlan:
    """The MCAP files of a recording, in order, their channels and chunk indexes."""

    files: tuple[_File, ...]

    def covers(self, topics: dict[str, str]) -> bool:
        """Every channel on one of ``topics`` (topic: message type) carries that type."""
        return all(
            topics.get(topic, schema) == schema
            for f in self.files
            for topic, schema in f.channels.values()
        )

    def messages(self, topics: dict[str, str]) -> Iterator[McapMessage]:
        """The messages on ``topics`` (topic: message type), file after file, each file's
        in ``rosbags``' order.

        Raises
        ------
        McapError, OSError
            A chunk or record that runs past its end, or the file cannot be read.
        """
        for f in self.files:
            wanted = {
                cid: tc for cid, tc in f.channels.items() if topics.get(tc[0]) == tc[1]
            }
            if wanted:
                yield from _file_messages(f, wanted)


def _pread(fd: int, size: int, offset: int) -> bytes:
    data = os.pread(fd, size, offset)
    if len(data) != size:
        raise McapError(f"truncated record at offset {offset}")
    return data


def _channel_counts(ci: object) -> frozenset[int]:
    """The channels a chunk's message index lists messages of: a channel's message count
    as ``rosbags`` reckons it from where the indexes lie (16 bytes a message after a
    15-byte header)."""
    offsets = ci.message_index_offsets  # type: ignore[attr-defined]
    ordered = sorted((o, cid) for cid, o in offsets.items())
    end = ci.chunk_start_offset + ci.chunk_length + ci.message_index_length  # type: ignore[attr-defined]
    ends = [o for o, _ in ordered[1:]] + [end]
    return frozenset(cid for (o, cid), e in zip(ordered, ends) if (e - o - 15) // 16)


def _read_file(path: Path) -> _File | None:
    """A file's channels and chunks from its summary (read by the ``mcap`` package);
    None when it cannot be read here (no summary, compressed chunks, a topic on two
    channels, not MCAP)."""
    from mcap.reader import make_reader

    with open(path, "rb") as f:
        if f.read(8) != MAGIC:
            return None
        f.seek(0)
        summary = make_reader(f).get_summary()
    if summary is None:
        return None
    channels = {
        cid: (c.topic, summary.schemas[c.schema_id].name
              if c.schema_id in summary.schemas else "__schemaless__")
        for cid, c in summary.channels.items()
    }
    chunks = []
    for ci in summary.chunk_indexes:
        if ci.compression:
            return None
        chunks.append(_Chunk(ci.message_start_time, ci.message_end_time,
                             ci.chunk_start_offset, _channel_counts(ci)))
    topics = [t for t, _ in channels.values()]
    if not chunks or len(set(topics)) != len(topics):
        return None
    return _File(str(path), channels, tuple(chunks))


def _bag_files(path: Path) -> list[Path] | None:
    """The MCAP files of a ``.mcap`` file or of a ROS 2 bag folder, in order; None when
    the bag is not MCAP or is compressed as a whole or per message."""
    if path.is_file():
        return [path] if path.suffix == ".mcap" else None
    from ruamel.yaml import YAML  # what rosbags reads metadata.yaml with

    meta = YAML(typ="safe").load((path / "metadata.yaml").read_text())
    info = meta["rosbag2_bagfile_information"]
    mode = str(info.get("compression_mode") or "").lower()
    if info.get("storage_identifier") != "mcap" or mode not in ("", "none"):
        return None
    files = [path / Path(str(name)).name for name in info["relative_file_paths"]]
    return files if files and all(f.suffix == ".mcap" for f in files) else None


def plan(path: str | Path) -> McapPlan | None:
    """How to read the recording at ``path`` in place (see the module docstring); None
    when it is not an MCAP recording with uncompressed chunks and a summary, or cannot
    be read so (the caller then reads it through ``rosbags``, which says why)."""
    try:
        files = _bag_files(Path(path))
        parsed = [_read_file(f) for f in files] if files else None
    except Exception:  # any reader's error: rosbags reads the file, or names what is wrong
        return None
    if not parsed or any(f is None for f in parsed):
        return None
    return McapPlan(tuple(f for f in parsed if f is not None))


class _Window:
    """Reads of one file through a window of a few kilobytes: a chunk's header and its
    records' headers mostly lie in the first, so a chunk costs about one system call."""

    SIZE = 4096

    def __init__(self, fd: int) -> None:
        self.fd, self.start, self.data = fd, 0, b""

    def read(self, offset: int, size: int) -> bytes:
        at = offset - self.start
        if at < 0 or at + size > len(self.data):
            self.start, self.data = offset, os.pread(self.fd, max(size, self.SIZE), offset)
            at = 0
        out = self.data[at : at + size]
        if len(out) != size:
            raise McapError(f"truncated record at offset {offset}")
        return out


def _chunk_messages(
    window: _Window, chunk: _Chunk, wanted: dict[int, tuple[str, str]]
) -> Iterator[tuple[int, int, int, int, int, int]]:
    """The messages of one chunk on the ``wanted`` channels, sorted by log time:
    ``(log time, chunk offset, order, channel, data offset, data length)``, after a
    first item that holds the chunk's start time (read only when the merge comes to it)."""
    yield (chunk.start, 0, -1, -1, -1, -1)
    op, length, _, _, size, crc = _CHUNK_HEAD.unpack(window.read(chunk.offset, _CHUNK_HEAD.size))
    if op != _CHUNK:
        raise McapError(f"no chunk at offset {chunk.offset}")
    pos = chunk.offset + _CHUNK_HEAD.size
    (n,) = _U32.unpack(window.read(pos, 4))
    pos += 4 + n
    (records,) = _U64.unpack(window.read(pos, 8))
    pos += 8
    end = pos + records
    if records != size or end > chunk.offset + 9 + length:
        raise McapError(f"chunk at offset {chunk.offset}: records do not fit")
    if crc:
        _check_crc(window.fd, pos, records, crc, chunk.offset)
    found = []
    while pos < end:
        op, length = _RECORD.unpack(window.read(pos, 9))
        if pos + 9 + length > end:
            raise McapError(f"record at offset {pos} runs past its chunk")
        if op == _MESSAGE:
            if length < 22:
                raise McapError(f"message record at offset {pos} is too short")
            _, _, channel, _, log_time, _ = _MESSAGE_HEAD.unpack(
                window.read(pos, _MESSAGE_HEAD.size)
            )
            if chunk.start <= log_time <= chunk.end and channel in wanted:
                found.append((log_time, channel, pos + 9 + 22, length - 22))
        pos += 9 + length
    found.sort(key=lambda m: m[0])
    for k, (log_time, channel, offset, n) in enumerate(found):
        yield (log_time, chunk.offset, k, channel, offset, n)


def _check_crc(fd: int, pos: int, size: int, crc: int, where: int) -> None:
    from binascii import crc32

    value, done = 0, 0
    while done < size:
        block = _pread(fd, min(1 << 22, size - done), pos + done)
        value = crc32(block, value)
        done += len(block)
    if value != crc:
        raise McapError(f"chunk at offset {where}: checksum mismatch")


def _file_messages(f: _File, wanted: dict[int, tuple[str, str]]) -> Iterator[McapMessage]:
    fd = os.open(f.path, os.O_RDONLY)
    try:
        window = _Window(fd)
        sources = [
            _chunk_messages(window, c, wanted) for c in f.chunks if c.channels & wanted.keys()
        ]
        for log_time, _, order, channel, offset, n in heapq.merge(*sources):
            if order >= 0:
                topic, msgtype = wanted[channel]
                yield McapMessage(topic, msgtype, log_time, f.path, offset, n)
    finally:
        os.close(fd)
