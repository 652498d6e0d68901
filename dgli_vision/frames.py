"""RGB-D input: colour and depth images, camera intrinsics, and the validated pair."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .camera import DEFAULT_INTRINSICS, Intrinsics
from .errors import CalibrationError, InvalidInputError, UnreadableInputError
from .io import read_json, write_png

__all__ = [
    "RGBDFrame",
    "parse_intrinsics",
    "read_color",
    "read_depth",
    "read_frame",
    "read_intrinsics",
    "write_color",
    "write_depth",
]


@dataclass(frozen=True, eq=False)
class RGBDFrame:
    """A registered colour + depth pair, validated.

    Attributes
    ----------
    color : ndarray of uint8, shape (H, W, 3)
        RGB.
    depth_mm : ndarray of uint16, shape (H, W)
        z-depth in mm, 0 = no reading.
    intrinsics : Intrinsics
    color_path, depth_path : str
        Where they came from (for messages and reports).
    intrinsics_source : str
        The intrinsics file, or ``"default"``.
    """

    color: NDArray[np.uint8]
    depth_mm: NDArray[np.uint16]
    intrinsics: Intrinsics
    color_path: str = ""
    depth_path: str = ""
    intrinsics_source: str = "default"


def _check_file(p: Path, what: str) -> None:
    if not p.exists():
        raise UnreadableInputError(f"{what} '{p}' does not exist")
    if p.is_dir():
        raise UnreadableInputError(f"{what} '{p}' is a directory; expected an image file")
    if p.stat().st_size == 0:
        raise UnreadableInputError(f"{what} '{p}' is empty")


def _imread(p: Path, what: str) -> NDArray:
    import cv2

    _check_file(p, what)
    data = np.fromfile(str(p), dtype=np.uint8)
    image = cv2.imdecode(data, cv2.IMREAD_UNCHANGED)  # None instead of raising
    if image is None:
        raise UnreadableInputError(f"{what} '{p}' is not an image OpenCV can decode")
    return image


def _describe(image: NDArray) -> str:
    channels = 1 if image.ndim == 2 else image.shape[2]
    return f"{channels}-channel {image.dtype.itemsize * 8}-bit"


def read_color(path: str | Path) -> NDArray[np.uint8]:
    """Read a colour image (8-bit PNG or JPEG, or 16-bit PNG scaled to 8 bits) as RGB
    (H, W, 3).

    Raises
    ------
    UnreadableInputError, InvalidInputError
    """
    import cv2

    p = Path(path)
    image = _imread(p, "colour image")
    if image.dtype == np.uint16 and image.ndim == 3:
        # 16-bit colour (a common camera export): to 8 bits, rounding (65535 -> 255)
        image = ((image.astype(np.uint32) * 255 + 32767) // 65535).astype(np.uint8)
    if image.dtype != np.uint8:
        raise InvalidInputError(
            f"colour image '{p}' is {_describe(image)}; expected an 8-bit RGB image"
            + (" (was the depth image given as colour?)" if image.ndim == 2 else "")
        )
    if image.ndim == 2 or image.shape[2] not in (3, 4):
        raise InvalidInputError(
            f"colour image '{p}' is {_describe(image)}; expected 3-channel RGB"
        )
    code = cv2.COLOR_BGRA2RGB if image.shape[2] == 4 else cv2.COLOR_BGR2RGB
    return cv2.cvtColor(image, code)


def read_depth(path: str | Path) -> NDArray[np.uint16]:
    """Read a 16-bit single-channel depth PNG in mm (H, W).

    Raises
    ------
    UnreadableInputError, InvalidInputError
    """
    p = Path(path)
    image = _imread(p, "depth image")
    if image.ndim == 3 and image.shape[2] > 1:
        raise InvalidInputError(
            f"depth image '{p}' is {_describe(image)} (a colour image?); "
            "expected a 16-bit single-channel PNG in mm"
        )
    image = image.reshape(image.shape[:2])
    if image.dtype != np.uint16:
        raise InvalidInputError(
            f"depth image '{p}' is {image.dtype.itemsize * 8}-bit; expected a 16-bit PNG in mm"
        )
    if not image.any():
        raise InvalidInputError(f"depth image '{p}' has no valid reading (all pixels are 0)")
    return image


def parse_intrinsics(data: Any, source: str) -> Intrinsics:
    """Validate Open3D ``PinholeCameraIntrinsic`` JSON (matrix column-major), with an
    optional ``"distortion": [k1, k2, p1, p2[, k3...]]`` (OpenCV's order; Open3D itself
    ignores the key).

    Raises
    ------
    CalibrationError
        Naming ``source`` and what is wrong.
    """
    from .intrinsics_files import check_size_and_focal, make_intrinsics, parse_distortion

    if not isinstance(data, dict):
        raise CalibrationError(f"intrinsics '{source}' must be a JSON object")
    missing = [k for k in ("width", "height", "intrinsic_matrix") if k not in data]
    if missing:
        raise CalibrationError(f"intrinsics '{source}' lack {', '.join(missing)}")
    m = data["intrinsic_matrix"]
    try:
        width, height = int(data["width"]), int(data["height"])
        k = np.asarray(m, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise CalibrationError(f"intrinsics '{source}' have non-numeric values") from None
    if k.shape != (9,) or not np.isfinite(k).all():
        raise CalibrationError(
            f"intrinsics '{source}': intrinsic_matrix must be 9 finite numbers, got {m!r}"
        )
    fx, fy, cx, cy = k[0], k[4], k[6], k[7]
    check_size_and_focal(width, height, fx, fy, source)
    if abs(k[8] - 1) > 1e-9 or any(abs(k[i]) > 1e-9 for i in (1, 2, 3, 5)):
        raise CalibrationError(
            f"intrinsics '{source}': intrinsic_matrix {k.tolist()} is not a pinhole matrix "
            "[fx, 0, 0, 0, fy, 0, cx, cy, 1] (column-major)"
        )
    distortion: tuple[float, ...] = ()
    if data.get("distortion") is not None:
        distortion = parse_distortion(data["distortion"], source)
    return make_intrinsics(width, height, fx, fy, cx, cy, distortion, source)


def _looks_like_json(p: Path) -> bool:
    """Whether a file of no telling extension starts like JSON (``{`` or ``[``)."""
    try:
        with p.open("rb") as fh:
            head = fh.read(256).lstrip(b"\xef\xbb\xbf \t\r\n")
    except OSError:
        return True  # let the JSON reader say what is wrong
    return head[:1] in (b"{", b"[")


def read_intrinsics(path: str | Path) -> Intrinsics:
    """Read camera intrinsics, with lens distortion when the file gives it.

    Open3D's intrinsics JSON (optionally with ``"distortion"``), an OpenCV calibration
    file (YAML, JSON or XML as ``cv2.FileStorage`` writes it: ``camera_matrix``,
    ``distortion_coefficients``, ``image_width``, ``image_height``) or a ROS
    ``camera_info`` YAML; told apart by extension and content (see
    :mod:`dgli_vision.intrinsics_files`).

    Raises
    ------
    UnreadableInputError
        The file does not exist or is a directory.
    CalibrationError
        One line naming the file and what is wrong.
    """
    from .intrinsics_files import MATRIX_KEYS, parse_calibration, read_calibration_file

    p = Path(path)
    suffix = p.suffix.lower()
    if p.is_file() and suffix != ".json":
        if suffix in (".yaml", ".yml", ".xml") or not _looks_like_json(p):
            return read_calibration_file(p, str(path))
    try:
        data = read_json(path, what="intrinsics")
    except InvalidInputError as exc:
        raise CalibrationError(str(exc)) from None
    if (
        isinstance(data, dict)
        and "intrinsic_matrix" not in data
        and any(key in data for key in MATRIX_KEYS)
    ):
        return parse_calibration(data, str(path))
    return parse_intrinsics(data, str(path))


def read_frame(
    color_path: str | Path,
    depth_path: str | Path,
    intrinsics_path: str | Path | None = None,
    *,
    threads: bool = True,
) -> RGBDFrame:
    """Read and validate a colour + depth pair and its intrinsics.

    Intrinsics are looked up in SPEC section 4's order: ``intrinsics_path``;
    ``intrinsics.json`` beside the colour image; the nominal Kinect default. With
    ``threads`` the two images are decoded concurrently (PNG decoding releases the GIL).

    Raises
    ------
    UnreadableInputError, InvalidInputError, CalibrationError
        One line naming the file and what is wrong.
    """
    from concurrent.futures import ThreadPoolExecutor

    if threads:
        with ThreadPoolExecutor(2) as pool:
            color_job = pool.submit(read_color, color_path)
            depth_job = pool.submit(read_depth, depth_path)
            color = color_job.result()
            depth = depth_job.result()
    else:
        color, depth = read_color(color_path), read_depth(depth_path)
    if color.shape[:2] != depth.shape:
        raise InvalidInputError(
            f"depth image '{depth_path}' is {depth.shape[1]}x{depth.shape[0]} but colour image "
            f"'{color_path}' is {color.shape[1]}x{color.shape[0]}; expected registered images "
            "of the same size"
        )
    source = "default"
    if intrinsics_path is not None:
        intr = read_intrinsics(intrinsics_path)
        source = str(intrinsics_path)
    elif (Path(color_path).parent / "intrinsics.json").is_file():
        source = str(Path(color_path).parent / "intrinsics.json")
        intr = read_intrinsics(source)
    else:
        intr = DEFAULT_INTRINSICS
    h, w = depth.shape
    if (intr.width, intr.height) != (w, h):
        raise CalibrationError(
            f"intrinsics '{source}' are for {intr.width}x{intr.height} images but "
            f"'{color_path}' is {w}x{h}"
        )
    return RGBDFrame(color, depth, intr, str(color_path), str(depth_path), source)


def write_color(path: str | Path, rgb: NDArray[np.uint8]) -> None:
    """Write an RGB uint8 image (PNG or JPEG by extension)."""
    import cv2

    write_png(path, cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))


def write_depth(path: str | Path, depth_mm: NDArray[np.uint16]) -> None:
    """Write a uint16 depth image in mm as a 16-bit PNG."""
    if depth_mm.dtype != np.uint16:
        raise ValueError(f"depth must be uint16, got {depth_mm.dtype}")
    write_png(path, depth_mm)
