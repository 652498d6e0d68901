"""Camera calibration files other than Open3D's intrinsics JSON.

``--intrinsics`` reads, besides Open3D's ``PinholeCameraIntrinsic`` JSON (see
:func:`dgli_vision.sources.frames.parse_intrinsics`):

* OpenCV calibration files as ``cv2.FileStorage`` writes them (YAML, JSON or XML):
  ``camera_matrix`` (or ``K``) and ``distortion_coefficients`` (or ``D``), each an
  ``opencv-matrix`` (``rows``, ``cols``, ``data``) or a plain list, with ``image_width``
  and ``image_height``;
* ROS ``camera_info`` YAML (``camera_calibration``'s output): ``image_width``,
  ``image_height``, ``camera_matrix: {rows, cols, data}``, ``distortion_model`` and
  ``distortion_coefficients: {data}``.

Matrices in these files are row-major (unlike Open3D's column-major JSON). YAML and XML
are parsed with OpenCV's own ``FileStorage`` (no YAML library is needed).

Every format may carry the camera's handedness, ``"mirrored"`` (:func:`parse_mirrored`):
``true`` for a camera that mirrors its image left to right (a webcam's "mirror" setting,
a driver's flip), ``false`` for one that does not. ``dgli calibrate`` writes it from an
image of the flat napkin lying front face up. Without the key the camera is taken as not
mirrored (the RealSense, Azure Kinect and ZED drivers never mirror); ``--mirroring``
overrides it (:func:`dgli_vision.core.handedness.camera_mirroring`).
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..core.camera import DISTORTION_LENGTHS, Intrinsics
from ..core.errors import CalibrationError

__all__ = [
    "MATRIX_KEYS",
    "SUPPORTED_DISTORTION_MODELS",
    "check_numbers",
    "check_size_and_focal",
    "intrinsics_text",
    "load_calibration_text",
    "make_intrinsics",
    "parse_calibration",
    "parse_distortion",
    "parse_mirrored",
    "read_calibration_file",
]

#: ``distortion_model`` names whose coefficients are OpenCV's ``k1, k2, p1, p2[, k3...]``
#: (ROS's ``plumb_bob`` and ``rational_polynomial``; Kalibr's ``radtan``).
SUPPORTED_DISTORTION_MODELS = ("plumb_bob", "rational_polynomial", "radtan")

#: Names of the camera matrix in OpenCV and ROS files.
MATRIX_KEYS = ("camera_matrix", "cameraMatrix", "K", "k")
_DISTORTION_KEYS = (
    "distortion_coefficients",
    "dist_coeffs",
    "distCoeffs",
    "distortion",
    "D",
    "d",
)
_SIZE_KEYS = (("image_width", "image_height"), ("width", "height"))


def _not_a_number(value: Any, where: str) -> tuple[str, Any] | None:
    """The first value in ``value`` (a number or nested lists of them) that is not a
    number, with where it is (``"[0]"``), or None: a string (``"605.0"``) or a bool
    (``true``) is not a number, though Python's ``float()`` would make one of it."""
    if isinstance(value, (list, tuple)):
        for k, item in enumerate(value):
            found = _not_a_number(item, f"{where}[{k}]")
            if found is not None:
                return found
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        return where, value
    return None


def check_numbers(value: Any, what: str, source: str) -> None:
    """Refuse a value that should be numbers (a number, or lists of numbers) and holds
    something else: the documented types, exactly (JSON numbers; never a string that
    looks like one, nor true/false).

    Raises
    ------
    CalibrationError
        Naming ``source``, the entry (``intrinsic_matrix[0]``) and what it holds.
    """
    found = _not_a_number(value, what)
    if found is None:
        return
    where, bad = found
    kind = {str: "a string", bool: "a boolean", type(None): "null"}.get(
        type(bad), f"a {type(bad).__name__}"
    )
    raise CalibrationError(
        f"intrinsics '{source}': {where} is {kind} ({_json_text(bad)}); expected a number "
        "(a JSON number, written without quotes)"
    )


def _json_text(value: Any) -> str:
    """``value`` as JSON would write it (``"605.0"``, ``true``), shortened."""
    import json

    try:
        text = json.dumps(value)
    except (TypeError, ValueError):
        text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _numbers(value: Any, what: str, source: str) -> NDArray[np.float64]:
    """The numbers of a matrix given as ``{rows, cols, data}`` (OpenCV, ROS) or as a flat
    or nested list, flattened row by row."""
    data = value.get("data") if isinstance(value, Mapping) else value
    if isinstance(value, Mapping) and data is None:
        raise CalibrationError(f"intrinsics '{source}': {what} has no 'data'")
    check_numbers(data, what, source)
    try:
        out = np.asarray(data, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise CalibrationError(
            f"intrinsics '{source}': {what} must be numbers, got {data!r}"
        ) from None
    if isinstance(value, Mapping) and "rows" in value and "cols" in value:
        try:
            n = int(value["rows"]) * int(value["cols"])
        except (TypeError, ValueError):
            n = -1
        if n != out.size:
            raise CalibrationError(
                f"intrinsics '{source}': {what} is {value['rows']}x{value['cols']} but "
                f"holds {out.size} numbers"
            )
    if not np.isfinite(out).all():
        raise CalibrationError(f"intrinsics '{source}': {what} has non-finite values")
    return out


def parse_distortion(value: Any, source: str, what: str = "distortion") -> tuple[float, ...]:
    """OpenCV distortion coefficients ``(k1, k2, p1, p2[, k3...])`` from a list or an
    ``opencv-matrix``; at most 14 finite numbers (shorter vectors are padded with zeros
    where used). All zero is no distortion: ``()``, so that equal lenses compare equal.

    Raises
    ------
    CalibrationError
        Naming ``source`` and what is wrong.
    """
    d = _numbers(value, what, source)
    if d.size > max(DISTORTION_LENGTHS):
        raise CalibrationError(
            f"intrinsics '{source}': {what} has {d.size} coefficients; OpenCV's model has "
            f"at most {max(DISTORTION_LENGTHS)} (k1, k2, p1, p2, k3, ...)"
        )
    return tuple(float(c) for c in d) if d.any() else ()


def parse_mirrored(data: Mapping[str, Any], source: str) -> bool | None:
    """The camera's declared handedness, ``data["mirrored"]``: True, False, or None
    when the key is absent (or null). YAML and XML give 0 and 1 (OpenCV writes no
    booleans), taken as False and True.

    Raises
    ------
    CalibrationError
        A value that is neither a boolean nor 0 or 1.
    """
    value = data.get("mirrored")
    if value is None:
        return None
    if isinstance(value, bool) or (isinstance(value, int) and value in (0, 1)):
        return bool(value)
    raise CalibrationError(
        f"intrinsics '{source}': mirrored is {value!r}; expected true or false (does the "
        "camera mirror its image left to right?)"
    )


def check_size_and_focal(width: int, height: int, fx: float, fy: float, source: str) -> None:
    """Raise :class:`CalibrationError` unless the image size and focal lengths are
    positive."""
    if width <= 0 or height <= 0:
        raise CalibrationError(
            f"intrinsics '{source}': image size {width}x{height} is not positive"
        )
    if fx <= 0 or fy <= 0:
        raise CalibrationError(
            f"intrinsics '{source}': focal lengths fx={fx}, fy={fy} must be positive"
        )


def make_intrinsics(
    width: int,
    height: int,
    fx: float,
    fy: float,
    cx: float,
    cy: float,
    distortion: tuple[float, ...],
    source: str,
    mirrored: bool | None = None,
) -> Intrinsics:
    """Validated :class:`~dgli_vision.core.camera.Intrinsics` (``mirrored``: the
    camera's declared handedness, :func:`parse_mirrored`).

    Raises
    ------
    CalibrationError
        A size or focal length that is not positive, or a principal point outside the
        image.
    """
    check_size_and_focal(width, height, fx, fy, source)
    if not (0 <= cx <= width and 0 <= cy <= height):
        raise CalibrationError(
            f"intrinsics '{source}': principal point ({cx}, {cy}) lies outside the "
            f"{width}x{height} image"
        )
    return Intrinsics(
        width, height, float(fx), float(fy), float(cx), float(cy), distortion, mirrored
    )


def _first(data: Mapping[str, Any], keys: tuple[str, ...]) -> tuple[str, Any] | None:
    for key in keys:
        if key in data:
            return key, data[key]
    return None


def _image_size(data: Mapping[str, Any], source: str) -> tuple[int, int]:
    for wkey, hkey in _SIZE_KEYS:
        if wkey in data and hkey in data:
            check_numbers(data[wkey], wkey, source)
            check_numbers(data[hkey], hkey, source)
            try:
                return int(data[wkey]), int(data[hkey])
            except (TypeError, ValueError):
                raise CalibrationError(
                    f"intrinsics '{source}': {wkey}/{hkey} must be integers, got "
                    f"{data[wkey]!r}/{data[hkey]!r}"
                ) from None
    raise CalibrationError(
        f"intrinsics '{source}' give no image size (add image_width and image_height)"
    )


def parse_calibration(data: Any, source: str) -> Intrinsics:
    """Intrinsics from an OpenCV calibration file or a ROS ``camera_info`` YAML, as a
    mapping (parsed JSON, or :func:`load_calibration_text`).

    Raises
    ------
    CalibrationError
        Naming ``source`` and what is wrong (one line).
    """
    if not isinstance(data, Mapping):
        raise CalibrationError(
            f"intrinsics '{source}' must be a mapping (Open3D JSON, an OpenCV calibration "
            "file or a ROS camera_info YAML)"
        )
    found = _first(data, MATRIX_KEYS)
    if found is None:
        raise CalibrationError(
            f"intrinsics '{source}' have no camera matrix (expected Open3D's "
            "intrinsic_matrix, or camera_matrix or K of an OpenCV or ROS calibration file)"
        )
    key, value = found
    k = _numbers(value, key, source)
    if k.size != 9:
        raise CalibrationError(f"intrinsics '{source}': {key} must be 3x3, got {k.size} numbers")
    k = k.reshape(3, 3)
    if abs(k[2, 2] - 1) > 1e-9 or any(
        abs(k[i, j]) > 1e-9 for i, j in ((0, 1), (1, 0), (2, 0), (2, 1))
    ):
        raise CalibrationError(
            f"intrinsics '{source}': {key} {k.reshape(-1).tolist()} is not a pinhole matrix "
            "[fx, 0, cx, 0, fy, cy, 0, 0, 1] (row by row)"
        )
    distortion: tuple[float, ...] = ()
    found = _first(data, _DISTORTION_KEYS)
    if found is not None:
        distortion = parse_distortion(found[1], source, found[0])
    model = data.get("distortion_model")
    if model not in (None, "", *SUPPORTED_DISTORTION_MODELS) and any(distortion):
        raise CalibrationError(
            f"intrinsics '{source}': distortion_model {model!r} is not supported "
            f"(expected {' or '.join(SUPPORTED_DISTORTION_MODELS)})"
        )
    width, height = _image_size(data, source)
    return make_intrinsics(
        width, height, k[0, 0], k[1, 1], k[0, 2], k[1, 2], distortion, source,
        parse_mirrored(data, source),
    )


def _node_value(node: Any) -> Any:
    """A ``cv2.FileNode`` as Python values (dict, list, int, float, str, None)."""
    if node.isMap():
        return {key: _node_value(node.getNode(key)) for key in node.keys()}
    if node.isSeq():
        return [_node_value(node.at(i)) for i in range(node.size())]
    if node.isInt():
        return int(node.real())
    if node.isReal():
        return float(node.real())
    if node.isString():
        return node.string()
    return None


def load_calibration_text(text: str, source: str) -> Any:
    """Parse YAML (OpenCV's or plain, as ROS writes it), XML or JSON with OpenCV's
    ``FileStorage`` into Python values.

    Raises
    ------
    CalibrationError
        The text is not a document ``FileStorage`` can read (with its reason and line).
    """
    import cv2

    flags = cv2.FILE_STORAGE_READ | cv2.FILE_STORAGE_MEMORY
    # OpenCV 4 reads YAML only after its "%YAML" directive (ROS writes plain YAML)
    head = text.lstrip()[:1]
    added = 0 if head in ("%", "{", "[", "<") else 1
    try:
        storage = cv2.FileStorage("%YAML:1.0\n" * added + text, flags)
    except (cv2.error, SystemError) as exc:
        message = str(exc.__cause__ or exc).strip().splitlines()
        where = re.search(r"\((\d+)\): (.*?)'?$", message[-1] if message else "")
        line = int(where.group(1)) - added if where else 0
        why = f"line {line}: {where.group(2)}" if where else "unknown format"
        raise CalibrationError(
            f"intrinsics '{source}' are neither JSON nor YAML/XML that OpenCV can read ({why})"
        ) from None
    try:
        if not storage.isOpened():
            raise CalibrationError(f"intrinsics '{source}' cannot be parsed")
        return _node_value(storage.root())
    finally:
        storage.release()


def read_calibration_file(path: Path, source: str) -> Intrinsics:
    """Intrinsics from an OpenCV or ROS calibration file that is not Open3D JSON.

    Raises
    ------
    CalibrationError
    """
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise CalibrationError(
            f"intrinsics '{source}' is not a text file (expected JSON, YAML or XML)"
        ) from None
    except OSError as exc:
        raise CalibrationError(f"cannot read intrinsics '{source}': {exc.strerror}") from None
    if not text.strip():
        raise CalibrationError(f"intrinsics '{source}' is empty")
    return parse_calibration(load_calibration_text(text, source), source)


def intrinsics_text(intrinsics: Intrinsics, path: str | Path) -> str:
    """The file :func:`dgli_vision.sources.frames.read_intrinsics` reads back, by the extension
    of ``path``: an OpenCV calibration file for ``.yaml``, ``.yml`` and ``.xml``
    (``image_width``, ``image_height``, ``camera_matrix``, ``distortion_coefficients``,
    and ``mirrored`` 0 or 1 when declared), else Open3D's intrinsics JSON with
    ``"distortion"`` and ``"mirrored"`` (Open3D ignores those keys)."""
    import json

    suffix = Path(path).suffix.lower()
    if suffix not in (".yaml", ".yml", ".xml"):
        return json.dumps(intrinsics.to_open3d_dict(), indent=1) + "\n"
    import cv2

    storage = cv2.FileStorage(suffix, cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_MEMORY)
    storage.write("image_width", intrinsics.width)
    storage.write("image_height", intrinsics.height)
    storage.write("camera_matrix", intrinsics.matrix())
    d = np.array([intrinsics.distortion or (0.0, 0.0, 0.0, 0.0, 0.0)], dtype=np.float64)
    storage.write("distortion_coefficients", d)
    if intrinsics.mirrored is not None:
        storage.write("mirrored", int(intrinsics.mirrored))
    return storage.releaseAndGetString()
