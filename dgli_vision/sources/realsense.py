"""RealSense recordings and cameras, through the RealSense SDK (``pyrealsense2``, the
``realsense`` extra).

A recording written by the SDK's recorder or the RealSense Viewer (ROS 2 ``.db3`` from
SDK 2.58 on, ROS 1 ``.bag`` before; topics named ``/device_0/sensor_N/...``) holds each
sensor's raw stream: colour at one resolution, depth at another, seen from another
point, in the depth sensor's units. The SDK plays it back (``set_real_time(False)``: no
frame dropped, as fast as they are taken) and aligns depth to colour (``rs.align``);
the depth scale comes from the depth sensor, the intrinsics and lens distortion from the
colour stream's profile, the times from the frames' own timestamps. A live camera gives
the same frames through the SDK's pipeline.

Frames come as :class:`RealSenseFrame`: RGB uint8 colour, uint16 depth in millimetres
aligned to colour, and the colour intrinsics. Without the SDK, every function here
raises one line saying what to install (:data:`INSTALL_HINT`).
"""

from __future__ import annotations

import queue
import sqlite3
import threading
from collections.abc import Callable, Iterator
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from ..core.camera import Intrinsics
from ..core.errors import InvalidInputError, UnreadableInputError
from ..core.frame import RGBDFrame
from ..core.parallel import SharedSlots
from .depth_align import DepthToColour, StreamCamera
from .labelled import LabelledPair

__all__ = [
    "INSTALL_HINT",
    "CameraFrame",
    "LazyRealSenseFrame",
    "LivePair",
    "RawRealSensePair",
    "RealSenseFrame",
    "RealSensePlayback",
    "camera_pairs",
    "is_realsense_recording",
    "open_camera",
    "realsense_sdk",
]

#: What to install for RealSense files and cameras (the last words of every such error).
INSTALL_HINT = "pip install 'dgli_vision[realsense]'"

#: Colour formats read from a RealSense colour stream, and the channel order of each.
_COLOUR_FORMATS = {"rgb8": (0, 1, 2), "bgr8": (2, 1, 0), "rgba8": (0, 1, 2), "bgra8": (2, 1, 0)}

#: OpenCV's conversion of each colour format to RGB (None: a copy).
_COLOUR_CODES = {
    "rgb8": None, "bgr8": "COLOR_BGR2RGB", "rgba8": "COLOR_RGBA2RGB", "bgra8": "COLOR_BGRA2RGB"
}

#: A frame's wait before the playback is asked whether it has ended, seconds.
_POLL_S = 0.05

#: Frames held between the SDK's playback thread and the reader (the playback waits
#: when they are all taken, so that a recording played with ``real_time=False`` loses
#: nothing and memory stays flat).
_QUEUE_FRAMES = 8


def realsense_sdk() -> Any:
    """The ``pyrealsense2`` module.

    Raises
    ------
    UnreadableInputError
        The ``realsense`` extra is not installed (one line saying what to install).
    """
    try:
        import pyrealsense2 as rs
    except ImportError:
        raise UnreadableInputError(
            "RealSense recordings and cameras are read through the RealSense SDK: "
            f"{INSTALL_HINT}"
        ) from None
    return rs


def is_realsense_recording(path: Path) -> bool:
    """A recording written by the RealSense SDK or Viewer: a ROS 1 ``.bag`` or a ROS 2
    ``.db3`` (or bag folder) whose topics are RealSense's own (``/device_0/...``), not a
    ROS driver's."""
    if path.is_dir():
        meta = path / "metadata.yaml"
        return meta.is_file() and "/device_0/" in meta.read_text(errors="replace")
    if not path.is_file():
        return False
    if path.suffix == ".bag":
        with path.open("rb") as fh:
            head = fh.read(1 << 20)
        return head.startswith(b"#ROSBAG V2.0") and b"/device_0/" in head
    if path.suffix == ".db3":
        return _db3_is_realsense(path)
    return False


def _db3_is_realsense(path: Path) -> bool:
    """A ROS 2 SQLite bag with RealSense's topics (False when it cannot be read: the
    ROS reader then says why)."""
    try:
        con = sqlite3.connect(f"file:{path}?mode=ro", uri=True)
        try:
            rows = con.execute("SELECT name FROM topics").fetchall()
        finally:
            con.close()
    except sqlite3.Error:
        return False
    return any(str(name).startswith("/device_0/") for (name,) in rows)


@dataclass(frozen=True)
class RealSenseFrame:
    """A colour frame and the depth aligned to it.

    Attributes
    ----------
    index : int
        Frame number in the recording or stream, from 0.
    time : float
        Seconds, from the SDK's frame timestamp (the colour frame's).
    color : ndarray of uint8, shape (H, W, 3)
        RGB.
    depth_mm : ndarray of uint16, shape (H, W)
        Depth aligned to colour by the SDK, in mm (0 = no reading).
    intrinsics : Intrinsics
        The colour stream's, with its lens distortion when OpenCV's model reads it.
    """

    index: int
    time: float
    color: NDArray[np.uint8]
    depth_mm: NDArray[np.uint16]
    intrinsics: Intrinsics


def colour_intrinsics(rs: Any, profile: Any) -> tuple[Intrinsics, str | None]:
    """The intrinsics of a colour stream profile and a note on its lens model.

    RealSense's Brown-Conrady coefficients are OpenCV's ``k1, k2, p1, p2, k3``; they are
    kept (sticker centres are then undistorted). Another model (inverse or modified
    Brown-Conrady, Kannala-Brandt) with non-zero coefficients is noted and the image is
    used as recorded.
    """
    intr = profile.as_video_stream_profile().get_intrinsics()
    coeffs = tuple(float(c) for c in intr.coeffs)
    nonzero = any(abs(c) > 1e-12 for c in coeffs)
    usable = intr.model == rs.distortion.brown_conrady
    out = Intrinsics(
        int(intr.width),
        int(intr.height),
        float(intr.fx),
        float(intr.fy),
        float(intr.ppx),
        float(intr.ppy),
        distortion=coeffs if usable and nonzero else (),
    )
    note = None
    if nonzero:
        model = str(intr.model).rsplit(".", 1)[-1]
        text = ", ".join(f"{c:.4g}" for c in coeffs)
        note = f"colour stream has {model} lens distortion [{text}]; " + (
            "sticker centres are undistorted with it"
            if usable
            else "not a model dgli reads, so images are used as recorded (not undistorted)"
        )
    return out, note


def _colour_array(rs: Any, frame: Any) -> NDArray[np.uint8]:
    """RGB uint8 (H, W, 3) of a colour frame, a copy owned by numpy (one pass: a copy
    of RGB, OpenCV's channel swap or drop for the others)."""

    fmt = str(frame.get_profile().format()).rsplit(".", 1)[-1]
    order = _COLOUR_FORMATS.get(fmt)
    if order is None:
        raise InvalidInputError(
            f"RealSense colour format {fmt} is not read (expected one of "
            f"{', '.join(_COLOUR_FORMATS)})"
        )
    return _colour_pixels(np.asanyarray(frame.get_data()), fmt)


def _colour_pixels(
    pixels: NDArray[np.uint8], fmt: str, *, copy: bool = True
) -> NDArray[np.uint8]:
    """RGB uint8 (H, W, 3) of a colour frame's pixels in format ``fmt`` (one of
    :data:`_COLOUR_FORMATS`), a copy owned by numpy (RGB itself without ``copy``: the
    pixels outlive the frame)."""
    import cv2

    code = _COLOUR_CODES[fmt]
    if code is None:
        return np.array(pixels, dtype=np.uint8, order="C", copy=copy or None)
    return cv2.cvtColor(np.ascontiguousarray(pixels), getattr(cv2, code))


#: Metres per unit -> the table from every Z16 value to mm (see :func:`_depth_mm`).
_DEPTH_TABLES: dict[float, NDArray[np.uint16]] = {}


def _depth_table(scale_m: float) -> NDArray[np.uint16]:
    """Every Z16 value's depth in mm, rounded as :func:`_depth_mm` rounds (float32
    product, to the nearest even on ties, clipped to uint16)."""
    table = _DEPTH_TABLES.get(scale_m)
    if table is None:
        raw = np.arange(65536, dtype=np.float32)
        mm = np.rint(raw * np.float32(scale_m * 1000.0))
        table = np.clip(mm, 0, 65535).astype(np.uint16)
        _DEPTH_TABLES[scale_m] = table
    return table


def _depth_mm(frame: Any, scale_m: float) -> NDArray[np.uint16]:
    """Depth in mm, uint16, of a Z16 frame whose unit is ``scale_m`` metres (each value
    ``rint(value * float32(scale_m * 1000))`` clipped to uint16, looked up in a table
    made once per unit)."""
    return _mm_of(np.asanyarray(frame.get_data()), scale_m)


def _mm_of(raw: NDArray[np.uint16], scale_m: float) -> NDArray[np.uint16]:
    """:func:`_depth_mm` of a Z16 frame's values (a new array)."""
    if abs(scale_m - 0.001) < 1e-9:
        return np.array(raw, dtype=np.uint16)
    return np.take(_depth_table(scale_m), raw)


def stream_calibration(
    c_profile: Any, d_profile: Any, scale_m: float
) -> DepthToColour | None:
    """What aligning depth to colour needs, from the two streams' profiles (None when
    the SDK has no extrinsics between them)."""

    def camera(profile: Any) -> StreamCamera:
        i = profile.as_video_stream_profile().get_intrinsics()
        return StreamCamera(
            int(i.width), int(i.height), float(i.fx), float(i.fy), float(i.ppx),
            float(i.ppy), str(i.model).rsplit(".", 1)[-1], tuple(float(c) for c in i.coeffs),
        )

    try:
        e = d_profile.get_extrinsics_to(c_profile)
    except RuntimeError:
        return None
    return DepthToColour(
        camera(d_profile),
        camera(c_profile),
        tuple(float(v) for v in e.rotation),
        tuple(float(v) for v in e.translation),  # type: ignore[arg-type]
        float(scale_m),
    )


class _Aligner:
    """Depth aligned to colour by the SDK: a colour and a depth frame made one frameset
    (a processing block), then ``rs.align`` to the colour stream."""

    def __init__(self, rs: Any) -> None:
        self.rs = rs
        self.align = rs.align(rs.stream.color)
        self.out = rs.frame_queue(2, True)
        self.pending: list[Any] = []

        def compose(_frame: Any, source: Any) -> None:
            source.frame_ready(source.allocate_composite_frame(self.pending))

        self.block = rs.processing_block(compose)
        self.block.start(self.out)

    def __call__(self, color: Any, depth: Any) -> Any:
        """The depth frame aligned to ``color``."""
        self.pending = [depth, color]
        self.block.invoke(depth)
        frameset = self.out.wait_for_frame(5000).as_frameset()
        self.pending = []
        return self.align.process(frameset).get_depth_frame()


def _stream_profiles(rs: Any, device: Any, where: str) -> tuple[Any, Any, Any, Any]:
    """The colour and depth sensors of ``device`` and the profile of each stream used:
    the first colour stream in a format read, the first Z16 depth stream."""
    color = depth = None
    for sensor in device.query_sensors():
        for profile in sensor.get_stream_profiles():
            kind, fmt = profile.stream_type(), profile.format()
            if color is None and kind == rs.stream.color:
                if str(fmt).rsplit(".", 1)[-1] in _COLOUR_FORMATS:
                    color = (sensor, profile)
            elif depth is None and kind == rs.stream.depth and fmt == rs.format.z16:
                depth = (sensor, profile)
    if color is None or depth is None:
        missing = " and no ".join(
            w
            for w, found in (
                (f"colour stream in {', '.join(f.upper() for f in _COLOUR_FORMATS)}", color),
                ("Z16 depth stream", depth),
            )
            if found is None
        )
        raise InvalidInputError(f"{where} has no {missing} (dgli needs colour and depth)")
    return color[0], color[1], depth[0], depth[1]


def _depth_scale(rs: Any, sensor: Any) -> float:
    """Metres per depth unit of the depth sensor (its ``depth_units`` option)."""
    try:
        return float(sensor.as_depth_sensor().get_depth_scale())
    except RuntimeError:
        if sensor.supports(rs.option.depth_units):
            return float(sensor.get_option(rs.option.depth_units))
        return 0.001


@dataclass(frozen=True)
class LazyRealSenseFrame:
    """A frame of a playback before its depth is aligned (:meth:`decode` does it).

    Attributes
    ----------
    index : int
    time : float
        Seconds, the colour frame's timestamp.
    color, depth : SDK frames
    playback : RealSensePlayback
    align : the playback's aligner
    """

    index: int
    time: float
    color: Any
    depth: Any
    playback: Any
    align: Any

    def decode(self) -> RealSenseFrame:
        """The frame with depth aligned to colour, in mm, and the colour as RGB (aligned
        here as the SDK aligns, :mod:`.depth_align`, or by the SDK where the lens
        models are not read there)."""
        rs, pb = self.playback.rs, self.playback
        if pb.calibration is not None:
            return RealSenseFrame(
                self.index, self.time, _colour_array(rs, self.color),
                _aligned_mm(np.asanyarray(self.depth.get_data()), pb.calibration),
                pb.intrinsics,
            )
        depth = self.align(self.color, self.depth)
        return RealSenseFrame(
            self.index,
            self.time,
            _colour_array(rs, self.color),
            _depth_mm(depth, pb.depth_scale_m),
            pb.intrinsics,
        )

    def raw(self) -> RawRealSensePair | None:
        """The frame's pixels as recorded, for another process to align and classify
        (None when this process's SDK must align it)."""
        pb = self.playback
        if pb.calibration is None:
            return None
        fmt = str(self.color.get_profile().format()).rsplit(".", 1)[-1]
        return RawRealSensePair(
            "", "", "", None, None, self.time,
            color_data=np.asanyarray(self.color.get_data()),
            depth_data=np.asanyarray(self.depth.get_data()),
            color_format=fmt,
            calibration=pb.calibration,
            intrinsics=pb.intrinsics,
        )


def _aligned_mm(raw: NDArray[np.uint16], calibration: DepthToColour) -> NDArray[np.uint16]:
    """A Z16 frame's values aligned to colour (:mod:`.depth_align`), in mm."""
    aligned = calibration.align(raw)
    if abs(calibration.scale_m - 0.001) < 1e-9:
        return aligned
    return np.take(_depth_table(calibration.scale_m), aligned)


class RealSensePlayback:
    """A RealSense recording played back through the SDK, frame by frame.

    ``with RealSensePlayback(path) as rec: for frame in rec.frames(): ...``. The
    attributes are known once it is open: ``intrinsics`` (the colour stream's),
    ``depth_scale_m``, ``count`` (colour frames expected) and ``notes``.

    Parameters
    ----------
    path : str or Path
    real_time : bool, keyword-only
        Play at the recorded pace (frames the reader is too slow for are dropped by the
        SDK) instead of as fast as they are read (none dropped).
    tolerance : float, keyword-only
        Largest difference between a colour frame's and its depth frame's timestamps,
        seconds.
    align : {"auto", "sdk", "numpy"}, keyword-only
        Who aligns depth to colour: :mod:`.depth_align` where it is exact and fast (the
        streams share their centre of projection and no corner lands at a rounding tie;
        ``"auto"``), the SDK's ``rs.align`` (``"sdk"``, and ``"auto"`` otherwise), or
        :mod:`.depth_align` wherever it reads the lens models (``"numpy"``: also a
        depth camera to the side, 30 ms a 1280 x 720 frame against the SDK's 4-7).

    Raises
    ------
    UnreadableInputError
        The SDK is not installed, or the file cannot be opened (truncated, corrupt, not a
        RealSense recording): one line naming it.
    InvalidInputError
        The recording has no colour or no depth stream.
    """

    def __init__(
        self,
        path: str | Path,
        *,
        real_time: bool = False,
        tolerance: float = 0.020,
        align: str = "auto",
    ) -> None:
        self.path = Path(path)
        self.real_time = real_time
        self.tolerance = tolerance
        self.align_by = align
        self.calibration: DepthToColour | None = None
        self.notes: list[str] = []
        self._device: Any = None
        self._started: list[Any] = []

    def __enter__(self) -> RealSensePlayback:
        rs = realsense_sdk()
        self.rs = rs
        try:
            device = rs.context().load_device(str(self.path))
        except RuntimeError as exc:
            why = str(exc).strip().splitlines()[-1] if str(exc).strip() else type(exc).__name__
            raise UnreadableInputError(
                f"RealSense recording '{self.path}' cannot be read (truncated, corrupt or "
                f"not a RealSense recording): {why}"
            ) from None
        self._device = device
        self.playback = device.as_playback()
        self.playback.set_real_time(self.real_time)
        where = f"RealSense recording '{self.path}'"
        self._sensors = _stream_profiles(rs, device, where)
        _, c_profile, d_sensor, d_profile = self._sensors
        self.intrinsics, note = colour_intrinsics(rs, c_profile)
        self.depth_scale_m = _depth_scale(rs, d_sensor)
        cal = stream_calibration(c_profile, d_profile, self.depth_scale_m)
        if cal is not None and cal.supported and self.align_by != "sdk":
            if self.align_by == "numpy" or cal.fast:
                self.calibration = cal
        fps = c_profile.fps() or 30
        seconds = self.playback.get_duration().total_seconds()
        self.count = _colour_count(self.path) or max(1, round(seconds * fps))
        d_intr = d_profile.as_video_stream_profile().get_intrinsics()
        self.notes.append(
            f"RealSense colour {self.intrinsics.width}x{self.intrinsics.height} "
            f"{str(c_profile.format()).rsplit('.', 1)[-1]}, depth {d_intr.width}x"
            f"{d_intr.height} aligned to colour "
            + ("as the SDK aligns" if self.calibration is not None else "by the SDK")
            + ", depth unit "
            f"{self.depth_scale_m * 1000:.4g} mm"
        )
        if note:
            self.notes.append(note)
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Stop the playback (safe to call twice)."""
        for sensor in self._started:
            try:
                sensor.stop()
                sensor.close()
            except RuntimeError:
                pass
        self._started = []

    def frames(self) -> Iterator[RealSenseFrame]:
        """The colour frames in order, each with its aligned depth; a colour frame with
        no depth frame within the tolerance is skipped and noted.

        Raises
        ------
        UnreadableInputError
            The playback stops with an error part-way.
        """
        lazy = self.lazy_frames()
        try:
            for frame in lazy:
                yield frame.decode()
        finally:
            lazy.close()

    def lazy_frames(self) -> Iterator[LazyRealSenseFrame]:
        """The frames of :meth:`frames`, each still the SDK's colour and depth frames:
        aligned and converted only when :meth:`LazyRealSenseFrame.decode` is called, so
        that a live reader pays for the frames it classifies, not those it drops. The
        frames must be decoded one at a time (one aligner serves them all).

        Raises
        ------
        UnreadableInputError
            The playback stops with an error part-way.
        """
        from .pairing import pair_by_time

        rs = self.rs
        events: queue.Queue = queue.Queue(maxsize=_QUEUE_FRAMES)
        halt = threading.Event()

        def on_frame(frame: Any) -> None:
            stream = "color" if frame.get_profile().stream_type() == rs.stream.color else "depth"
            item = (stream, frame.get_timestamp() * 1e-3, frame)
            while not halt.is_set():  # the playback waits (real_time=False): none lost
                try:
                    events.put(item, timeout=_POLL_S)
                    return
                except queue.Full:
                    if self.real_time:
                        return  # at the recorded pace a slow reader loses the frame
        self._start(on_frame)
        align = _Aligner(rs)
        t0 = None
        index = 0
        try:
            for paired in pair_by_time(self._events(events), self.tolerance):
                if paired.color is None:
                    continue  # a depth frame no colour frame took
                t0 = paired.color_time if t0 is None else t0
                if paired.depth is None:
                    self.notes.append(
                        f"colour frame at {paired.color_time - t0:.3f} s: no depth frame "
                        f"within {round(self.tolerance * 1000)} ms (not used)"
                    )
                    continue
                yield LazyRealSenseFrame(
                    index, float(paired.color_time), paired.color, paired.depth, self, align
                )
                index += 1
        finally:
            halt.set()
            self.close()

    def _start(self, on_frame: Callable[[Any], None]) -> None:
        """Open the colour and depth streams and start them into ``on_frame``. The
        playback is paused meanwhile: the first sensor started would otherwise set it
        going, and the other would miss its first frames."""
        c_sensor, c_profile, d_sensor, d_profile = self._sensors
        self.playback.pause()
        if c_sensor == d_sensor:
            c_sensor.open([c_profile, d_profile])
            c_sensor.start(on_frame)
            self._started = [c_sensor]
        else:
            d_sensor.open(d_profile)
            c_sensor.open(c_profile)
            d_sensor.start(on_frame)
            c_sensor.start(on_frame)
            self._started = [d_sensor, c_sensor]
        self.playback.resume()

    def _events(self, events: queue.Queue) -> Iterator[tuple[str, float, Any]]:
        """The frames the playback delivers, until it has stopped and none is left."""
        rs = self.rs
        while True:
            try:
                yield events.get(timeout=_POLL_S)
            except queue.Empty:
                if self.playback.current_status() == rs.playback_status.stopped:
                    while not events.empty():
                        yield events.get_nowait()
                    return


def _colour_count(path: Path) -> int | None:
    """Colour frames in a recording, from its index (None when not known: a ROS 1
    ``.bag`` without ``rosbags``)."""
    if path.suffix == ".bag":
        return _bag_colour_count(path)
    if path.suffix != ".db3":
        return None
    try:
        con = sqlite3.connect(f"file:{path}?mode=ro", uri=True)
        try:
            (n,) = con.execute(
                "SELECT COUNT(*) FROM messages JOIN topics ON messages.topic_id = topics.id "
                "WHERE topics.name LIKE '%/Color\\_%/image/data%' ESCAPE '\\'"
            ).fetchone()
        finally:
            con.close()
    except sqlite3.Error:
        return None
    return int(n) or None


def _bag_colour_count(path: Path) -> int | None:
    """Colour frames in a ROS 1 ``.bag`` recording, from its index through ``rosbags``."""
    try:
        from rosbags.rosbag1 import Reader
    except ImportError:
        return None
    try:
        with Reader(path) as reader:
            n = sum(
                c.msgcount
                for c in reader.connections
                if "/Color_" in c.topic and c.topic.endswith("/image/data")
            )
    except Exception:  # the SDK says what is wrong with the file
        return None
    return n or None


def open_camera(
    serial: str | None = None,
    *,
    width: int = 1280,
    height: int = 720,
    fps: int = 30,
) -> Iterator[CameraFrame]:
    """The frames of a connected RealSense camera, as they come: colour (RGB8) and Z16
    depth, aligned to colour by the SDK when decoded (:meth:`CameraFrame.decode`), for as
    long as the caller takes them.

    Parameters
    ----------
    serial : str, optional
        The camera's serial number (default: the first camera found).
    width, height, fps : int, keyword-only
        The colour stream asked for; depth is the camera's default for that rate.

    Raises
    ------
    UnreadableInputError
        The SDK is not installed, no camera (or not that one) is connected, or it cannot
        stream colour and depth at that size and rate.
    """
    rs = realsense_sdk()
    pipeline = rs.pipeline()
    config = rs.config()
    if serial:
        config.enable_device(serial)
    config.enable_stream(rs.stream.color, width, height, rs.format.rgb8, fps)
    config.enable_stream(rs.stream.depth, rs.format.z16, fps)
    which = f"RealSense camera {serial}" if serial else "a RealSense camera"
    try:
        profile = pipeline.start(config)
    except RuntimeError as exc:
        raise UnreadableInputError(
            f"cannot stream from {which} (colour {width}x{height} at {fps} fps and "
            f"depth): {str(exc).strip() or 'no device connected'}"
        ) from None
    return _camera_frames(rs, pipeline, profile)


@dataclass(frozen=True)
class CameraFrame:
    """A camera's frameset before its depth is aligned (:meth:`decode` does it, in the
    thread that classifies it, so that a frame dropped costs no alignment).

    Attributes
    ----------
    index : int
    time : float
        Seconds, the colour frame's timestamp.
    frameset : the SDK's frameset (kept)
    align : the aligner to colour (one per camera, used by one thread)
    scale_m : float
        Metres per depth unit.
    intrinsics : Intrinsics
    """

    index: int
    time: float
    frameset: Any
    align: Any
    scale_m: float
    intrinsics: Intrinsics

    def decode(self) -> RealSenseFrame:
        """The frame with depth aligned to colour, in mm, and the colour as RGB."""
        rs = realsense_sdk()
        aligned = self.align.process(self.frameset)
        color, depth = aligned.get_color_frame(), aligned.get_depth_frame()
        return RealSenseFrame(
            self.index,
            self.time,
            _colour_array(rs, color),
            _depth_mm(depth, self.scale_m),
            self.intrinsics,
        )


def _camera_frames(rs: Any, pipeline: Any, profile: Any) -> Iterator[CameraFrame]:
    """Framesets of a started pipeline until the caller stops taking them."""
    depth_sensor = profile.get_device().first_depth_sensor()
    scale = float(depth_sensor.get_depth_scale())
    intr, _ = colour_intrinsics(rs, profile.get_stream(rs.stream.color))
    align = rs.align(rs.stream.color)
    index = 0
    try:
        while True:
            try:
                frameset = pipeline.wait_for_frames(5000)
            except RuntimeError as exc:
                raise UnreadableInputError(f"RealSense camera stopped: {exc}") from None
            color = frameset.get_color_frame()
            if not color or not frameset.get_depth_frame():
                continue
            frameset.keep()  # held past the next frameset, until it is classified or dropped
            yield CameraFrame(index, color.get_timestamp() * 1e-3, frameset, align, scale, intr)
            index += 1
    finally:
        pipeline.stop()


@dataclass(frozen=True)
class LivePair(LabelledPair):
    """A frame of a RealSense recording or camera for the live loop: the SDK's frames,
    whose depth is aligned only when the frame is loaded (a frame dropped costs nothing).
    Not for other processes: it holds the SDK's frames."""

    frame: Any = None

    #: Holds the SDK's frames: read in this process (the live loop decodes it before a
    #: worker process classifies it) unless :meth:`shared` sends its pixels as recorded.
    local: ClassVar[bool] = True

    def load(self) -> RGBDFrame:
        """The decoded frame, depth aligned to colour."""
        f = self.frame.decode()
        return RGBDFrame(f.color, f.depth_mm, f.intrinsics, self.color, self.depth, "stream")

    @property
    def portable(self) -> bool:
        """Another process can align and classify it from its pixels (:meth:`shared`)."""
        playback = getattr(self.frame, "playback", None)
        return getattr(playback, "calibration", None) is not None

    def shared(self, slots: SharedSlots) -> tuple[Any, int | None]:
        """The frame's pixels as recorded, for a worker process (a
        :class:`RawRealSensePair`), copied into a slot of ``slots`` (the slot to free
        once the worker is done; None when none was free: the pixels are then copied into
        the pair); the frame itself when only this process can decode it."""
        raw = self.frame.raw() if getattr(self.frame, "raw", None) is not None else None
        if raw is None:
            return self, None
        raw = replace(raw, color=self.color, depth=self.depth, time=self.time)
        put = slots.put([raw.color_data, raw.depth_data])
        if put is None:
            data = (np.array(raw.color_data), np.array(raw.depth_data))
            return replace(raw, color_data=data[0], depth_data=data[1]), None
        slot, (c, d) = put
        return replace(raw, color_data=c, depth_data=d), slot


@dataclass(frozen=True)
class RawRealSensePair(LabelledPair):
    """A RealSense frame's pixels as recorded (colour in its format, depth in its stream's
    size and units) with what aligning them needs: read in any process, without the SDK.

    ``color_data`` and ``depth_data`` are arrays, or references to bytes in shared
    memory (:class:`~dgli_vision.core.parallel.SlotRef`).
    """

    color_data: Any = None
    depth_data: Any = None
    color_format: str = "rgb8"
    calibration: DepthToColour | None = None
    intrinsics: Intrinsics | None = None

    def load(self) -> RGBDFrame:
        """The decoded frame, depth aligned to colour (:mod:`.depth_align`), in mm."""
        cal = self.calibration
        assert cal is not None and self.intrinsics is not None
        c, d = cal.colour, cal.depth
        channels = 4 if self.color_format.endswith("a8") else 3
        color = _pixels(self.color_data, np.uint8).reshape(c.height, c.width, channels)
        raw = _pixels(self.depth_data, np.uint16).reshape(d.height, d.width)
        return RGBDFrame(
            _colour_pixels(color, self.color_format, copy=False), _aligned_mm(raw, cal),
            self.intrinsics,
            self.color, self.depth, "stream",
        )


def _pixels(data: Any, dtype: Any) -> NDArray:
    """The values of an array, or of bytes in shared memory, as a flat array."""
    view = getattr(data, "view", None)
    if isinstance(data, np.ndarray) or view is None:
        return np.asarray(data).reshape(-1).view(dtype)
    return np.frombuffer(view(), dtype)

    def light(self) -> LabelledPair:
        """This frame as names only."""
        return LabelledPair(self.color, self.depth, self.label, self.variant, self.line, self.time)


def camera_pairs(
    serial: str | None = None, *, width: int = 1280, height: int = 720, fps: int = 30
) -> Iterator[Any]:
    """A connected camera's frames as a recording's frames
    (:class:`~dgli_vision.sources.recording.RecordedPair`, times from the first frame),
    for the live loop.

    Raises
    ------
    UnreadableInputError
        As :func:`open_camera`.
    """
    frames = open_camera(serial, width=width, height=height, fps=fps)
    name = f"RealSense camera {serial}" if serial else "RealSense camera"

    def pairs() -> Iterator[Any]:
        t0 = None
        try:
            for f in frames:
                t0 = f.time if t0 is None else t0
                where = f"{name} frame {f.index}"
                yield LivePair(
                    f"{where} colour", f"{where} depth", "", None, None, round(f.time - t0, 6),
                    frame=f,
                )
        finally:
            frames.close()

    return pairs()
