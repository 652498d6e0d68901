"""The robot's frame: a rigid camera-to-base transform, read from a file, and the 3D
points of a JSON answer put in that frame.

``--extrinsics FILE`` reads either

* a JSON 4 x 4 matrix, row-major, that takes a point in the camera frame (x right,
  y down, z forward, metres) to the robot's base frame: ``[[r11, r12, r13, tx], ...,
  [0, 0, 0, 1]]``, or an object ``{"matrix": [[...]...], "frame": "base_link"}`` (the
  frame's name; ``"base"`` when not given);
* a ROS ``geometry_msgs/TransformStamped`` as YAML (or JSON), as ``ros2 topic echo
  /tf_static`` or ``ros2 run tf2_ros tf2_echo`` give it: ``header.frame_id`` (the
  parent, the robot's base), ``child_frame_id`` (the camera's *optical* frame, x right,
  y down, z forward, as dgli's camera frame) and ``transform: {translation: {x, y, z},
  rotation: {x, y, z, w}}``; a ``tf2_msgs/TFMessage`` (``transforms: [...]``) holding
  one transform is taken too. The answer's frame is named by ``header.frame_id``.

The transform must be rigid (a rotation and a translation): a matrix whose 3 x 3 part is
not orthonormal with determinant +1 (within :data:`RIGID_TOLERANCE`), whose last row is
not ``0 0 0 1``, or a quaternion that is not of unit length, is refused with one line
naming the file. A point is moved by the whole transform; a direction (the table's
normal ``up``) by its rotation only.
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .errors import InvalidInputError, UnreadableInputError
from .io import check_input_file, display_path

__all__ = [
    "CAMERA",
    "POINT_KEYS",
    "RIGID_TOLERANCE",
    "Extrinsics",
    "extrinsics_of",
    "in_frame",
    "moved_point",
    "parse_extrinsics",
    "read_extrinsics",
]

#: How far the rotation part may be from orthonormal (largest entry of ``R^T R - I``,
#: and of ``det R - 1``), and a quaternion's norm from 1: a matrix printed with six
#: decimals is rigid within about 1e-6; a scale or shear of 0.1% is not.
RIGID_TOLERANCE = 1e-4

#: JSON keys whose value is one 3D point (a list of three numbers) in the camera frame.
POINT_KEYS = ("point",)
#: JSON keys whose value is a list of 3D points (a line's two ends).
LINE_KEYS = ("line", "fold_line")
#: JSON keys whose value is a direction (turned, not moved).
DIRECTION_KEYS = ("up",)


@dataclass(frozen=True)
class Extrinsics:
    """A rigid camera-to-base transform.

    Attributes
    ----------
    matrix : ndarray (4, 4) of float64
        ``base_point = matrix @ [x, y, z, 1]`` for a camera-frame point ``(x, y, z)`` in
        metres.
    frame : str
        The name of the frame it takes points to (``"base"``, ``"base_link"``), given in
        the JSON as ``"frame"``.
    source : str
        Where it was read (a file name, for messages).
    """

    matrix: NDArray[np.float64] = field(default_factory=lambda: np.eye(4))
    frame: str = "camera"
    source: str = "default"

    def points(self, xyz: NDArray[np.float64]) -> NDArray[np.float64]:
        """Points (..., 3) in metres, camera frame -> the same points in :attr:`frame`."""
        p = np.asarray(xyz, dtype=np.float64)
        return p @ self.matrix[:3, :3].T + self.matrix[:3, 3]

    def directions(self, v: NDArray[np.float64]) -> NDArray[np.float64]:
        """Directions (..., 3), camera frame -> :attr:`frame` (the rotation alone)."""
        return np.asarray(v, dtype=np.float64) @ self.matrix[:3, :3].T


#: The camera's own frame: the identity, what every answer is in without ``--extrinsics``.
CAMERA = Extrinsics()


def _rigid(m: NDArray[np.float64], source: str) -> NDArray[np.float64]:
    """``m`` checked to be a rigid 4 x 4 transform."""
    where = f"extrinsics '{source}'"
    if m.shape != (4, 4):
        shape = " x ".join(str(n) for n in m.shape) or "scalar"
        raise InvalidInputError(f"{where} is a {shape} matrix; expected 4 x 4 (row-major)")
    if not np.isfinite(m).all():
        raise InvalidInputError(f"{where} has a NaN or infinite entry")
    if np.abs(m[3] - [0.0, 0.0, 0.0, 1.0]).max() > RIGID_TOLERANCE:
        raise InvalidInputError(
            f"{where}: last row is {_row(m[3])}; expected 0 0 0 1 (a rigid transform)"
        )
    r = m[:3, :3]
    off = float(np.abs(r.T @ r - np.eye(3)).max())
    det = float(np.linalg.det(r))
    if off > RIGID_TOLERANCE or abs(det - 1.0) > RIGID_TOLERANCE:
        what = (
            f"is a reflection (determinant {det:.4g})" if det < 0
            else f"is not a rotation (R^T R differs from I by {off:.3g}, determinant {det:.4g})"
        )
        raise InvalidInputError(
            f"{where}: its 3 x 3 part {what}; expected a rigid camera-to-base transform "
            "(a rotation and a translation in metres, no scale or shear)"
        )
    out = m.astype(np.float64, copy=True)
    out[3] = [0.0, 0.0, 0.0, 1.0]
    return out


def _row(values: Any) -> str:
    return " ".join(f"{float(v):g}" for v in values)


def _numbers(value: Any, what: str, source: str) -> NDArray[np.float64]:
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise InvalidInputError(
            f"extrinsics '{source}': {what} is not a list of numbers"
        ) from None
    return a


def _quaternion_matrix(q: dict[str, Any], t: dict[str, Any], source: str) -> NDArray:
    """The 4 x 4 matrix of a ROS transform's rotation (x, y, z, w) and translation."""
    try:
        x, y, z, w = (float(q[k]) for k in ("x", "y", "z", "w"))
        tx, ty, tz = (float(t[k]) for k in ("x", "y", "z"))
    except (KeyError, TypeError, ValueError):
        raise InvalidInputError(
            f"extrinsics '{source}': transform needs translation {{x, y, z}} and rotation "
            "{x, y, z, w} as numbers"
        ) from None
    norm = math.sqrt(x * x + y * y + z * z + w * w)
    if not math.isfinite(norm) or abs(norm - 1.0) > RIGID_TOLERANCE:
        raise InvalidInputError(
            f"extrinsics '{source}': rotation quaternion has length {norm:.6g}; expected a "
            "unit quaternion (x, y, z, w)"
        )
    x, y, z, w = x / norm, y / norm, z / norm, w / norm
    m = np.eye(4)
    m[:3, :3] = [
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ]
    m[:3, 3] = [tx, ty, tz]
    return m


def parse_extrinsics(data: Any, source: str) -> Extrinsics:
    """The transform of a parsed extrinsics document (see the module's docstring).

    Parameters
    ----------
    data : list or dict
        A 4 x 4 list of rows, ``{"matrix": ..., "frame": ...}``, or a ROS
        ``TransformStamped`` (or a ``TFMessage`` of one) as a dict.
    source : str
        Where it came from, for messages.

    Raises
    ------
    InvalidInputError
        Not one of these forms, or not rigid (one line naming ``source``).
    """
    if isinstance(data, dict) and isinstance(data.get("transforms"), list):
        if len(data["transforms"]) != 1:
            raise InvalidInputError(
                f"extrinsics '{source}' holds {len(data['transforms'])} transforms; keep "
                "only the camera's (camera optical frame to the robot's base)"
            )
        data = data["transforms"][0]
    if isinstance(data, dict) and "transform" in data:
        tr = data["transform"]
        if not isinstance(tr, dict):
            raise InvalidInputError(f"extrinsics '{source}': transform is not a mapping")
        m = _quaternion_matrix(tr.get("rotation"), tr.get("translation"), source)
        header = data.get("header") if isinstance(data.get("header"), dict) else {}
        frame = header.get("frame_id") or "base"
        return Extrinsics(_rigid(m, source), str(frame).lstrip("/"), source)
    frame = "base"
    if isinstance(data, dict):
        if "matrix" not in data:
            raise InvalidInputError(
                f"extrinsics '{source}' has neither a 4 x 4 \"matrix\" nor a ROS "
                "\"transform\" (translation, rotation)"
            )
        frame = str(data.get("frame") or data.get("frame_id") or "base")
        data = data["matrix"]
    m = _numbers(data, "the matrix", source)
    if m.shape == (16,):
        m = m.reshape(4, 4)
    return Extrinsics(_rigid(m, source), frame, source)


def _yaml(text: str, source: str) -> Any:
    """Plain YAML (as ROS prints it) parsed with OpenCV's ``FileStorage``: no YAML
    library is needed (as for ROS ``camera_info`` files)."""
    import cv2

    body = "\n".join(
        line for line in text.splitlines() if not re.fullmatch(r"\s*(---|\.\.\.)\s*", line)
    )
    try:
        storage = cv2.FileStorage(
            "%YAML:1.0\n" + body, cv2.FILE_STORAGE_READ | cv2.FILE_STORAGE_MEMORY
        )
    except (cv2.error, SystemError):
        storage = None
    if storage is None or not storage.isOpened():
        raise InvalidInputError(
            f"extrinsics '{source}' is neither JSON nor YAML that can be read"
        )
    try:
        return _node(storage.root())
    finally:
        storage.release()


def _node(node: Any) -> Any:
    if node.isMap():
        return {key: _node(node.getNode(key)) for key in node.keys()}
    if node.isSeq():
        return [_node(node.at(i)) for i in range(node.size())]
    if node.isInt() or node.isReal():
        return float(node.real())
    if node.isString():
        return node.string()
    return None


def read_extrinsics(path: str | Path) -> Extrinsics:
    """The camera-to-base transform of a file (JSON matrix or ROS transform YAML).

    Raises
    ------
    UnreadableInputError
        Missing or unreadable.
    InvalidInputError
        Neither form, or not a rigid transform: one line naming the file.
    """
    p = Path(path)
    check_input_file(p, "extrinsics")
    source = display_path(p)
    try:
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        why = getattr(exc, "strerror", None) or "not a text file"
        raise UnreadableInputError(f"cannot read extrinsics '{source}': {why}") from None
    if not text.strip():
        raise InvalidInputError(f"extrinsics '{source}' is empty")
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        if p.suffix.lower() == ".json":
            raise InvalidInputError(
                f"extrinsics '{source}' is not valid JSON (line {exc.lineno}, column "
                f"{exc.colno}: {exc.msg})"
            ) from None
        data = _yaml(text, source)
    return parse_extrinsics(data, source)


def extrinsics_of(value: Any) -> Extrinsics | None:
    """The transform an API's ``extrinsics=`` argument names: an :class:`Extrinsics`, a
    file path (:func:`read_extrinsics`), a 4 x 4 array or nested list (camera to base,
    row-major; the frame is then ``"base"``), or None (the camera frame).

    Raises
    ------
    InvalidInputError
        Not one of these, or not rigid.
    """
    if value is None or isinstance(value, Extrinsics):
        return value
    if isinstance(value, (str, Path)):
        return read_extrinsics(value)
    if isinstance(value, (list, tuple, np.ndarray)):
        return parse_extrinsics(np.asarray(value, dtype=np.float64).tolist(), "<array>")
    raise InvalidInputError(
        "extrinsics must be an Extrinsics, a file path or a 4 x 4 camera-to-base matrix; "
        f"got {type(value).__name__}"
    )


def moved_point(ext: Extrinsics, p: Any) -> tuple[float, float, float] | None:
    """One camera-frame point (or None) in the frame of ``ext``, as a tuple."""
    if p is None:
        return None
    x, y, z = ext.points(np.asarray(p, dtype=np.float64))
    return float(x), float(y), float(z)


def _is_point(v: Any) -> bool:
    return (
        isinstance(v, list) and len(v) == 3
        and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v)
    )


def in_frame(
    data: Any,
    extrinsics: Extrinsics | None = None,
    *,
    digits: int = 5,
    frame_key: str = "frame",
) -> Any:
    """A JSON answer (the ``to_json()`` of a verdict, a plan, a fold check) with every
    3D point in the frame of ``extrinsics`` and ``"frame"`` naming it.

    Points are the values of :data:`POINT_KEYS` (one point), :data:`LINE_KEYS` (a list of
    points) and :data:`DIRECTION_KEYS` (a direction, turned only), at any depth; pixels
    and sizes on the napkin (``pixel``, ``*_mm``) are not 3D points and stay. The top
    object gains ``frame_key`` (``"frame"``; ``dgli watch``'s lines, whose ``"frame"``
    is the frame's number, say ``"points_frame"``) naming it, ``"camera"`` without
    extrinsics. A new object is returned; ``data`` is not changed.
    """
    ext = extrinsics or CAMERA
    moved = _walk(data, ext, digits) if ext is not CAMERA else data
    if isinstance(moved, dict):
        moved = {**moved, frame_key: ext.frame}
    return moved


def _walk(value: Any, ext: Extrinsics, digits: int) -> Any:
    if isinstance(value, list):
        return [_walk(v, ext, digits) for v in value]
    if not isinstance(value, dict):
        return value
    out = {}
    for key, v in value.items():
        if key in POINT_KEYS and _is_point(v):
            out[key] = _rounded(ext.points(v), digits)
        elif key in LINE_KEYS and isinstance(v, list) and v and all(map(_is_point, v)):
            out[key] = [_rounded(p, digits) for p in ext.points(v)]
        elif key in DIRECTION_KEYS and _is_point(v):
            out[key] = _rounded(ext.directions(v), digits)
        else:
            out[key] = _walk(v, ext, digits)
    return out


def _rounded(p: NDArray[np.float64], digits: int) -> list[float]:
    return [round(float(x), digits) for x in p]
