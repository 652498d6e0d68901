"""The frames of a recording, in order: a folder of colour + depth pairs, a ROS 1 or
ROS 2 bag, or a RealSense SDK recording.

A folder holds ``<name>_color.png`` / ``<name>_depth.png`` pairs, in the order given by
a ``frames.csv`` (``color,depth[,time]``, paths relative to the folder) or, without
one, by name; a ``labels.csv`` (the labelled-folder format) labels the frames, so that
a tracker can score itself. A bag's frames are read one at a time as they are
classified (:func:`open_recording`); a labels file for it names frames by index or time.
"""

from __future__ import annotations

import csv
import os
from collections.abc import Callable, Iterable, Iterator
from contextlib import ExitStack
from dataclasses import dataclass, field, replace
from pathlib import Path

from ..core.camera import DEFAULT_INTRINSICS, Intrinsics
from ..core.errors import CalibrationError, InvalidInputError, UnreadableInputError
from ..core.frame import RGBDFrame
from ..core.parallel import FileSpan, SharedSlots, SlotRef
from .labelled import LabelledPair, find_labelled_pairs, folder_intrinsics
from .realsense import LivePair
from .ros_images import ImagePayload, decode_color, decode_depth

__all__ = [
    "RECORDING_READERS",
    "LivePair",
    "ReadingOptions",
    "RecordedPair",
    "Recording",
    "RecordingReader",
    "is_recording_file",
    "open_recording",
    "read_recording",
    "select_frames",
]


@dataclass(frozen=True)
class Recording:
    """The frames of a recording.

    Attributes
    ----------
    frames : iterable of LabelledPair
        In order; ``label`` is ``""`` for an unlabelled frame, ``time`` in seconds from
        the start where known. A bag's frames (:class:`RecordedPair`) can be iterated
        once; a folder's are a tuple.
    count : int
        How many frames to expect (for a progress bar; exact for a folder).
    labelled : bool
        Every frame carries a label (for a bag: a labels file was given).
    source : str
        The folder or file.
    kind : str
        ``"folder"``, ``"ROS 1 bag"``, ``"ROS 2 bag"`` or ``"RealSense recording"``.
    notes : list of str
        What reading found worth saying: the topics read, a lens distortion left
        uncorrected, depth frames no colour frame took (filled while the frames are read).
    """

    frames: Iterable[LabelledPair]
    count: int
    labelled: bool
    source: str
    kind: str = "folder"
    notes: list[str] = field(default_factory=list)


def _frames_csv(path: Path, root: Path) -> tuple[list[LabelledPair], list[float | None]]:
    pairs: list[LabelledPair] = []
    times: list[float | None] = []
    try:
        with path.open(newline="", encoding="utf-8-sig") as fh:  # a BOM is dropped
            reader = csv.DictReader(fh)
            missing = {"color", "depth"} - set(reader.fieldnames or [])
            if missing:
                raise InvalidInputError(
                    f"frames file '{path}' lacks column(s) {', '.join(sorted(missing))}; "
                    "expected color,depth[,time]"
                )
            for k, row in enumerate(reader, start=2):
                if not row.get("color") or not row.get("depth"):
                    raise InvalidInputError(f"frames file '{path}' line {k} is incomplete")
                t = (row.get("time") or "").strip()
                try:
                    times.append(float(t) if t else None)
                except ValueError:
                    raise InvalidInputError(
                        f"frames file '{path}' line {k}: time {t!r} is not a number"
                    ) from None
                pairs.append(LabelledPair(str(root / row["color"]), str(root / row["depth"]), ""))
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise UnreadableInputError(f"cannot read frames file '{path}': {exc}") from None
    return pairs, times


def read_recording(folder: str | Path) -> Recording:
    """The frames of ``folder`` in order, labelled when it has a ``labels.csv``.

    Raises
    ------
    UnreadableInputError, InvalidInputError
        The folder is missing, a CSV file is malformed, or no frame is found.
    """
    root = Path(folder)
    if not root.is_dir():
        raise UnreadableInputError(f"folder '{root}' does not exist or is not a directory")
    listing = root / "frames.csv"
    if listing.is_file():
        pairs, times = _frames_csv(listing, root)
    else:
        pairs = []
        for color in sorted(root.rglob("*_color.png")):
            depth = color.with_name(color.name[: -len("_color.png")] + "_depth.png")
            pairs.append(LabelledPair(str(color), str(depth), ""))
        times = [None] * len(pairs)
    if not pairs:
        raise InvalidInputError(
            f"folder '{root}' holds no frames (no frames.csv and no <name>_color.png files)"
        )
    labelled = False
    if (root / "labels.csv").is_file():
        known, _ = find_labelled_pairs(root, lenient=True)
        by_color = {os.path.realpath(p.color): p for p in known}
        found = [by_color.get(os.path.realpath(p.color)) for p in pairs]
        labelled = all(f is not None for f in found)
        pairs = [
            LabelledPair(p.color, p.depth, f.label, f.variant, f.line) if f else p
            for p, f in zip(pairs, found)
        ]
    pairs = [
        replace(p, time=t, intrinsics_file=folder_intrinsics(root, p.color))
        for p, t in zip(pairs, times)
    ]
    return Recording(tuple(pairs), len(pairs), labelled, str(root))


@dataclass(frozen=True)
class RecordedPair(LabelledPair):
    """A frame of a recorded episode: its colour and depth pixels, still encoded.

    ``color`` and ``depth`` name the frame (recording, topic, frame number, time) for
    messages and reports. ``problem`` says why the frame cannot be classified (a colour
    image with no depth near it in time): it is then a gap, not a lost frame.
    """

    color_payload: ImagePayload | None = None
    depth_payload: ImagePayload | None = None
    intrinsics: Intrinsics | None = None
    problem: str | None = None

    def load(self) -> RGBDFrame:
        """The decoded, validated frame.

        Raises
        ------
        InvalidInputError, CalibrationError
        """
        if self.problem or self.color_payload is None or self.depth_payload is None:
            raise InvalidInputError(self.problem or f"{self.color}: no image")
        color = decode_color(_in_memory(self.color_payload, self.color), self.color)
        depth = decode_depth(_in_memory(self.depth_payload, self.depth), self.depth)
        if color.shape[:2] != depth.shape:
            raise InvalidInputError(
                f"{self.depth}: depth is {depth.shape[1]}x{depth.shape[0]} but colour is "
                f"{color.shape[1]}x{color.shape[0]}: depth not aligned to colour (record "
                "the driver's aligned_depth_to_color topic)"
            )
        intr, source = self.intrinsics, "camera_info"
        if intr is None:
            intr, source = DEFAULT_INTRINSICS, "default"
        if (intr.width, intr.height) != (depth.shape[1], depth.shape[0]):
            raise CalibrationError(
                f"{self.color}: camera info is for {intr.width}x{intr.height} images but the "
                f"frame is {depth.shape[1]}x{depth.shape[0]}"
            )
        return RGBDFrame(color, depth, intr, self.color, self.depth, source)

    def light(self) -> LabelledPair:
        """This frame as names only, without its pixels (what an outcome keeps)."""
        return LabelledPair(self.color, self.depth, self.label, self.variant, self.line, self.time)

    def shared(self, slots: SharedSlots) -> tuple[RecordedPair, int | None]:
        """This frame with its pixels copied into a slot of ``slots``, for a worker process
        (what pickles is then a few names and numbers), and the slot to free once the
        worker is done; the frame itself and None when it has no pixels or no slot is
        free."""
        c, d = self.color_payload, self.depth_payload
        if self.problem or c is None or d is None:
            return self, None
        # pixels that lie in the recording's file as they are go as where they lie
        held = [p for p in (c, d) if not isinstance(p.data, FileSpan)]
        if not held:
            return self, None
        put = slots.put([p.data for p in held])
        if put is None:
            return self, None
        slot, refs = put
        sent = dict(zip(map(id, held), refs))
        c, d = (replace(p, data=sent[id(p)]) if id(p) in sent else p for p in (c, d))
        return replace(self, color_payload=c, depth_payload=d), slot


def _in_memory(p: ImagePayload, where: str) -> ImagePayload:
    """The payload with its bytes readable: mapped from their shared slot when they were
    sent in one (:meth:`RecordedPair.shared`), or from the recording's file.

    Raises
    ------
    UnreadableInputError
        The recording's file cannot be read there any more.
    """
    if not isinstance(p.data, (SlotRef, FileSpan)):
        return p
    try:
        return replace(p, data=p.data.view())
    except (OSError, ValueError) as exc:
        raise UnreadableInputError(f"{where}: cannot be read from the recording: {exc}") from None


def is_recording_file(path: str | Path) -> bool:
    """A recorded episode (a bag) rather than a folder of PNG pairs."""
    from .ros_bags import is_ros_bag

    return is_ros_bag(Path(path))


def _labels_file(path: Path) -> tuple[dict[int, tuple[str, str | None, int]], list]:
    """A recording's labels: ``frame`` (index from 0) or ``time`` (seconds from the
    start), ``label`` and optionally ``variant``."""
    from ..core.classes import CLASS_IDS, VARIANTS, class_id_of, digits_note

    by_frame: dict[int, tuple[str, str | None, int]] = {}
    by_time: list[tuple[float, str, str | None, int]] = []
    try:
        with path.open(newline="", encoding="utf-8-sig") as fh:  # a BOM is dropped
            reader = csv.DictReader(fh)
            cols = set(reader.fieldnames or [])
            if "label" not in cols or not cols & {"frame", "time"}:
                raise InvalidInputError(
                    f"labels file '{path}' needs columns frame or time, and label "
                    "(optionally variant)"
                )
            for k, row in enumerate(reader, start=2):
                written = (row.get("label") or "").strip()
                label = class_id_of(written) or written
                variant = (row.get("variant") or "").strip() or None
                if label not in CLASS_IDS or (variant and variant not in VARIANTS.get(label, ())):
                    raise InvalidInputError(
                        f"labels file '{path}' line {k}: unknown class or variant "
                        f"{label!r} {variant or ''}".rstrip() + digits_note(label)
                    )
                try:  # ASCII digits only (int() and float() read other scripts' too)
                    frame, time_s = (row.get("frame") or "").strip(), row.get("time") or ""
                    if not (frame.isascii() and time_s.isascii()):
                        raise ValueError(frame)
                    if frame:
                        by_frame[int(frame)] = (label, variant, k)
                    else:
                        by_time.append((float(time_s), label, variant, k))
                except ValueError:
                    raise InvalidInputError(
                        f"labels file '{path}' line {k}: frame or time is not a number"
                    ) from None
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise UnreadableInputError(f"cannot read labels file '{path}': {exc}") from None
    return by_frame, sorted(by_time)


def _label_frames(
    frames: Iterable[LabelledPair], path: Path, tolerance: float
) -> Iterator[LabelledPair]:
    """``frames`` with their labels; once all are read, a row that named no frame of the
    recording (a frame past its end, a time no frame is near) is an error.

    Raises
    ------
    InvalidInputError
        Naming the labels file, the row's line and the frames the recording has.
    """
    import bisect

    by_frame, by_time = _labels_file(path)
    times = [t for t, *_ in by_time]
    used: set[int] = set()  # the rows by time that labelled a frame
    n = 0
    for index, pair in enumerate(frames):
        n = index + 1
        found = by_frame.get(index)
        if found is None and pair.time is not None and times:
            k = bisect.bisect_left(times, pair.time)
            near = [j for j in (k - 1, k) if 0 <= j < len(times)]
            j = min(near, key=lambda j: abs(times[j] - pair.time))
            if abs(times[j] - pair.time) <= tolerance:
                found = by_time[j][1:]
                used.add(j)
        yield replace(pair, label=found[0], variant=found[1], line=found[2]) if found else pair
    _check_rows_named_frames(path, by_frame, by_time, used, n, tolerance)


def _no_such_frames(
    path: Path, by_frame: dict[int, tuple[str, str | None, int]], count: int
) -> None:
    """Refuse a row naming a frame number the recording (``count`` frames at most)
    cannot have.

    Raises
    ------
    InvalidInputError
    """
    past = sorted((line, f) for f, (_, _, line) in by_frame.items() if f < 0 or f >= count)
    if past:
        line, f = past[0]
        more = f" (and {len(past) - 1} more rows)" if len(past) > 1 else ""
        raise InvalidInputError(
            f"labels file '{path}' line {line}: frame {f} does not exist; the recording has "
            f"{count} frame{'s' if count != 1 else ''} (0 to {count - 1}){more}"
        )


def _check_rows_named_frames(
    path: Path,
    by_frame: dict[int, tuple[str, str | None, int]],
    by_time: list[tuple[float, str, str | None, int]],
    used: set[int],
    count: int,
    tolerance: float,
) -> None:
    """Every row of the labels file named a frame of the recording read (``count``
    frames); ``used``: the rows by time that did.

    Raises
    ------
    InvalidInputError
    """
    _no_such_frames(path, by_frame, count)
    unused = [(row[3], row[0]) for j, row in enumerate(by_time) if j not in used]
    if unused:
        line, t = min(unused)
        more = f" (and {len(unused) - 1} more rows)" if len(unused) > 1 else ""
        raise InvalidInputError(
            f"labels file '{path}' line {line}: no frame of the recording within "
            f"{round(tolerance * 1000)} ms of time {t:g} s{more}"
        )


def select_frames(
    frames: Iterable[LabelledPair],
    *,
    every: int = 1,
    start: float | None = None,
    end: float | None = None,
) -> Iterator[tuple[int, LabelledPair]]:
    """Every ``every``-th frame with its index, between ``start`` and ``end`` seconds
    (frames of unknown time are kept); stops reading at ``end``."""
    for index, pair in enumerate(frames):
        t = pair.time
        if end is not None and t is not None and t > end:
            return
        if (start is None or t is None or t >= start) and index % every == 0:
            yield index, pair


def open_recording(
    path: str | Path,
    *,
    color_topic: str | None = None,
    depth_topic: str | None = None,
    info_topic: str | None = None,
    tolerance: float = 0.020,
    labels: str | Path | None = None,
    live: bool = False,
) -> Recording:
    """Any recording: a folder of pairs (:func:`read_recording`), a ROS 1 ``.bag``, a
    ROS 2 bag (``.db3``, ``.mcap`` or its folder), or a RealSense SDK recording (``.db3``
    or ``.bag`` with RealSense's own topics; needs the ``realsense`` extra).

    Parameters
    ----------
    path : str or Path
    color_topic, depth_topic, info_topic : str, keyword-only, optional
        A ROS bag's topics, when the usual names do not find them.
    tolerance : float, keyword-only
        Largest time difference (seconds) between a colour image and its depth.
    labels : str or Path, keyword-only, optional
        A bag's labels file (``frame`` or ``time``, ``label``, ``variant``); a folder
        has its own ``labels.csv``.
    live : bool, keyword-only
        For the live loop, in this process: a RealSense recording's frames are aligned
        only when loaded (:class:`LivePair`).

    Raises
    ------
    UnreadableInputError, InvalidInputError
        One line naming the recording and what is wrong (no image topic, an ambiguous
        topic, a truncated file, the ``recordings`` extra missing...).
    """
    p = Path(path)
    if not p.exists():
        raise UnreadableInputError(f"recording '{p}' does not exist")
    reader = next((r for r in RECORDING_READERS if r.claims(p)), None)
    if reader is None:
        shown = [r.what for r in reversed(RECORDING_READERS)]
        raise UnreadableInputError(
            f"'{p}' is not a recording: expected {', '.join(shown[:-1])} or {shown[-1]}"
        )
    if labels is not None and not reader.takes_labels:
        raise InvalidInputError(
            f"--labels is for recorded episodes; {reader.name} '{p}' is labelled by its "
            "labels.csv"
        )
    options = ReadingOptions(color_topic, depth_topic, info_topic, tolerance, live)
    recording = reader.read(p, options)
    if labels is None:
        return recording
    labels_path = Path(labels)
    by_frame, _ = _labels_file(labels_path)  # a malformed file stops the run before the work
    if recording.kind.startswith("ROS"):  # a bag's count of colour messages is exact
        _no_such_frames(labels_path, by_frame, recording.count)
    return replace(
        recording, frames=_label_frames(recording.frames, labels_path, tolerance), labelled=True
    )


def _realsense_recording(p: Path, tolerance: float, live: bool = False) -> Recording:
    """A RealSense SDK recording, played through the SDK (:mod:`.realsense`): each frame's
    colour and depth aligned to it, with the colour stream's intrinsics; ``live``: as
    :class:`LivePair` (aligned when loaded)."""
    from .realsense import RealSensePlayback

    playback = RealSensePlayback(p, tolerance=tolerance)
    playback.__enter__()  # opened now: a file the SDK cannot read stops the run here
    notes = playback.notes

    def lazy_pairs() -> Iterator[LivePair]:
        t0 = None
        try:
            for f in playback.lazy_frames():
                t0 = f.time if t0 is None else t0
                t = round(f.time - t0, 6)
                name = f"{p} frame {f.index} ({t:.3f} s)"
                yield LivePair(f"{name} colour", f"{name} depth", "", None, None, t, frame=f)
        finally:
            playback.close()

    def pairs() -> Iterator[RecordedPair]:
        t0 = None
        try:
            for f in playback.frames():
                t0 = f.time if t0 is None else t0
                t = round(f.time - t0, 6)
                name = f"{p} frame {f.index} ({t:.3f} s)"
                h, w = f.depth_mm.shape
                yield RecordedPair(
                    f"{name} colour", f"{name} depth", "", None, None, t,
                    ImagePayload("rgb8", w, h, 3 * w, False, f.color.tobytes()),
                    ImagePayload("16UC1", w, h, 2 * w, False, f.depth_mm.tobytes()),
                    f.intrinsics,
                )
        finally:
            playback.close()

    frames = lazy_pairs() if live else pairs()
    return Recording(frames, playback.count, False, str(p), "RealSense recording", notes)


def _bag_recording(
    p: Path,
    color_topic: str | None,
    depth_topic: str | None,
    info_topic: str | None,
    tolerance: float,
) -> Recording:
    from .ros_bags import (
        BagMessage,
        InfoMessage,
        RosBag,
        choose_topics,
        in_place_reader,
        read_bag_messages,
    )

    with RosBag(p) as bag:
        topics = choose_topics(
            bag.types, bag.counts, str(p), color=color_topic, depth=depth_topic, info=info_topic
        )
        kind = "ROS 2 bag" if bag.reader.is2 else "ROS 1 bag"
        in_place = in_place_reader(bag, topics)  # an MCAP file: no second opening
    if topics.counts[topics.color] == 0 or topics.counts[topics.depth] == 0:
        empty = topics.color if topics.counts[topics.color] == 0 else topics.depth
        raise InvalidInputError(f"recording '{p}': topic {empty} holds no message")
    notes = [
        f"colour {topics.color}, depth {topics.depth}, camera info "
        + (topics.info or "none (the nominal intrinsics are used)")
    ]
    ms = round(tolerance * 1000)

    state: dict = {"intr": None, "t0": None}  # the latest camera info; the first stamp

    def events() -> Iterator[tuple[str, float, object]]:
        with ExitStack() as opened:
            if in_place is None:
                items = read_bag_messages(opened.enter_context(RosBag(p)), topics)
            else:
                items = in_place()
            opened.callback(items.close)
            for item in items:
                if isinstance(item, InfoMessage):
                    state["intr"] = item.intrinsics
                    if item.note and item.note not in notes:
                        notes.append(item.note)
                    continue
                assert isinstance(item, BagMessage)
                if state["t0"] is None:
                    state["t0"] = item.time
                yield item.stream, item.time, (item.payload, state["intr"])

    def frames_of(stream: Iterator[tuple[str, float, object]]) -> Iterator[RecordedPair]:
        from .pairing import pair_by_time

        index = 0
        for paired in pair_by_time(stream, tolerance):
            if paired.color is None:
                notes.append(
                    f"depth frame at {paired.depth_time - state['t0']:.3f} s on "
                    f"{topics.depth}: no colour frame within {ms} ms (not used)"
                )
                continue
            t = paired.color_time - state["t0"]
            name = f"{p} frame {index} ({t:.3f} s)"
            color_payload, intr = paired.color
            depth_payload = paired.depth[0] if paired.depth else None
            problem = None
            if depth_payload is None:
                problem = f"{name}: no depth frame within {ms} ms on {topics.depth}"
            pair = RecordedPair(
                f"{name} {topics.color}", f"{name} {topics.depth}", "", None, None,
                round(t, 6), color_payload, depth_payload, intr, problem,
            )
            if index == 0 and problem is None:
                _check_first(pair)
            yield pair
            index += 1

    def pairs() -> Iterator[RecordedPair]:
        stream = events()
        try:
            yield from frames_of(stream)
        finally:  # the bag is closed even when the caller stops early
            stream.close()

    return Recording(pairs(), topics.counts[topics.color], False, str(p), kind, notes)


def _check_first(pair: RecordedPair) -> None:
    """Stop at the first frame when the whole recording cannot be used (depth not
    aligned to colour, camera info for another image size): every frame would fail
    alike. A first image that does not decode is only that frame's gap."""
    assert pair.color_payload is not None and pair.depth_payload is not None
    try:
        decode_color(_in_memory(pair.color_payload, pair.color), pair.color)
        decode_depth(_in_memory(pair.depth_payload, pair.depth), pair.depth)
    except InvalidInputError:
        return
    pair.load()


@dataclass(frozen=True)
class ReadingOptions:
    """How to read a recording (the options of :func:`open_recording`)."""

    color_topic: str | None = None
    depth_topic: str | None = None
    info_topic: str | None = None
    tolerance: float = 0.020
    live: bool = False


@dataclass(frozen=True)
class RecordingReader:
    """One recording format in :data:`RECORDING_READERS`.

    Attributes
    ----------
    name : str
        What the format is called in messages (``"folder"``, ``"ROS bag"``).
    what : str
        What a user gives, for the message naming the formats that are read.
    claims : callable
        ``claims(path) -> bool``: whether ``path`` (which exists) is of this format;
        asked in the table's order, so a more particular format comes first.
    read : callable
        ``read(path, options) -> Recording``: its frames (each a :class:`RecordedPair`
        with the frame's intrinsics and time, read as they are iterated) and notes.
    takes_labels : bool
        Whether ``--labels`` may label it (a folder has its own ``labels.csv``).
    """

    name: str
    what: str
    claims: Callable[[Path], bool]
    read: Callable[[Path, ReadingOptions], Recording]
    takes_labels: bool = True


def _is_realsense(p: Path) -> bool:
    from .realsense import is_realsense_recording

    return is_realsense_recording(p)


def _is_folder(p: Path) -> bool:
    return p.is_dir()


def _read_folder(p: Path, options: ReadingOptions) -> Recording:
    return read_recording(p)


def _read_realsense(p: Path, options: ReadingOptions) -> Recording:
    return _realsense_recording(p, options.tolerance, options.live)


def _read_bag(p: Path, options: ReadingOptions) -> Recording:
    return _bag_recording(
        p, options.color_topic, options.depth_topic, options.info_topic, options.tolerance
    )


#: The recording formats :func:`open_recording` reads, asked in this order whether a
#: path is theirs: a RealSense recording is also a ROS bag, and a ROS 2 bag can be a
#: folder. A new format is a row here (before the folder).
RECORDING_READERS: tuple[RecordingReader, ...] = (
    RecordingReader("RealSense recording", "a RealSense .db3/.bag", _is_realsense,
                    _read_realsense),
    RecordingReader("ROS bag", "a ROS 1 .bag, a ROS 2 bag (.db3, .mcap or its folder)",
                    is_recording_file, _read_bag),
    RecordingReader("folder", "a folder of PNG pairs", _is_folder, _read_folder,
                    takes_labels=False),
)
