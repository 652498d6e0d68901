"""The PNG decoders side by side on camera frames (issue 51, item 11): the package's own
path (:mod:`dgli_vision.sources.png_decode`: ISA-L's inflate, rows unfiltered in numpy),
OpenCV's libpng, and the maintained decoders imagecodecs and pyspng (libspng), each on
the same files' bytes, interleaved, one thread, best and median of ``--repeats`` rounds.

Every decoder's pixels are checked against OpenCV's first (a decoder that differs is
reported, not timed). The result is a ratio to the package's own path, the anchor:
``ratio <= 1.15`` is "within 15% of today's speed", the bar a maintained decoder must
clear to replace the hand-written one (docs: sources/png_decode.py's module note).

    python benchmarks/png_decoders.py [--frames 8] [--repeats 7] [--markdown FILE]

The frames are rendered with a seed (``dgli render --per-class``), colour (8-bit RGB)
and depth (16-bit grey) as a camera or ``dgli render`` writes them.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def _frames(count: int, seed: int) -> list[tuple[str, bytes]]:
    """``count`` rendered pairs' PNG files as (kind, bytes)."""
    from click.testing import CliRunner

    from dgli_vision.cli import main

    out = Path(tempfile.mkdtemp(prefix="png-bench-"))
    per_class = max(1, -(-count // 12))
    r = CliRunner().invoke(main, ["render", str(out), "--per-class", str(per_class),
                                  "--seed", str(seed), "-j", "1"])
    if r.exit_code != 0:
        raise SystemExit(r.output)
    files = []
    for c in sorted(out.glob("*_color.png"))[:count]:
        files.append(("colour", c.read_bytes()))
        files.append(("depth", c.with_name(c.name.replace("_color", "_depth")).read_bytes()))
    return files


def _ours(kind: str, data: bytes) -> np.ndarray:
    from dgli_vision.sources.frames import _decode_as, _EncodedImage, _header

    image = _EncodedImage(data, *_header(data, "bench"))
    import cv2

    flag = cv2.IMREAD_COLOR_RGB if kind == "colour" else None
    return _decode_as(image, Path("bench"), kind, flag)


def _opencv(kind: str, data: bytes) -> np.ndarray:
    import cv2

    flag = cv2.IMREAD_COLOR_RGB if kind == "colour" else cv2.IMREAD_UNCHANGED
    return cv2.imdecode(np.frombuffer(data, np.uint8), flag)


def _decoders() -> dict[str, Callable[[str, bytes], np.ndarray]]:
    out: dict[str, Callable[[str, bytes], np.ndarray]] = {
        "dgli_vision (ISA-L + numpy)": _ours, "OpenCV (libpng)": _opencv,
    }
    try:
        import imagecodecs

        out["imagecodecs"] = lambda kind, data: imagecodecs.png_decode(data)
    except ImportError:
        pass
    try:
        import pyspng

        out["pyspng (libspng)"] = lambda kind, data: pyspng.load(data)
    except ImportError:
        pass
    return out


def run(frames: int = 8, repeats: int = 7, seed: int = 5151) -> list[dict]:
    """Each decoder's time per image of each kind (colour, depth), ms, and its ratio to
    ours; a decoder whose pixels differ from OpenCV's on a kind is not timed on it."""
    import cv2

    cv2.setNumThreads(1)
    files = _frames(frames, seed)
    decoders = _decoders()
    rows = []
    for kind in ("colour", "depth"):
        mine = [d for k, d in files if k == kind]
        truth = [_opencv(kind, d) for d in mine]
        ok = {
            name: all(np.array_equal(fn(kind, d), t) for d, t in zip(mine, truth))
            for name, fn in decoders.items()
        }
        times: dict[str, list[float]] = {n: [] for n in decoders if ok[n]}
        for _ in range(repeats):  # interleaved: the machine's drift is shared
            for name in times:
                fn = decoders[name]
                t0 = time.perf_counter()
                for d in mine:
                    fn(kind, d)
                times[name].append((time.perf_counter() - t0) / len(mine) * 1e3)
        anchor = statistics.median(times["dgli_vision (ISA-L + numpy)"])
        for name in decoders:
            row = {"kind": kind, "decoder": name, "same_pixels": ok[name]}
            if ok[name]:
                med = statistics.median(times[name])
                row.update(best_ms=min(times[name]), median_ms=med, ratio=med / anchor)
            rows.append(row)
    return rows


def markdown(rows: list[dict], frames: int) -> str:
    lines = [f"PNG decoding of {frames} rendered 1280 x 720 pairs, one thread, per image; "
             "ratio: the median against dgli_vision's own path on the same images", "",
             "| image | decoder | same pixels as OpenCV | best ms | median ms | ratio |",
             "|---|---|---|---|---|---|"]
    for r in rows:
        kind = "colour (8-bit RGB)" if r["kind"] == "colour" else "depth (16-bit grey)"
        if not r["same_pixels"]:
            lines.append(f"| {kind} | {r['decoder']} | no | - | - | - |")
            continue
        lines.append(f"| {kind} | {r['decoder']} | yes | {r['best_ms']:.1f} | "
                     f"{r['median_ms']:.1f} | {r['ratio']:.2f} |")
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, default=8)
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--markdown")
    args = ap.parse_args()
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    rows = run(args.frames, args.repeats)
    text = markdown(rows, args.frames)
    print(text, end="")
    if args.markdown:
        Path(args.markdown).write_text(text)


if __name__ == "__main__":
    main()
