"""Write RGB-D frames as a ROS bag, the way a camera driver records an episode: a colour
topic, a depth topic aligned to colour and the colour camera's ``CameraInfo``.

Used to make test episodes and benchmark recordings with real bag formats (needs the
``recordings`` extra). Topic names follow the RealSense ROS driver.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from .camera import Intrinsics
from .errors import OverwriteError

__all__ = ["COLOR_TOPIC", "DEPTH_TOPIC", "INFO_TOPIC", "write_bag"]

COLOR_TOPIC = "/camera/color/image_raw"
DEPTH_TOPIC = "/camera/aligned_depth_to_color/image_raw"
INFO_TOPIC = "/camera/color/camera_info"

BagFormat = Literal["ros1", "ros2-sqlite3", "ros2-mcap"]


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

    Returns
    -------
    Path
        The bag.

    Raises
    ------
    OverwriteError
        ``path`` exists.
    """
    import cv2
    from rosbags.typesys import Stores, get_typestore

    path = Path(path)
    if path.exists():
        raise OverwriteError(f"'{path}' exists; a bag is written only to a new path")
    ros1 = fmt == "ros1"
    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    T = store.types
    image_t, compressed_t = "sensor_msgs/msg/Image", "sensor_msgs/msg/CompressedImage"
    info_t = "sensor_msgs/msg/CameraInfo"
    if ros1:
        from rosbags.rosbag1 import Writer

        writer = Writer(path)
        serialize = store.serialize_ros1
    else:
        from rosbags.rosbag2 import StoragePlugin, Writer

        plugin = StoragePlugin.MCAP if fmt == "ros2-mcap" else StoragePlugin.SQLITE3
        writer = Writer(path, version=9, storage_plugin=plugin)
        serialize = store.serialize_cdr
    jpeg = color_encoding == "jpeg"
    color_topic = COLOR_TOPIC + ("/compressed" if jpeg else "")

    def header(t: float) -> object:
        sec = int(t)
        stamp = T["builtin_interfaces/msg/Time"](sec=sec, nanosec=round((t - sec) * 1e9))
        return T["std_msgs/msg/Header"](**({"seq": 0} if ros1 else {}), stamp=stamp,
                                        frame_id="camera_color_optical_frame")

    def image(t: float, pixels: NDArray, encoding: str) -> object:
        h, w = pixels.shape[:2]
        data = np.ascontiguousarray(pixels).view(np.uint8).reshape(-1)
        return T[image_t](header=header(t), height=h, width=w, encoding=encoding,
                          is_bigendian=0, step=data.size // h, data=data)

    k = intrinsics.matrix().reshape(-1)
    p_matrix = np.array([k[0], 0, k[2], 0, 0, k[4], k[5], 0, 0, 0, 1, 0], float)
    info_fields = {"D": "d", "K": "k", "R": "r", "P": "p"}
    if ros1:
        info_fields = {key: key for key in info_fields}
    roi = T["sensor_msgs/msg/RegionOfInterest"](x_offset=0, y_offset=0, height=0, width=0,
                                                 do_rectify=False)
    with writer:
        kw = {"typestore": store}
        c_color = writer.add_connection(color_topic, compressed_t if jpeg else image_t, **kw)
        c_depth = writer.add_connection(DEPTH_TOPIC, image_t, **kw)
        c_info = writer.add_connection(INFO_TOPIC, info_t, **kw)
        for t, rgb, depth_mm in frames:
            ns = round(t * 1e9)
            info = T[info_t](
                header=header(t), height=intrinsics.height, width=intrinsics.width,
                distortion_model="plumb_bob",
                **{info_fields["D"]: np.array(distortion, float),
                   info_fields["K"]: k.astype(float),
                   info_fields["R"]: np.eye(3).reshape(-1),
                   info_fields["P"]: p_matrix},
                binning_x=0, binning_y=0, roi=roi,
            )
            writer.write(c_info, ns, serialize(info, info_t))
            if jpeg:
                ok, buf = cv2.imencode(".jpg", rgb[:, :, ::-1], [cv2.IMWRITE_JPEG_QUALITY, 95])
                assert ok
                msg = T[compressed_t](header=header(t), format="jpeg",
                                      data=buf.reshape(-1).astype(np.uint8))
                writer.write(c_color, ns, serialize(msg, compressed_t))
            else:
                pixels = rgb[:, :, ::-1] if color_encoding == "bgr8" else rgb
                msg = image(t, pixels, color_encoding)
                writer.write(c_color, ns, serialize(msg, image_t))
            td = t + depth_offset_s
            if depth_encoding == "32FC1":
                metres = depth_mm.astype(np.float32) / 1000.0
                metres[depth_mm == 0] = np.nan
                msg = image(td, metres, "32FC1")
            else:
                msg = image(td, depth_mm.astype(np.uint16), "16UC1")
            writer.write(c_depth, round(td * 1e9), serialize(msg, image_t))
    return path
