"""PNG decoding without zlib's inflate: the file's chunks walked and checked, its image
data inflated by ISA-L (``isal``, about four times zlib's speed on camera images), and
its rows unfiltered in numpy.

Inflating is most of a PNG's decoding time (16 of 17 ms for a noisy 1280x720 RGB frame
with the zlib OpenCV's wheels carry). Two ways on from the inflated rows:

- the layouts a camera or renderer writes (8-bit RGB, 8- or 16-bit grey, not
  interlaced) whose rows use the filters None, Sub or Up (OpenCV's default writer):
  the filters are undone in numpy, exactly as PNG defines them;
- anything else (Average or Paeth rows, palettes, interlacing...): the same PNG with its
  image data stored uncompressed is handed to OpenCV, whose libpng then only unfilters.

Both give the same pixels as OpenCV decoding the original file, to the bit (tested).
Without ``isal`` installed, :func:`inflate_rows` returns None and OpenCV decodes the
original file.

Why by hand: no maintained PNG decoder comes within 15% of this path on camera frames
(``benchmarks/png_decoders.py``, the decoders interleaved on the same rendered 1280 x 720
pairs, one thread, 2026-12-02): on 8-bit RGB colour pyspng (libspng) takes 1.44 times
as long, imagecodecs 1.58 and OpenCV's libpng 1.82; on 16-bit grey depth imagecodecs
2.08 and libpng 2.11, and pyspng does not give the depth image's pixels (it reads a
16-bit grey PNG as two channels). All of them inflate with zlib; ISA-L's inflate is
what this path has that they do not.
"""

from __future__ import annotations

import struct
import sys
import zlib
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..core.errors import UnreadableInputError

try:  # an optional speed-up: without it OpenCV decodes the file itself
    from isal import isal_zlib as _fast_zlib
except ImportError:  # pragma: no cover - isal is a dependency; the fallback is tested
    _fast_zlib = None

__all__ = ["PNG_SIGNATURE", "PngFile", "inflate_rows", "stored_png", "unfilter", "walk_png"]

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
#: Channels per pixel of each PNG colour type (grey, RGB, palette, grey+alpha, RGBA).
_CHANNELS = {0: 1, 2: 3, 3: 1, 4: 2, 6: 4}
#: The layouts :func:`unfilter` handles: (bit depth, colour type).
_PLAIN = frozenset({(8, 0), (8, 2), (16, 0)})
#: Deflate's stored blocks carry at most this many bytes each.
_STORED_BLOCK = 65535


@dataclass(frozen=True, eq=False)
class PngFile:
    """A PNG's header fields and where its image data lie, its chunks checked.

    Attributes
    ----------
    width, height, bit_depth, colour_type, interlace : int
        From IHDR.
    idat : tuple of (start, end)
        Byte ranges of the IDAT chunks' payloads, in order.
    where : str
        How messages name the file.
    """

    width: int
    height: int
    bit_depth: int
    colour_type: int
    interlace: int
    idat: tuple[tuple[int, int], ...]
    where: str

    @property
    def row_bytes(self) -> int:
        """Bytes of one unfiltered row (without its filter byte), not interlaced."""
        bits = self.width * _CHANNELS.get(self.colour_type, 1) * self.bit_depth
        return (bits + 7) // 8

    @property
    def bytes_per_pixel(self) -> int:
        """The byte distance the Sub filter looks back (at least 1)."""
        return max(_CHANNELS.get(self.colour_type, 1) * self.bit_depth // 8, 1)


def walk_png(buf: bytes, where: str) -> PngFile:
    """Walk a PNG's chunks: a file that ends before IEND or a critical chunk that fails
    its checksum is refused here, rather than by libpng (which prints its own lines
    before failing).

    Parameters
    ----------
    buf : bytes
        The whole file.
    where : str
        How messages name the file (``"colour image 'x.png'"``).

    Returns
    -------
    PngFile

    Raises
    ------
    UnreadableInputError
        No IHDR, a truncated file, or a critical chunk failing its CRC.
    """
    if len(buf) < 33 or buf[12:16] != b"IHDR":
        raise UnreadableInputError(f"{where} is a damaged PNG (no IHDR header)")
    width, height, depth, colour, _, _, interlace = struct.unpack(">IIBBBBB", buf[16:29])
    crc32 = _fast_zlib.crc32 if _fast_zlib is not None else zlib.crc32
    view = memoryview(buf)
    idat: list[tuple[int, int]] = []
    pos = len(PNG_SIGNATURE)
    while True:
        if pos + 12 > len(buf):
            raise UnreadableInputError(
                f"{where} is truncated: the PNG ends after {len(buf)} bytes, before its IEND"
            )
        (length,) = struct.unpack_from(">I", buf, pos)
        kind = buf[pos + 4 : pos + 8]
        end = pos + 12 + length
        if end > len(buf):
            raise UnreadableInputError(
                f"{where} is truncated: the PNG ends after {len(buf)} bytes, inside its "
                f"{kind.decode('latin-1')!r} chunk"
            )
        critical = not kind[0] & 0x20  # ancillary chunks have a lower-case first letter
        (crc,) = struct.unpack_from(">I", buf, end - 4)
        if critical and crc32(view[pos + 4 : end - 4]) != crc:
            raise UnreadableInputError(
                f"{where} is damaged: its PNG chunk {kind.decode('latin-1')!r} at byte {pos} "
                "fails its checksum"
            )
        if kind == b"IDAT":
            idat.append((pos + 8, end - 4))
        if kind == b"IEND":
            return PngFile(width, height, depth, colour, interlace, tuple(idat), where)
        pos = end


def inflate_rows(buf: bytes, png: PngFile) -> bytes | None:
    """The image data inflated: each row's filter byte and its filtered bytes.

    Returns
    -------
    bytes or None
        None when ``isal`` is not installed.

    Raises
    ------
    UnreadableInputError
        Image data that do not inflate, or inflate to more than the header allows.
    """
    if _fast_zlib is None:
        return None
    view = memoryview(buf)
    stream = b"".join(view[a:b] for a, b in png.idat)
    # interlacing adds at most one filter byte per pass row and a partial byte per pass
    limit = png.height * (png.row_bytes + 1) + 16 * (png.height + 8) + 64
    inflater = _fast_zlib.decompressobj()
    try:
        rows = inflater.decompress(stream, limit)
    except _fast_zlib.error as exc:
        raise UnreadableInputError(
            f"{png.where} is damaged: its image data do not inflate ({exc})"
        ) from None
    if inflater.unconsumed_tail:
        raise UnreadableInputError(
            f"{png.where} is damaged: its image data inflate to more than its "
            f"{png.width}x{png.height} header allows"
        )
    return rows


def unfilter(rows: bytes, png: PngFile) -> NDArray | None:
    """Undo the row filters of a plain layout whose rows use None, Sub or Up only.

    Parameters
    ----------
    rows : bytes
        From :func:`inflate_rows`.
    png : PngFile

    Returns
    -------
    ndarray or None
        uint8 (H, W) or (H, W, 3) in the file's channel order (RGB), or native-endian
        uint16 (H, W); None for any other layout, an interlaced file, rows that use the
        Average or Paeth filter, or data of the wrong length (OpenCV then decides).
    """
    if png.interlace or (png.bit_depth, png.colour_type) not in _PLAIN:
        return None
    stride = png.row_bytes + 1
    if len(rows) != png.height * stride:
        return None
    table = np.frombuffer(rows, np.uint8).reshape(png.height, stride)
    kinds = table[:, 0]
    if kinds.max(initial=0) > 2:
        return None
    bpp = png.bytes_per_pixel
    data = table[:, 1:].reshape(png.height, png.width, bpp)
    if png.bit_depth == 16 and sys.byteorder == "little":
        # the filters work on each byte alone, so the two bytes of a big-endian sample
        # are swapped on the way in, and the result is native uint16 as it comes out
        data = data[..., ::-1]
    if (kinds == 1).all():  # OpenCV's writer: every row Sub
        return _as_pixels(np.cumsum(data, axis=1, dtype=np.uint8), png)
    out = np.empty(data.shape, np.uint8)
    for r, kind in enumerate(kinds.tolist()):
        if kind == 1:  # Sub: a running sum along the row, per byte of the pixel
            np.cumsum(data[r], axis=0, dtype=np.uint8, out=out[r])
        elif kind == 2 and r:  # Up: the row above added
            np.add(data[r], out[r - 1], out=out[r])
        else:  # None, or Up on the first row (zeros above it)
            out[r] = data[r]
    return _as_pixels(out, png)


def _as_pixels(data: NDArray[np.uint8], png: PngFile) -> NDArray:
    """Unfiltered bytes (H, W, bytes per pixel), C-contiguous, as pixels (16-bit samples
    already in the machine's byte order)."""
    if png.bit_depth == 16:
        return data.view(np.uint16)[..., 0]
    return data[..., 0] if png.colour_type == 0 else data


def stored_png(buf: bytes, png: PngFile, rows: bytes) -> bytearray:
    """The same PNG with its image data in one IDAT chunk of stored (uncompressed)
    deflate blocks: libpng then only copies and unfilters.

    Parameters
    ----------
    buf : bytes
        The original file.
    png : PngFile
    rows : bytes
        From :func:`inflate_rows`.

    Returns
    -------
    bytearray
    """
    assert _fast_zlib is not None  # rows come from inflate_rows
    first, last = png.idat[0][0] - 8, png.idat[-1][1] + 4
    n = len(rows)
    blocks = max(-(-n // _STORED_BLOCK), 1)
    payload = 2 + 5 * blocks + n + 4
    out = bytearray(first + 12 + payload + len(buf) - last)
    out[:first] = buf[:first]
    struct.pack_into(">I", out, first, payload)
    out[first + 4 : first + 8] = b"IDAT"
    pos = first + 8
    out[pos : pos + 2] = b"\x78\x01"  # deflate, 32 KiB window, no preset dictionary
    pos += 2
    view = memoryview(rows)
    for k in range(blocks):
        block = view[k * _STORED_BLOCK : (k + 1) * _STORED_BLOCK]
        size = len(block)
        struct.pack_into("<BHH", out, pos, int(k == blocks - 1), size, size ^ 0xFFFF)
        out[pos + 5 : pos + 5 + size] = block
        pos += 5 + size
    struct.pack_into(">I", out, pos, _fast_zlib.adler32(rows))
    pos += 4
    crc = _fast_zlib.crc32(memoryview(out)[first + 4 : pos])
    struct.pack_into(">I", out, pos, crc)
    out[pos + 4 :] = buf[last:]
    return out
