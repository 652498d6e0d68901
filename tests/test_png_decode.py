"""PNG decoding with ISA-L's inflate: the same pixels as the PNG standard and OpenCV give,
for every row filter and the layouts cameras write, and one-line errors on damage.

The files are written here by a small encoder that follows the PNG specification (filter
types 0-4 chosen per row), independent of the code under test and of OpenCV's writer.
"""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import cv2
import numpy as np
import pytest

from dgli_vision.core.errors import UnreadableInputError
from dgli_vision.sources import png_decode
from dgli_vision.sources.frames import read_color, read_depth


def _chunk(kind: bytes, payload: bytes) -> bytes:
    return struct.pack(">I", len(payload)) + kind + payload + struct.pack(
        ">I", zlib.crc32(kind + payload)
    )


def _paeth(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    p = a + b - c
    pa, pb, pc = np.abs(p - a), np.abs(p - b), np.abs(p - c)
    return np.where((pa <= pb) & (pa <= pc), a, np.where(pb <= pc, b, c))


def _filter_row(kind: int, row: np.ndarray, above: np.ndarray, bpp: int) -> bytes:
    """One row filtered as the PNG specification defines it (bytes, mod 256)."""
    x = row.astype(np.int32)
    b = above.astype(np.int32)
    a = np.concatenate([np.zeros(bpp, np.int32), x[:-bpp]])
    c = np.concatenate([np.zeros(bpp, np.int32), b[:-bpp]])
    predictor = {0: 0, 1: a, 2: b, 3: (a + b) // 2, 4: _paeth(a, b, c)}[kind]
    return bytes([kind]) + ((x - predictor) % 256).astype(np.uint8).tobytes()


def write_png_with(
    path: Path, pixels: np.ndarray, kinds: list[int], *, level: int = 6, split: int = 0
) -> bytes:
    """Write ``pixels`` (uint8 H x W x 3 RGB, uint8 or uint16 H x W grey) as a PNG whose
    row ``r`` uses filter ``kinds[r % len(kinds)]``; ``split`` > 0 cuts the image data
    into IDAT chunks of that many bytes."""
    h, w = pixels.shape[:2]
    colour = 2 if pixels.ndim == 3 else 0
    depth = 16 if pixels.dtype == np.uint16 else 8
    raw = pixels.astype(">u2") if depth == 16 else pixels
    rows = np.frombuffer(raw.tobytes(), np.uint8).reshape(h, -1)
    bpp = (3 if colour == 2 else 1) * depth // 8
    above = np.zeros(rows.shape[1], np.uint8)
    out = []
    for r in range(h):
        out.append(_filter_row(kinds[r % len(kinds)], rows[r], above, bpp))
        above = rows[r]
    stream = zlib.compress(b"".join(out), level)
    parts = [stream[i : i + split] for i in range(0, len(stream), split)] if split else [stream]
    ihdr = struct.pack(">IIBBBBB", w, h, depth, colour, 0, 0, 0)
    data = png_decode.PNG_SIGNATURE + _chunk(b"IHDR", ihdr)
    data += b"".join(_chunk(b"IDAT", p) for p in parts) + _chunk(b"IEND", b"")
    path.write_bytes(data)
    return data


@pytest.fixture(scope="module")
def rgb() -> np.ndarray:
    rng = np.random.default_rng(7)
    ramp = np.linspace(0, 200, 64)[None, :, None]
    return (rng.integers(0, 56, (24, 64, 3)) + ramp).astype(np.uint8)


@pytest.fixture(scope="module")
def depth() -> np.ndarray:
    rng = np.random.default_rng(8)
    return (rng.integers(0, 3000, (24, 64)) + 400).astype(np.uint16)


FILTERS = [[0], [1], [2], [3], [4], [1, 2], [2, 1, 0], [0, 1, 2, 3, 4], [4, 3]]


@pytest.mark.parametrize("kinds", FILTERS, ids=lambda k: "filters " + "".join(map(str, k)))
def test_every_row_filter_gives_the_image_written(tmp_path, rgb, depth, kinds):
    color_file, depth_file = tmp_path / "c.png", tmp_path / "d.png"
    write_png_with(color_file, rgb, kinds, split=1000)
    write_png_with(depth_file, depth, kinds)
    np.testing.assert_array_equal(read_color(color_file), rgb)
    np.testing.assert_array_equal(read_depth(depth_file), depth)
    # and what OpenCV's own decoder gives (channels as OpenCV orders them)
    np.testing.assert_array_equal(cv2.imread(str(color_file))[..., ::-1], rgb)
    np.testing.assert_array_equal(cv2.imread(str(depth_file), cv2.IMREAD_UNCHANGED), depth)


def test_opencv_written_frames_decode_as_opencv_reads_them(tmp_path, rgb, depth):
    """OpenCV's writer (every row Sub), RGBA and 8-bit grey: the same as OpenCV reads."""
    bgra = np.dstack([rgb, rgb[..., :1]])
    for name, image in (("bgr", rgb), ("bgra", bgra), ("g", rgb[..., 1])):
        path = tmp_path / f"{name}.png"
        cv2.imwrite(str(path), image)
        expected = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        if name == "g":  # grey as colour is refused, so compare the decoder itself
            buf = path.read_bytes()
            png = png_decode.walk_png(buf, "x")
            got = png_decode.unfilter(png_decode.inflate_rows(buf, png), png)
            np.testing.assert_array_equal(got, expected)
        else:
            np.testing.assert_array_equal(read_color(path), expected[..., 2::-1])
    cv2.imwrite(str(tmp_path / "d.png"), depth)
    np.testing.assert_array_equal(read_depth(tmp_path / "d.png"), depth)


def test_without_isal_opencv_decodes_the_file(tmp_path, rgb, depth, monkeypatch):
    write_png_with(tmp_path / "c.png", rgb, [4, 1])
    write_png_with(tmp_path / "d.png", depth, [2])
    monkeypatch.setattr(png_decode, "_fast_zlib", None)
    np.testing.assert_array_equal(read_color(tmp_path / "c.png"), rgb)
    np.testing.assert_array_equal(read_depth(tmp_path / "d.png"), depth)


def _rewrite_idat(data: bytes, stream: bytes) -> bytes:
    """The same PNG with its image data replaced (checksums right)."""
    start = data.index(b"IDAT") - 4
    end = data.index(b"IEND") - 4
    return data[:start] + _chunk(b"IDAT", stream) + data[end:]


def test_image_data_that_do_not_inflate_are_one_line_naming_the_file(tmp_path, depth):
    path = tmp_path / "d.png"
    data = write_png_with(path, depth, [1])
    path.write_bytes(_rewrite_idat(data, b"\x78\x01" + b"\xff" * 200))
    with pytest.raises(UnreadableInputError, match=r"depth image '.*d\.png' is damaged"):
        read_depth(path)


def test_image_data_larger_than_the_header_allows_are_refused(tmp_path, depth):
    """A small file that inflates to far more than its header's pixels (a zip bomb)."""
    path = tmp_path / "d.png"
    data = write_png_with(path, depth, [0])
    bomb = zlib.compress(bytes(50 * len(depth.tobytes())), 9)
    path.write_bytes(_rewrite_idat(data, bomb))
    with pytest.raises(UnreadableInputError, match="more than its 64x24 header allows"):
        read_depth(path)
