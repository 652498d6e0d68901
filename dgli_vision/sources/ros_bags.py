"""ROS 1 (``.bag``) and ROS 2 (``.db3``, ``.mcap`` or a bag folder) recordings, through
``rosbags`` (pure Python, no ROS install; the ``recordings`` extra).

The colour, aligned-depth and ``CameraInfo`` topics are found by message type and usual
names (a RealSense or Kinect driver's ``.../color/image_raw``,
``.../aligned_depth_to_color/image_raw`` and their ``camera_info``), or named by the
user. Messages are read one at a time and paired by timestamp (:mod:`.pairing`), so
memory stays flat however long the episode; each frame's pixels stay encoded
(:class:`~dgli_vision.sources.ros_images.ImagePayload`) until a worker classifies it.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..core.camera import Intrinsics
from ..core.errors import InvalidInputError, UnreadableInputError
from ..core.parallel import FileSpan
from .ros_images import COLOR_ENCODINGS, DEPTH_ENCODINGS, ImagePayload

__all__ = [
    "BagMessage",
    "BagTopics",
    "InfoMessage",
    "RosBag",
    "choose_topics",
    "in_place_reader",
    "is_ros_bag",
    "read_bag_messages",
]

IMAGE = "sensor_msgs/msg/Image"
COMPRESSED = "sensor_msgs/msg/CompressedImage"
INFO = "sensor_msgs/msg/CameraInfo"


def _rosbags() -> Any:
    """The ``rosbags`` modules, imported on first use."""
    try:
        from rosbags import highlevel, typesys
    except ImportError:
        raise UnreadableInputError(
            "reading ROS bags needs the 'recordings' extra: pip install 'dgli_vision[recordings]'"
        ) from None
    return highlevel, typesys


def is_ros_bag(path: Path) -> bool:
    """A ROS 1 ``.bag`` file, a ROS 2 ``.db3`` or ``.mcap`` file, or a ROS 2 bag folder."""
    if path.is_dir():
        return (path / "metadata.yaml").is_file()
    return path.suffix in (".bag", ".db3", ".mcap")


@dataclass(frozen=True)
class BagTopics:
    """The topics a recording is read from.

    Attributes
    ----------
    color, depth : str
        Image (or CompressedImage) topics.
    info : str or None
        The colour camera's ``CameraInfo`` topic (None: none in the bag).
    counts : dict of str to int
        Messages per topic.
    """

    color: str
    depth: str
    info: str | None
    counts: dict[str, int]


@dataclass(frozen=True)
class InfoMessage:
    """The camera's intrinsics from a ``CameraInfo`` message, and a note on its lens
    distortion when that is not zero."""

    intrinsics: Intrinsics
    note: str | None


@dataclass(frozen=True)
class BagMessage:
    """One image message: its stream, its time (seconds, header stamp) and its pixels."""

    stream: str
    time: float
    payload: ImagePayload


def _stamp(msg: Any, bag_ns: int) -> float:
    stamp = msg.header.stamp
    t = stamp.sec + stamp.nanosec * 1e-9
    return t if t > 0 else bag_ns * 1e-9  # drivers that leave the stamp empty


def _describe(topics: dict[str, str]) -> str:
    return ", ".join(f"{t} ({ty.rsplit('/', 1)[-1]})" for t, ty in sorted(topics.items()))


def _pick(
    images: dict[str, str],
    wanted: Callable[[str], bool],
    prefer: tuple[str, ...],
    what: str,
    flag: str,
    src: str,
) -> str:
    """The one image topic ``wanted`` selects: raw before its compressed republication,
    then the first word of ``prefer`` its name contains; an error when none or several."""
    candidates = [t for t in images if wanted(t)]
    if not candidates:
        raise InvalidInputError(
            f"recording '{src}' has no {what} image topic (images: {_describe(images)}); "
            f"name one with {flag}"
        )
    candidates = [t for t in candidates if images[t] == IMAGE] or candidates
    for word in prefer:
        hits = [t for t in candidates if word in t.lower()]
        if len(hits) == 1:
            return hits[0]
        if hits:
            candidates = hits
            break
    if len(candidates) == 1:
        return candidates[0]
    raise InvalidInputError(
        f"recording '{src}' has several {what} topics ({', '.join(sorted(candidates))}); "
        f"choose one with {flag}"
    )


def choose_topics(
    types: dict[str, str],
    counts: dict[str, int],
    src: str,
    *,
    color: str | None = None,
    depth: str | None = None,
    info: str | None = None,
) -> BagTopics:
    """The colour, depth and camera-info topics of a bag (see the module docstring).

    Parameters
    ----------
    types : dict of str to str
        Message type of every topic.
    counts : dict of str to int
        Messages per topic.
    src : str
        The recording, for messages.
    color, depth, info : str, keyword-only, optional
        Topics named by the user (checked to exist and to carry the right type).

    Raises
    ------
    InvalidInputError
        No image topic, an ambiguous choice, or a named topic missing or of another type.
    """
    images = {t: ty for t, ty in types.items() if ty in (IMAGE, COMPRESSED)}
    if not images:
        raise InvalidInputError(
            f"recording '{src}' has no image topic (topics: {_describe(types) or 'none'})"
        )

    def named(topic: str, kinds: tuple[str, ...], flag: str) -> str:
        if topic not in types:
            raise InvalidInputError(
                f"recording '{src}' has no topic {topic} ({flag}; topics: {_describe(types)})"
            )
        if types[topic] not in kinds:
            raise InvalidInputError(
                f"recording '{src}': topic {topic} ({flag}) carries {types[topic]}, "
                f"not {' or '.join(kinds)}"
            )
        return topic

    if depth:
        depth = named(depth, (IMAGE, COMPRESSED), "--depth-topic")
    else:
        depth = _pick(
            images,
            lambda t: "depth" in t.lower(),
            ("aligned_depth_to_color", "aligned"),
            "depth",
            "--depth-topic",
            src,
        )
    if color:
        color = named(color, (IMAGE, COMPRESSED), "--color-topic")
    else:
        color = _pick(
            images,
            lambda t: "depth" not in t.lower() and t != depth,
            ("color", "rgb"),
            "colour",
            "--color-topic",
            src,
        )
    if info:
        info = named(info, (INFO,), "--info-topic")
    else:
        infos = [t for t, ty in types.items() if ty == INFO]
        base = color.removesuffix("/compressed").rsplit("/", 1)[0]
        dbase = depth.removesuffix("/compressedDepth").rsplit("/", 1)[0]
        same = [t for t in infos if t.rsplit("/", 1)[0] in (base, dbase)]
        same.sort(key=lambda t: t.rsplit("/", 1)[0] != base)  # colour's own first
        info = same[0] if same else (infos[0] if len(infos) == 1 else None)
    return BagTopics(color, depth, info, {t: counts.get(t, 0) for t in types})


def _info_field(msg: Any, name: str) -> Any:
    """A ``CameraInfo`` array by its ROS 2 name (``k``, ``d``) or its ROS 1 name (``K``, ``D``)."""
    value = getattr(msg, name, None)
    return getattr(msg, name.upper(), None) if value is None else value


def _intrinsics(msg: Any) -> tuple[Intrinsics, str | None]:
    """Intrinsics of a ``CameraInfo``, with its ``d`` when the model is OpenCV's
    (``plumb_bob``, ``rational_polynomial``); a note says what was done with a lens
    distortion that is not zero."""
    from .intrinsics_files import SUPPORTED_DISTORTION_MODELS

    k, d = _info_field(msg, "k"), _info_field(msg, "d")
    d = [float(v) for v in d] if d is not None else []
    model = str(getattr(msg, "distortion_model", "") or "")
    usable = model in ("", *SUPPORTED_DISTORTION_MODELS) and len(d) <= 14
    intr = Intrinsics(
        int(msg.width),
        int(msg.height),
        *(float(k[i]) for i in (0, 4, 2, 5)),
        distortion=tuple(d) if usable and any(d) else (),
    )
    note = None
    if any(abs(v) > 1e-12 for v in d):
        coeffs = ", ".join(f"{v:.4g}" for v in d)
        note = f"camera_info has non-zero {model or 'lens'} distortion [{coeffs}]; " + (
            "sticker centres are undistorted with it"
            if usable
            else "not a model dgli reads, so images are used as recorded (not undistorted)"
        )
    return intr, note


def _payload(
    msg: Any, msgtype: str, stream: str, where: str, data: Any = None
) -> ImagePayload:
    """The message's pixels, ``data`` (where they lie in the file) or its own."""
    if msgtype == COMPRESSED:
        return ImagePayload(
            f"compressed:{msg.format}", 0, 0, 0, False, bytes(msg.data) if data is None else data
        )
    known = COLOR_ENCODINGS if stream == "color" else DEPTH_ENCODINGS
    if msg.encoding not in known:
        what = "colour" if stream == "color" else "depth"
        raise InvalidInputError(
            f"{where}: {what} encoding '{msg.encoding}' is not supported "
            f"(expected one of {', '.join(known)})"
        )
    return ImagePayload(
        msg.encoding,
        int(msg.width),
        int(msg.height),
        int(msg.step),
        bool(msg.is_bigendian),
        msg.data if data is None else data,  # an array over the message read: no copy
    )


def _read_errors() -> tuple[type[BaseException], ...]:
    """What ``rosbags`` raises on a truncated or corrupt bag."""
    import sqlite3
    import struct

    from rosbags.highlevel import AnyReaderError
    from rosbags.rosbag1 import ReaderError as Reader1Error
    from rosbags.rosbag2 import ReaderError as Reader2Error
    from rosbags.serde import SerdeError

    try:  # rosbags reads ROS 2 sqlite3 bags through apsw when it is installed
        import apsw

        apsw_errors: tuple[type[BaseException], ...] = (apsw.Error,)
    except ImportError:
        apsw_errors = ()
    return (
        *apsw_errors,
        AnyReaderError,
        Reader1Error,
        Reader2Error,
        SerdeError,
        sqlite3.DatabaseError,
        struct.error,
        OSError,
        EOFError,
        ValueError,
        KeyError,
    )


class RosBag:
    """An open ROS bag: ``with RosBag(path) as bag:``; ``bag.reader`` is rosbags'
    ``AnyReader`` and ``bag.types``/``bag.counts`` describe its topics.

    Raises
    ------
    UnreadableInputError
        The extra is missing, or the bag is truncated, corrupt or not a bag.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)

    def __enter__(self) -> RosBag:
        highlevel, typesys = _rosbags()
        errors = _read_errors()
        try:
            try:  # most bags carry their message definitions: no default types to load
                self.reader = highlevel.AnyReader([self.path])
                self.reader.open()
            except highlevel.AnyReaderError:  # none (or another problem, said again)
                store = typesys.get_typestore(typesys.Stores.ROS2_HUMBLE)
                self.reader = highlevel.AnyReader([self.path], default_typestore=store)
                self.reader.open()
        except errors as exc:
            raise UnreadableInputError(
                f"recording '{self.path}' cannot be read (truncated, corrupt or not a bag): "
                f"{str(exc).strip() or type(exc).__name__}"
            ) from None
        self.types = {c.topic: c.msgtype for c in self.reader.connections}
        self.counts: dict[str, int] = {}
        for c in self.reader.connections:
            self.counts[c.topic] = self.counts.get(c.topic, 0) + c.msgcount
        self.in_place = None  # how to read it in place (an MCAP recording), if it can be
        if self.reader.is2:
            from .mcap_file import plan

            self.in_place = plan(self.path)
        return self

    def __exit__(self, *exc: object) -> None:
        self.reader.close()


def read_bag_messages(bag: RosBag, topics: BagTopics) -> Iterator[BagMessage | InfoMessage]:
    """The image messages of ``bag`` on ``topics``, one at a time, in recording order,
    with an :class:`InfoMessage` whenever the camera info changes.

    Raises
    ------
    InvalidInputError
        An unsupported encoding (named with its topic and time).
    UnreadableInputError
        The bag is truncated or corrupt part-way.
    """
    reader = bag.reader
    wanted = _streams(topics)
    conns = [c for c in reader.connections if c.topic in wanted]

    def items() -> Iterator[tuple[str, str, int, Any, Any]]:
        for conn, bag_ns, raw in reader.messages(connections=conns):
            # a view: rosbags slices off the CDR header, which copies a whole image of bytes
            msg = reader.deserialize(memoryview(raw), conn.msgtype)
            yield conn.topic, conn.msgtype, bag_ns, msg, None

    return _messages(items(), wanted, bag.path)


def in_place_reader(
    bag: RosBag, topics: BagTopics
) -> Callable[[], Iterator[BagMessage | InfoMessage]] | None:
    """What :func:`read_bag_messages` gives, read in place from the recording's MCAP files
    (:mod:`.mcap_file`), without ``bag`` staying open: each image's pixels are a
    :class:`~dgli_vision.core.parallel.FileSpan` of the file, mapped only where the frame
    is decoded. None when the recording cannot be read so.
    """
    wanted = _streams(topics)
    types = {t: bag.types[t] for t in wanted}
    plan = bag.in_place
    if plan is None or not plan.covers(types):
        return None
    typestore, path = bag.reader.typestore, bag.path

    def items() -> Iterator[tuple[str, str, int, Any, Any]]:
        for m in plan.messages(types):
            view = FileSpan(m.path, m.offset, m.length).view()
            msg = typestore.deserialize_cdr(view, m.msgtype)
            yield m.topic, m.msgtype, m.log_time, msg, _span_of(msg, view, m)

    return lambda: _messages(items(), wanted, path)


def _span_of(msg: Any, view: memoryview, m: Any) -> FileSpan | None:
    """Where an image message's pixels lie in its file (None: not an image, or its
    ``data`` is not a view of the message's bytes)."""
    import numpy as np

    data = getattr(msg, "data", None)
    if m.msgtype not in (IMAGE, COMPRESSED) or not isinstance(data, np.ndarray):
        return None
    if data.dtype != np.uint8 or data.ndim != 1 or not data.flags.c_contiguous or not data.size:
        return None
    base = np.frombuffer(view, np.uint8).__array_interface__["data"][0]
    start = data.__array_interface__["data"][0] - base
    if start < 0 or start + data.size > len(view):
        return None
    return FileSpan(m.path, m.offset + start, data.size)


def _streams(topics: BagTopics) -> dict[str, str]:
    wanted = {topics.color: "color", topics.depth: "depth"}
    if topics.info:
        wanted[topics.info] = "info"
    return wanted


def _messages(
    items: Iterator[tuple[str, str, int, Any, Any]], wanted: dict[str, str], path: Path
) -> Iterator[BagMessage | InfoMessage]:
    """The messages of ``items`` (topic, type, bag time in ns, message, where its pixels
    lie or None) as :func:`read_bag_messages` gives them."""
    errors = _read_errors()
    last_info, first_t, last_t = None, None, 0.0
    while True:
        try:
            item = next(items, None)
            if item is None:
                return
            topic, msgtype, bag_ns, msg, span = item
        except errors as exc:
            where = "" if first_t is None else f" after {last_t - first_t:.3f} s"
            raise UnreadableInputError(
                f"recording '{path}' cannot be read{where} (truncated or corrupt): "
                f"{str(exc).strip() or type(exc).__name__}"
            ) from None
        stream = wanted[topic]
        last_t = bag_ns * 1e-9
        first_t = last_t if first_t is None else first_t
        if stream == "info":
            info = InfoMessage(*_intrinsics(msg))
            if info != last_info:  # drivers repeat it with every frame
                last_info = info
                yield info
            continue
        t = _stamp(msg, bag_ns)
        where = f"recording '{path}' topic {topic} at {t:.3f} s"
        yield BagMessage(stream, t, _payload(msg, msgtype, stream, where, span))
