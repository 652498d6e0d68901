"""ROS image messages as the pipeline's arrays: RGB uint8 colour and uint16 depth in mm.

A message's pixels travel as an :class:`ImagePayload` (its bytes and how to read them),
small to pickle and decoded only where the frame is classified, so that a recording is
read by one process and its frames decoded by the workers. No ROS or ``rosbags`` import
here: the payload is plain data.

Encodings (``sensor_msgs/Image``): colour ``rgb8``, ``bgr8``, ``rgba8``, ``bgra8``;
depth ``16UC1`` or ``mono16`` (millimetres, as a RealSense or Kinect driver publishes
aligned depth) and ``32FC1`` (metres; NaN and non-positive values read as no depth).
``sensor_msgs/CompressedImage``: JPEG or PNG colour, and ``compressedDepth`` PNG depth
(``compressed_depth_image_transport``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..core.errors import InvalidInputError

__all__ = [
    "COLOR_ENCODINGS",
    "DEPTH_ENCODINGS",
    "ImagePayload",
    "decode_color",
    "decode_depth",
]

COLOR_ENCODINGS = ("rgb8", "bgr8", "rgba8", "bgra8")
DEPTH_ENCODINGS = ("16UC1", "mono16", "32FC1")
_CHANNELS = {"rgb8": 3, "bgr8": 3, "rgba8": 4, "bgra8": 4, "16UC1": 1, "mono16": 1, "32FC1": 1}
_ITEM = {"16UC1": 2, "mono16": 2, "32FC1": 4}


@dataclass(frozen=True, eq=False)
class ImagePayload:
    """One image message's pixels, undecoded.

    Attributes
    ----------
    encoding : str
        ``sensor_msgs/Image`` encoding, or ``"compressed:<format>"`` for a
        ``CompressedImage`` (its ``format`` field, e.g. ``jpeg`` or
        ``16UC1; compressedDepth png``).
    width, height, step : int
        From the message (0 for a compressed image).
    big_endian : bool
    data : bytes-like
        The message's bytes (``bytes``, or an array of uint8 over the message read; a
        :class:`~dgli_vision.core.parallel.SlotRef` while in a shared slot).
    """

    encoding: str
    width: int
    height: int
    step: int
    big_endian: bool
    data: Any

    @property
    def compressed(self) -> bool:
        """A ``CompressedImage`` (sizes known only once decoded)."""
        return self.encoding.startswith("compressed:")


def _raw_array(p: ImagePayload, where: str) -> NDArray:
    channels, item = _CHANNELS[p.encoding], _ITEM.get(p.encoding, 1)
    row = p.width * channels * item
    if p.step < row or len(p.data) < p.step * p.height:
        raise InvalidInputError(
            f"{where}: image message holds {len(p.data)} bytes, too few for "
            f"{p.width}x{p.height} {p.encoding} (step {p.step})"
        )
    rows = np.frombuffer(p.data, np.uint8, p.step * p.height).reshape(p.height, p.step)
    pixels = rows[:, :row]
    if item == 1:
        return pixels.reshape(p.height, p.width, channels)
    kind = {"32FC1": "f4"}.get(p.encoding, "u2")
    dtype = np.dtype((">" if p.big_endian else "<") + kind)
    return np.ascontiguousarray(pixels).view(dtype).reshape(p.height, p.width)


def _imdecode(data: Any, flags: int, where: str) -> NDArray:
    import cv2

    image = cv2.imdecode(np.frombuffer(data, np.uint8), flags) if len(data) else None
    if image is None:
        raise InvalidInputError(f"{where}: compressed image could not be decoded")
    return image


def decode_color(p: ImagePayload, where: str) -> NDArray[np.uint8]:
    """RGB uint8 (H, W, 3) of a colour message.

    Raises
    ------
    InvalidInputError
        Unknown encoding, too few bytes, or a compressed image that does not decode;
        the message names ``where`` (recording, topic and time).
    """
    import cv2

    if p.compressed:
        bgr = _imdecode(p.data, cv2.IMREAD_COLOR, where)
        return np.ascontiguousarray(bgr[:, :, ::-1])
    if p.encoding not in COLOR_ENCODINGS:
        raise InvalidInputError(
            f"{where}: colour encoding '{p.encoding}' is not supported "
            f"(expected one of {', '.join(COLOR_ENCODINGS)} or a JPEG/PNG CompressedImage)"
        )
    pixels = _raw_array(p, where)[:, :, :3]
    if p.encoding.startswith("bgr"):
        pixels = pixels[:, :, ::-1]
    return np.ascontiguousarray(pixels)


def decode_depth(p: ImagePayload, where: str) -> NDArray[np.uint16]:
    """Depth in mm, uint16 (H, W), 0 = no reading, of a depth message.

    Raises
    ------
    InvalidInputError
        Unknown encoding, too few bytes, or a compressed image that does not decode.
    """
    import cv2

    if p.compressed:
        if "compresseddepth" not in p.encoding.lower():
            raise InvalidInputError(
                f"{where}: depth as '{p.encoding.removeprefix('compressed:')}' compressed "
                "images is not supported (expected 16UC1 or 32FC1, raw or compressedDepth)"
            )
        # compressed_depth_image_transport: a 12-byte header (format and quantisation),
        # then a 16-bit PNG of the depth in mm
        image = _imdecode(p.data[12:], cv2.IMREAD_UNCHANGED, where)
        if image.dtype != np.uint16 or image.ndim != 2:
            raise InvalidInputError(f"{where}: compressedDepth image is not 16-bit depth in mm")
        return image
    if p.encoding not in DEPTH_ENCODINGS:
        raise InvalidInputError(
            f"{where}: depth encoding '{p.encoding}' is not supported "
            f"(expected one of {', '.join(DEPTH_ENCODINGS)})"
        )
    raw = _raw_array(p, where)
    if p.encoding == "32FC1":  # metres
        mm = np.nan_to_num(raw.astype(np.float64) * 1000.0, nan=0.0, posinf=0.0, neginf=0.0)
        return np.clip(np.rint(mm), 0, 65535).astype(np.uint16)
    return raw.astype(np.uint16, copy=False)
