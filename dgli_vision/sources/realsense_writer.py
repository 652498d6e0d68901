"""Write RGB-D frames as a RealSense recording with the SDK itself: a software device
with a colour sensor and a depth sensor, recorded by the SDK's recorder (``.db3`` with
SDK 2.58 and later, ``.bag`` before).

The depth stream is written as a RealSense camera gives it, not as dgli reads it: at a
lower resolution than colour (``depth_step`` times fewer pixels each way), in the depth
sensor's own unit (``depth_scale_m`` metres, a ``depth_units`` option of the sensor),
with the extrinsics from depth to colour, so that reading it back needs the SDK's
alignment and depth scale. Used by the tests and the benchmark (``realsense`` extra).
"""

from __future__ import annotations

import time
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..core.camera import Intrinsics
from ..core.errors import InvalidInputError, OverwriteError
from .realsense import realsense_sdk

__all__ = ["write_realsense_recording"]


def _rs_intrinsics(rs: Any, intr: Intrinsics) -> Any:
    out = rs.intrinsics()
    out.width, out.height = intr.width, intr.height
    out.fx, out.fy, out.ppx, out.ppy = intr.fx, intr.fy, intr.cx, intr.cy
    out.model = rs.distortion.brown_conrady
    coeffs = [float(c) for c in intr.distortion[:5]]
    out.coeffs = coeffs + [0.0] * (5 - len(coeffs))
    return out


def _stream(rs: Any, kind: Any, uid: int, intr: Intrinsics, fmt: Any, bpp: int, fps: int) -> Any:
    vs = rs.video_stream()
    vs.type, vs.index, vs.uid = kind, 0, uid
    vs.width, vs.height, vs.fps, vs.bpp, vs.fmt = intr.width, intr.height, fps, bpp, fmt
    vs.intrinsics = _rs_intrinsics(rs, intr)
    return vs


def _push(
    rs: Any, sensor: Any, profile: Any, pixels: NDArray, bpp: int, t: float, n: int, units: float
) -> None:
    frame = rs.software_video_frame()
    frame.pixels = np.ascontiguousarray(pixels)
    frame.bpp = bpp
    frame.stride = pixels.shape[1] * bpp
    frame.timestamp = t * 1000.0
    frame.domain = rs.timestamp_domain.hardware_clock
    frame.frame_number = n
    frame.profile = profile
    if units:
        frame.depth_units = units
    sensor.on_video_frame(frame)


def depth_intrinsics(color: Intrinsics, step: int) -> Intrinsics:
    """The depth stream's intrinsics when its pixel ``(u, v)`` sees what colour pixel
    ``(step * u, step * v)`` sees (same centre of projection)."""
    return Intrinsics(
        -(-color.width // step),
        -(-color.height // step),
        color.fx / step,
        color.fy / step,
        color.cx / step,
        color.cy / step,
    )


def write_realsense_recording(
    path: str | Path,
    frames: Iterable[tuple[float, NDArray[np.uint8], NDArray[np.uint16]]],
    intrinsics: Intrinsics,
    *,
    depth_scale_m: float = 0.0001,
    depth_step: int = 2,
    fps: int = 30,
    compress: bool = True,
    serial: str = "000000000000",
    paced: bool = False,
    extrinsics: tuple[tuple[float, ...], tuple[float, ...]] | None = None,
) -> Path:
    """Record ``frames`` (time in seconds, RGB uint8, depth uint16 in mm registered to
    colour) with the RealSense SDK's recorder.

    Parameters
    ----------
    path : str or Path
        ``.db3`` (SDK 2.58 and later) or ``.bag`` (earlier SDKs); must not exist.
    frames : iterable of (float, ndarray, ndarray)
    intrinsics : Intrinsics
        The colour camera's (its stream profile's intrinsics).
    depth_scale_m : float, keyword-only
        Metres per depth unit (a D400's default is 0.001; 0.0001 is its high-accuracy
        setting).
    depth_step : int, keyword-only
        The depth stream has ``depth_step`` times fewer pixels each way than colour.
    fps : int, keyword-only
    compress : bool, keyword-only
        The recorder's compression (the SDK's default).
    serial : str, keyword-only
        The serial number the device reports.
    paced : bool, keyword-only
        Push the frames at the pace of their times, as a camera gives them (the recorder
        stamps each message with its arrival: a recording played at its recorded pace
        then plays at the frames' pace); otherwise as fast as they come.
    extrinsics : (rotation, translation), keyword-only, optional
        From depth to colour as the SDK holds them (9 numbers column-major, 3 in
        metres); default: the same place (the depth written is colour's, subsampled).

    Returns
    -------
    Path

    Raises
    ------
    OverwriteError
        ``path`` exists.
    UnreadableInputError
        The ``realsense`` extra is missing.
    """
    rs = realsense_sdk()
    path = Path(path)
    if path.exists():
        raise OverwriteError(f"'{path}' exists; a recording is written only to a new path")
    dev, (d_sensor, d_prof), (c_sensor, c_prof) = _software_camera(
        rs, intrinsics, depth_intrinsics(intrinsics, depth_step), depth_scale_m, fps,
        serial, extrinsics,
    )
    try:
        recorder = rs.recorder(str(path), dev, compress)
    except RuntimeError as exc:
        raise InvalidInputError(f"cannot record to '{path}': {exc}") from None
    queue = rs.frame_queue(4)
    d_sensor.open(d_prof)
    c_sensor.open(c_prof)
    d_sensor.start(queue)
    c_sensor.start(queue)
    d_vs, c_vs = d_prof.as_video_stream_profile(), c_prof.as_video_stream_profile()
    per_mm = 0.001 / depth_scale_m
    offset = None  # wall clock minus frame time, paced
    try:
        for n, (t, rgb, depth_mm) in enumerate(frames):
            if paced:
                offset = time.perf_counter() - t if offset is None else offset
                time.sleep(max(0.0, offset + t - time.perf_counter()))
            sampled = depth_mm[::depth_step, ::depth_step].astype(np.float64) * per_mm
            raw = np.clip(np.rint(sampled), 0, 65535).astype(np.uint16)
            _push(rs, d_sensor, d_vs, raw, 2, t, n, depth_scale_m)
            _push(rs, c_sensor, c_vs, np.ascontiguousarray(rgb, np.uint8), 3, t, n, 0.0)
            while queue.poll_for_frame():  # the frames are recorded; nobody else needs them
                pass
    finally:
        for sensor in (d_sensor, c_sensor):
            sensor.stop()
            sensor.close()
        del recorder  # the file is complete once the recorder is released
    return path


def _software_camera(
    rs: Any,
    intrinsics: Intrinsics,
    d_intr: Intrinsics,
    depth_scale_m: float,
    fps: int,
    serial: str,
    extrinsics: tuple[tuple[float, ...], tuple[float, ...]] | None,
) -> tuple[Any, tuple[Any, Any], tuple[Any, Any]]:
    """A software D435 for :func:`write_realsense_recording`: the device, and its depth
    and colour sensors with their stream profiles, depth placed to colour by
    ``extrinsics`` (default: the same place)."""
    dev = rs.software_device()
    dev.register_info(rs.camera_info.name, "Intel RealSense D435 (software)")
    dev.register_info(rs.camera_info.serial_number, serial)
    d_sensor, c_sensor = dev.add_sensor("Stereo Module"), dev.add_sensor("RGB Camera")
    d_sensor.add_read_only_option(rs.option.depth_units, depth_scale_m)
    d_prof = d_sensor.add_video_stream(
        _stream(rs, rs.stream.depth, 0, d_intr, rs.format.z16, 2, fps)
    )
    c_prof = c_sensor.add_video_stream(
        _stream(rs, rs.stream.color, 1, intrinsics, rs.format.rgb8, 3, fps)
    )
    place = rs.extrinsics()
    place.rotation = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
    place.translation = [0.0, 0.0, 0.0]
    if extrinsics is not None:
        place.rotation = [float(v) for v in extrinsics[0]]
        place.translation = [float(v) for v in extrinsics[1]]
    d_prof.register_extrinsics_to(c_prof, place)
    return dev, (d_sensor, d_prof), (c_sensor, c_prof)
