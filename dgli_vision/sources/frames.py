"""RGB-D input: colour and depth images, camera intrinsics, and the validated pair."""

from __future__ import annotations

import struct
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..core.camera import DEFAULT_INTRINSICS, Intrinsics
from ..core.errors import (
    CalibrationError,
    InvalidInputError,
    InvalidValueError,
    UnreadableInputError,
)
from ..core.frame import RGBDFrame
from ..core.io import check_input_file, read_json, write_png
from .png_decode import PNG_SIGNATURE, PngFile, inflate_rows, stored_png, unfilter, walk_png

# RGBDFrame lives in core (:mod:`dgli_vision.core.frame`: every folder may use it); it
# is named here too, where it was first
__all__ = [
    "MAX_IMAGE_BYTES",
    "MAX_IMAGE_PIXELS",
    "RGBDFrame",
    "check_intrinsics",
    "parse_intrinsics",
    "read_color",
    "read_depth",
    "read_frame",
    "read_intrinsics",
    "write_color",
    "write_depth",
]


#: The largest image decoded, in pixels (an 8K frame has 33 million): checked from the
#: file's header (PNG IHDR, JPEG SOF) before any pixel is decoded, so that a small file
#: that claims a huge image is refused at once instead of filling the memory.
MAX_IMAGE_PIXELS = 50_000_000

#: The largest image file read, in bytes.
MAX_IMAGE_BYTES = 1 << 30

#: JPEG start-of-frame markers (baseline, progressive, lossless, arithmetic...): they carry
#: the image size. 0xC4 (DHT), 0xC8 (JPG) and 0xCC (DAC) are not frames.
_JPEG_SOF = frozenset(range(0xC0, 0xD0)) - {0xC4, 0xC8, 0xCC}


@dataclass(frozen=True, eq=False)
class _EncodedImage:
    """An image file's bytes, the size its header gives (None: not PNG or JPEG) and, for a
    PNG, its walked chunks."""

    data: bytes
    size: tuple[int, int] | None
    png: PngFile | None = None


def _jpeg_size(buf: bytes, where: str) -> tuple[int, int] | None:
    """(width, height) of a JPEG from its start-of-frame segment (None: the height comes
    later, in a DNL segment); a file without its end-of-image marker is truncated."""
    pos = 2
    while pos + 4 <= len(buf):
        if buf[pos] != 0xFF:
            raise UnreadableInputError(f"{where} is a damaged JPEG (no marker at byte {pos})")
        marker = buf[pos + 1]
        if marker == 0xFF:  # fill byte
            pos += 1
            continue
        if marker == 0x01 or 0xD0 <= marker <= 0xD8:  # markers without a segment
            pos += 2
            continue
        if marker == 0xDA:  # start of scan before any frame header
            break
        if marker in _JPEG_SOF:
            if pos + 9 > len(buf):
                break
            height, width = struct.unpack(">HH", buf[pos + 5 : pos + 9])
            if buf.rfind(b"\xff\xd9") < pos:
                raise UnreadableInputError(
                    f"{where} is truncated: the JPEG ends after {len(buf)} bytes, without its "
                    "end-of-image marker"
                )
            return (width, height) if height else None
        pos += 2 + ((buf[pos + 2] << 8) | buf[pos + 3])
    raise UnreadableInputError(f"{where} is a damaged or truncated JPEG (no frame header)")


def _header(data: bytes, where: str) -> tuple[tuple[int, int] | None, PngFile | None]:
    """The (width, height) a PNG or JPEG file's header gives, without decoding it (None
    for another format: OpenCV's own limits then apply), and a PNG's walked chunks.

    Raises
    ------
    UnreadableInputError
        A truncated or damaged PNG or JPEG.
    InvalidInputError
        A header that gives no pixels, or more than :data:`MAX_IMAGE_PIXELS`.
    """
    png = None
    if data.startswith(PNG_SIGNATURE):
        png = walk_png(data, where)
        size: tuple[int, int] | None = (png.width, png.height)
    elif data.startswith(b"\xff\xd8"):
        size = _jpeg_size(data, where)
    else:
        return None, None
    if size is None:
        return None, None
    width, height = size
    if width == 0 or height == 0:
        raise InvalidInputError(f"{where} is {width}x{height} pixels: an empty image")
    if width * height > MAX_IMAGE_PIXELS:
        raise InvalidInputError(
            f"{where} is {width}x{height} pixels ({width * height / 1e6:.0f} megapixels); "
            f"images of up to {MAX_IMAGE_PIXELS / 1e6:.0f} megapixels are read"
        )
    return size, png


def _check_file(p: Path, what: str) -> int:
    """The size in bytes of an input image file that exists, is a regular file, is not
    empty and is not larger than :data:`MAX_IMAGE_BYTES`."""
    size = check_input_file(p, what).st_size
    if size == 0:
        raise UnreadableInputError(f"{what} '{p}' is empty")
    if size > MAX_IMAGE_BYTES:
        raise InvalidInputError(
            f"{what} '{p}' is a file of {size / 2**20:.0f} MiB; image files of up to "
            f"{MAX_IMAGE_BYTES / 2**20:.0f} MiB are read"
        )
    return size


def _read_encoded(p: Path, what: str) -> _EncodedImage:
    """An image file's bytes, with its header checked against the limits."""
    _check_file(p, what)
    try:
        data = p.read_bytes()
    except OSError as exc:
        raise UnreadableInputError(f"cannot read {what} '{p}': {exc.strerror or exc}") from None
    return _EncodedImage(data, *_header(data, f"{what} '{p}'"))


def _decode(image: _EncodedImage, p: Path, what: str) -> NDArray:
    """The decoded image as stored (OpenCV's channel order), for validation."""
    return _decode_as(image, p, what, None)


def _decode_color(image: _EncodedImage, p: Path) -> NDArray[np.uint8]:
    """A colour image as RGB uint8, validated: an 8-bit RGB PNG decoded straight to RGB
    (a tenth faster than decoding and then swapping the channels), anything else as
    stored and then converted."""
    import cv2

    flag = getattr(cv2, "IMREAD_COLOR_RGB", None)  # OpenCV >= 4.10
    png = image.png
    if flag is not None and png and (png.bit_depth, png.colour_type) == (8, 2):
        return _decode_as(image, p, "colour image", flag)
    return _color_of(_decode(image, p, "colour image"), p)


def _decode_as(image: _EncodedImage, p: Path, what: str, flag: int | None) -> NDArray:
    import cv2

    data: bytes | bytearray = image.data
    png = image.png
    rows = inflate_rows(data, png) if png is not None else None
    if png is not None and rows is not None:
        # unfilter's pixels are OpenCV's when RGB is asked of an RGB file, or grey as stored
        if (flag is None) == (png.colour_type == 0):
            pixels = unfilter(rows, png)
            if pixels is not None:
                return pixels
        data = stored_png(data, png, rows)
    flag = cv2.IMREAD_UNCHANGED if flag is None else flag
    try:
        decoded = cv2.imdecode(np.frombuffer(data, np.uint8), flag)  # None, not raising
    except cv2.error as exc:
        raise UnreadableInputError(f"{what} '{p}' cannot be decoded ({exc.err})") from None
    if decoded is None:
        raise UnreadableInputError(f"{what} '{p}' is not an image OpenCV can decode")
    return decoded


def _imread(p: Path, what: str) -> NDArray:
    return _decode(_read_encoded(p, what), p, what)


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
    p = Path(path)
    return _decode_color(_read_encoded(p, "colour image"), p)


def _color_of(image: NDArray, p: Path) -> NDArray[np.uint8]:
    """A decoded colour image (OpenCV's channel order) as RGB uint8, validated."""
    import cv2

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
    return _depth_of(_imread(p, "depth image"), p)


def _depth_of(image: NDArray, p: Path) -> NDArray[np.uint16]:
    """A decoded depth image as uint16 (H, W), validated."""
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
    optional ``"distortion": [k1, k2, p1, p2[, k3...]]`` (OpenCV's order) and
    ``"mirrored": true|false``, the camera's declared handedness
    (:func:`~dgli_vision.sources.intrinsics_files.parse_mirrored`); Open3D itself ignores
    both keys.

    Raises
    ------
    CalibrationError
        Naming ``source`` and what is wrong.
    """
    from .intrinsics_files import (
        check_numbers,
        check_size_and_focal,
        make_intrinsics,
        parse_distortion,
        parse_mirrored,
    )

    if not isinstance(data, dict):
        raise CalibrationError(f"intrinsics '{source}' must be a JSON object")
    missing = [k for k in ("width", "height", "intrinsic_matrix") if k not in data]
    if missing:
        raise CalibrationError(f"intrinsics '{source}' lack {', '.join(missing)}")
    m = data["intrinsic_matrix"]
    for key in ("width", "height", "intrinsic_matrix"):  # JSON numbers, as documented
        check_numbers(data[key], key, source)
    for key in ("width", "height"):
        if data[key] != int(data[key]):
            raise CalibrationError(
                f"intrinsics '{source}': {key} is {data[key]!r}; expected a whole number "
                "of pixels"
            )
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
    mirrored = parse_mirrored(data, source)
    return make_intrinsics(width, height, fx, fy, cx, cy, distortion, source, mirrored)


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
    :mod:`dgli_vision.sources.intrinsics_files`).

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
    intrinsics_path: str | Path | Intrinsics | None = None,
    *,
    threads: bool = True,
) -> RGBDFrame:
    """Read and validate a colour + depth pair and its intrinsics.

    Intrinsics are looked up in SPEC section 4's order: ``intrinsics_path`` (a file, or
    :class:`Intrinsics` given in code); ``intrinsics.json`` beside the colour image; the
    nominal Kinect default. The images' headers are checked (limits, the same size, the
    intrinsics' size) before either is decoded. With ``threads`` the two images are
    decoded concurrently (PNG decoding releases the GIL).

    Raises
    ------
    UnreadableInputError, InvalidInputError, CalibrationError
        One line naming the file and what is wrong.
    """
    from concurrent.futures import ThreadPoolExecutor

    cp, dp = Path(color_path), Path(depth_path)
    color_file = _read_encoded(cp, "colour image")
    depth_file = _read_encoded(dp, "depth image")
    if color_file.size and depth_file.size:  # before decoding either
        _check_same_size(color_file.size, depth_file.size, color_path, depth_path)
    intr, source = _frame_intrinsics(color_path, intrinsics_path)
    size = depth_file.size or color_file.size
    if size is not None:
        _check_intrinsics_size(intr, source, size, color_path)
    if threads:
        with ThreadPoolExecutor(2) as pool:
            color_job = pool.submit(_decode_color, color_file, cp)
            depth_job = pool.submit(_decode, depth_file, dp, "depth image")
            color = color_job.result()
            depth = _depth_of(depth_job.result(), dp)
    else:
        color = _decode_color(color_file, cp)
        depth = _depth_of(_decode(depth_file, dp, "depth image"), dp)
    h, w = depth.shape
    _check_same_size((color.shape[1], color.shape[0]), (w, h), color_path, depth_path)
    _check_intrinsics_size(intr, source, (w, h), color_path)
    return RGBDFrame(color, depth, intr, str(color_path), str(depth_path), source)


def _check_same_size(
    color_wh: tuple[int, int], depth_wh: tuple[int, int], color_path: Any, depth_path: Any
) -> None:
    if color_wh != depth_wh:
        raise InvalidInputError(
            f"depth image '{depth_path}' is {depth_wh[0]}x{depth_wh[1]} but colour image "
            f"'{color_path}' is {color_wh[0]}x{color_wh[1]}; expected registered images "
            "of the same size"
        )


def _frame_intrinsics(
    color_path: str | Path, intrinsics_path: str | Path | Intrinsics | None
) -> tuple[Intrinsics, str]:
    """The intrinsics of a pair and where they came from (SPEC section 4's order)."""
    if isinstance(intrinsics_path, Intrinsics):
        return check_intrinsics(intrinsics_path), "given"
    if intrinsics_path is not None:
        return read_intrinsics(intrinsics_path), str(intrinsics_path)
    beside = Path(color_path).parent / "intrinsics.json"
    if beside.is_file():
        return read_intrinsics(beside), str(beside)
    return DEFAULT_INTRINSICS, "default"


def _check_intrinsics_size(
    intr: Intrinsics, source: str, size: tuple[int, int], color_path: Any
) -> None:
    if (intr.width, intr.height) != size:
        nominal = source == "default"
        raise CalibrationError(
            f"intrinsics '{source}'{' (the nominal camera) ' if nominal else ' '}are for "
            f"{intr.width}x{intr.height} images but '{color_path}' is {size[0]}x{size[1]}"
            + (f"; put the camera's intrinsics.json beside '{Path(color_path).name}' or "
               "give --intrinsics FILE" if nominal else "")
        )


def check_intrinsics(intr: Any, source: str = "given") -> Intrinsics:
    """Validate intrinsics given in code: an :class:`Intrinsics` or a dict in the Open3D
    JSON form, checked as a file's are (:func:`parse_intrinsics`: finite, positive focal
    lengths, principal point in the image).

    Raises
    ------
    CalibrationError
        Naming ``source`` and what is wrong.
    InvalidInputError
        Neither an Intrinsics nor a dict.
    """
    if not isinstance(intr, (Intrinsics, dict)):
        raise InvalidInputError(
            f"intrinsics must be an Intrinsics, an Open3D intrinsics dict or a JSON file's "
            f"path; got {type(intr).__name__}"
        )
    try:
        if isinstance(intr, dict):
            return parse_intrinsics(intr, source)
        parse_intrinsics(intr.to_open3d_dict(), source)  # the same checks as a file's
        distortion = np.asarray(intr.distortion, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        raise CalibrationError(f"intrinsics '{source}' have non-numeric values") from None
    if not np.isfinite(distortion).all():
        raise CalibrationError(
            f"intrinsics '{source}': distortion coefficients must be finite, got "
            f"{list(intr.distortion)}"
        )
    return intr


def write_color(path: str | Path, rgb: NDArray[np.uint8]) -> None:
    """Write an RGB uint8 image (PNG or JPEG by extension)."""
    import cv2

    write_png(path, cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))


def write_depth(path: str | Path, depth_mm: NDArray[np.uint16]) -> None:
    """Write a uint16 depth image in mm as a 16-bit PNG."""
    if depth_mm.dtype != np.uint16:
        raise InvalidValueError(f"depth must be uint16, got {depth_mm.dtype}")
    write_png(path, depth_mm)
