"""Write RGB-D frames as a ROS bag, the way a camera driver records an episode: a colour
topic, a depth topic aligned to colour and the colour camera's ``CameraInfo``.

Used to make test episodes and benchmark recordings with real bag formats (needs the
``recordings`` extra). Topic names follow the RealSense ROS driver.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from ..core.camera import Intrinsics
from ..core.errors import OverwriteError

__all__ = ["COLOR_TOPIC", "DEPTH_TOPIC", "INFO_TOPIC", "write_bag"]

COLOR_TOPIC = "/camera/color/image_raw"
DEPTH_TOPIC = "/camera/aligned_depth_to_color/image_raw"
INFO_TOPIC = "/camera/color/camera_info"

BagFormat = Literal["ros1", "ros2-sqlite3", "ros2-mcap"]

_IMAGE = "sensor_msgs/msg/Image"
_COMPRESSED = "sensor_msgs/msg/CompressedImage"
_INFO = "sensor_msgs/msg/CameraInfo"


@dataclass(frozen=True)
class _Messages:
    """Builds and serialises the messages of one bag (ROS 1 or ROS 2 types).

    Attributes
    ----------
    store : Any
        The ``rosbags`` type store of the bag's ROS version.
    ros1 : bool
        ROS 1 messages (headers with ``seq``, upper-case ``CameraInfo`` matrices).
    """

    store: Any
    ros1: bool

    def serialize(self, msg: object, type_name: str) -> bytes:
        """The message's bytes as the bag stores them."""
        if self.ros1:
            return self.store.serialize_ros1(msg, type_name)
        return self.store.serialize_cdr(msg, type_name)

    def header(self, t: float) -> object:
        """A ``Header`` stamped ``t`` seconds in the colour camera's optical frame."""
        types = self.store.types
        sec = int(t)
        stamp = types["builtin_interfaces/msg/Time"](sec=sec, nanosec=round((t - sec) * 1e9))
        return types["std_msgs/msg/Header"](
            **({"seq": 0} if self.ros1 else {}),
            stamp=stamp,
            frame_id="camera_color_optical_frame",
        )

    def image(self, t: float, pixels: NDArray, encoding: str) -> object:
        """A raw ``Image`` of ``pixels`` (H, W[, C]) in ``encoding``."""
        h, w = pixels.shape[:2]
        data = np.ascontiguousarray(pixels).view(np.uint8).reshape(-1)
        return self.store.types[_IMAGE](
            header=self.header(t),
            height=h,
            width=w,
            encoding=encoding,
            is_bigendian=0,
            step=data.size // h,
            data=data,
        )

    def camera_info(
        self, t: float, intrinsics: Intrinsics, distortion: tuple[float, ...]
    ) -> object:
        """The colour camera's ``CameraInfo`` (``plumb_bob`` distortion, no rectification)."""
        types = self.store.types
        k = intrinsics.matrix().reshape(-1)
        p_matrix = np.array([k[0], 0, k[2], 0, 0, k[4], k[5], 0, 0, 0, 1, 0], float)
        fields = {"D": "d", "K": "k", "R": "r", "P": "p"}
        if self.ros1:
            fields = {key: key for key in fields}
        roi = types["sensor_msgs/msg/RegionOfInterest"](
            x_offset=0, y_offset=0, height=0, width=0, do_rectify=False
        )
        return types[_INFO](
            header=self.header(t),
            height=intrinsics.height,
            width=intrinsics.width,
            distortion_model="plumb_bob",
            **{
                fields["D"]: np.array(distortion, float),
                fields["K"]: k.astype(float),
                fields["R"]: np.eye(3).reshape(-1),
                fields["P"]: p_matrix,
            },
            binning_x=0,
            binning_y=0,
            roi=roi,
        )

    def colour(self, t: float, rgb: NDArray[np.uint8], encoding: str) -> tuple[object, str]:
        """The colour message and its type: a JPEG ``CompressedImage`` or a raw image."""
        if encoding == "jpeg":
            import cv2

            ok, buf = cv2.imencode(".jpg", rgb[:, :, ::-1], [cv2.IMWRITE_JPEG_QUALITY, 95])
            assert ok
            msg = self.store.types[_COMPRESSED](
                header=self.header(t), format="jpeg", data=buf.reshape(-1).astype(np.uint8)
            )
            return msg, _COMPRESSED
        pixels = rgb[:, :, ::-1] if encoding == "bgr8" else rgb
        return self.image(t, pixels, encoding), _IMAGE

    def depth(self, t: float, depth_mm: NDArray[np.uint16], encoding: str) -> object:
        """The depth image: millimetres (``16UC1``) or metres with NaN for none (``32FC1``)."""
        if encoding == "32FC1":
            metres = depth_mm.astype(np.float32) / 1000.0
            metres[depth_mm == 0] = np.nan
            return self.image(t, metres, "32FC1")
        return self.image(t, depth_mm.astype(np.uint16), "16UC1")


def _open_writer(path: Path, fmt: BagFormat, compress: bool = False) -> tuple[Any, _Messages]:
    """A ``rosbags`` writer of a new bag in ``fmt`` and its message builder (``compress``:
    an MCAP bag's chunks compressed with zstd)."""
    from rosbags.typesys import Stores, get_typestore

    ros1 = fmt == "ros1"
    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    if ros1:
        from rosbags.rosbag1 import Writer

        return Writer(path), _Messages(store, ros1)
    from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin, Writer

    plugin = StoragePlugin.MCAP if fmt == "ros2-mcap" else StoragePlugin.SQLITE3
    writer = Writer(path, version=9, storage_plugin=plugin)
    if compress and fmt == "ros2-mcap":  # each chunk zstd-compressed (the MCAP's own)
        writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
    return writer, _Messages(store, ros1)


def write_bag(
    path: str | Path,
    frames: Iterable[tuple[float, NDArray[np.uint8], NDArray[np.uint16]]],
    intrinsics: Intrinsics,
    *,
    fmt: BagFormat = "ros2-mcap",
    color_encoding: Literal["rgb8", "bgr8", "jpeg"] = "rgb8",
    depth_encoding: Literal["16UC1", "32FC1"] = "16UC1",
    distortion: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0, 0.0),
    depth_offset_s: float = 0.0,
    compress: bool = False,
) -> Path:
    """Write ``frames`` (time in seconds, RGB uint8, depth uint16 mm) to a new bag.

    Parameters
    ----------
    path : str or Path
        A ``.bag`` file (ROS 1) or a bag folder (ROS 2); must not exist.
    frames : iterable of (float, ndarray, ndarray)
        Written one at a time (an episode need not fit in memory).
    intrinsics : Intrinsics
        Written as the colour ``CameraInfo`` (one per frame, as drivers do).
    fmt : {"ros1", "ros2-sqlite3", "ros2-mcap"}, keyword-only
    color_encoding : {"rgb8", "bgr8", "jpeg"}, keyword-only
        ``jpeg``: a ``CompressedImage`` on ``<colour topic>/compressed``.
    depth_encoding : {"16UC1", "32FC1"}, keyword-only
        Millimetres, or metres as float.
    distortion : tuple of float, keyword-only
        ``plumb_bob`` coefficients of the ``CameraInfo``.
    depth_offset_s : float, keyword-only
        Depth stamped this much later than colour (a driver's jitter).
    compress : bool, keyword-only
        ``ros2-mcap``: compress each chunk with zstd (as ``ros2 bag record
        --compression-mode storage`` does; the bag is read through ``rosbags`` then).

    Returns
    -------
    Path
        The bag.

    Raises
    ------
    OverwriteError
        ``path`` exists.
    """
    path = Path(path)
    if path.exists():
        raise OverwriteError(f"'{path}' exists; a bag is written only to a new path")
    writer, messages = _open_writer(path, fmt, compress)
    jpeg = color_encoding == "jpeg"
    color_topic = COLOR_TOPIC + ("/compressed" if jpeg else "")

    def write(connection: Any, t: float, msg: object, type_name: str) -> None:
        writer.write(connection, round(t * 1e9), messages.serialize(msg, type_name))

    with writer:
        kw = {"typestore": messages.store}
        c_color = writer.add_connection(color_topic, _COMPRESSED if jpeg else _IMAGE, **kw)
        c_depth = writer.add_connection(DEPTH_TOPIC, _IMAGE, **kw)
        c_info = writer.add_connection(INFO_TOPIC, _INFO, **kw)
        for t, rgb, depth_mm in frames:
            write(c_info, t, messages.camera_info(t, intrinsics, distortion), _INFO)
            write(c_color, t, *messages.colour(t, rgb, color_encoding))
            td = t + depth_offset_s
            write(c_depth, td, messages.depth(td, depth_mm, depth_encoding), _IMAGE)
    return path
