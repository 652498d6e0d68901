"""RealSense SDK recordings (the ``.bag`` files of the RealSense Viewer), through Open3D's
``RSBagReader``: colour and depth aligned to colour, intrinsics from the file.

Frames come one at a time as :class:`~dgli_vision.sources.ros_images.ImagePayload` (``rgb8``
colour and ``16UC1`` depth in mm), like the frames of a ROS bag.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.camera import Intrinsics
from ..core.errors import UnreadableInputError
from .ros_images import ImagePayload

__all__ = ["RealSenseFrame", "is_realsense_bag", "read_realsense_bag"]

_MARKERS = (b"/device_0/", b"realsense_msgs", b"/file_version")


def is_realsense_bag(path: Path) -> bool:
    """A ``.bag`` file written by the RealSense SDK (its topics are named
    ``/device_0/...``; a ROS driver's bag has the driver's own topic names)."""
    if path.suffix != ".bag" or not path.is_file():
        return False
    with path.open("rb") as fh:
        head = fh.read(1 << 20)
    return head.startswith(b"#ROSBAG V2.0") and any(m in head for m in _MARKERS)


@dataclass(frozen=True)
class RealSenseFrame:
    """A synchronised colour + aligned depth frame of a RealSense recording."""

    time: float
    color: ImagePayload
    depth: ImagePayload
    intrinsics: Intrinsics


def read_realsense_bag(path: str | Path) -> tuple[int, Iterator[RealSenseFrame]]:
    """The expected number of frames and the frames of a RealSense recording.

    Raises
    ------
    UnreadableInputError
        The file cannot be opened as a RealSense recording (named, with the reason).
    """
    import open3d as o3d

    path = Path(path)
    reader = o3d.t.io.RSBagReader()
    try:
        with o3d.utility.VerbosityContextManager(o3d.utility.VerbosityLevel.Error):
            opened = reader.open(str(path))
    except RuntimeError as exc:
        opened, why = False, str(exc).strip().splitlines()[-1] if str(exc).strip() else ""
    else:
        why = ""
    if not opened:
        raise UnreadableInputError(
            f"RealSense recording '{path}' cannot be opened"
            + (f": {why}" if why else " (truncated, or without colour and depth streams)")
        )
    meta = reader.metadata
    k = meta.intrinsics.numpy()
    intr = Intrinsics(
        int(meta.width), int(meta.height), float(k[0, 0]), float(k[1, 1]), k[0, 2], k[1, 2]
    )
    to_mm = 1000.0 / float(meta.depth_scale or 1000.0)  # depth_scale: units per metre
    count = int(round(meta.stream_length_usec * 1e-6 * meta.fps)) if meta.fps else 0

    def frames() -> Iterator[RealSenseFrame]:
        try:
            while not reader.is_eof():
                rgbd = reader.next_frame()
                if rgbd.is_empty():
                    continue
                color = np.ascontiguousarray(rgbd.color.as_tensor().numpy()[:, :, :3])
                depth = rgbd.depth.as_tensor().numpy().reshape(color.shape[:2])
                if to_mm != 1.0:
                    depth = np.clip(np.rint(depth * to_mm), 0, 65535)
                depth = np.ascontiguousarray(depth.astype(np.uint16))
                h, w = depth.shape
                yield RealSenseFrame(
                    reader.get_timestamp() * 1e-6,
                    ImagePayload("rgb8", w, h, 3 * w, False, color.tobytes()),
                    ImagePayload("16UC1", w, h, 2 * w, False, depth.tobytes()),
                    intr,
                )
        finally:
            reader.close()

    return count, frames()
