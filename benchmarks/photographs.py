"""Per-pair table of ``dgli evaluate`` on path-traced sets, with each miss put down to the
detector or the classifier (the tables of benchmarks/PHOTOGRAPHS.md).

Usage: python benchmarks/photographs.py FOLDER:REPORT [FOLDER:REPORT ...] [--markdown OUT]

FOLDER is a set rendered by ``dgli render --engine cycles`` (its ``truth.json`` holds
every sticker's true camera-frame point and how much of it the camera sees); REPORT is
the folder ``dgli evaluate FOLDER --report REPORT`` wrote (its ``results.jsonl``). For
every pair: the truth, the answer, its confidence and reason, the stickers' true size in
pixels (``30 mm x fx / z``, the median and the smallest of those seen), how many of the
stickers seen (at least half of the disc) were found where they truly are (within half a
diameter), and what the scene drew (table, bar lamp, the napkin's distance and where it
lies in the frame).

A pair not answered right is put down to:

- ``beyond``: its stickers are under the 10 px floor (the tool says "cannot tell" with
  the size, rightly);
- ``detector``: a sticker the camera sees was missed or misplaced: ``misplaced`` when
  its identity was given to a blob farther than half a diameter from it, ``washed out``
  when it is the sticker the bar lamp's streak was aimed at or within 8 cm of it,
  ``pale`` when more than a fifth of the napkin's pixels clip (over-exposed),
  ``partial`` when less than 90 % of its disc is seen (cut by a fold), ``small`` under
  13 px, ``missed`` otherwise;
- ``classifier``: every sticker seen was found where it lies; the reason names the check
  or the doubt that withheld the answer.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np

from dgli_vision.classifier.capture_limits import MIN_STICKER_PX
from dgli_vision.core.layout import default_layout


def _pairs(folder: Path, report: Path) -> list[dict[str, Any]]:
    truth = json.loads((folder / "truth.json").read_text())
    intr = json.loads((folder / "intrinsics.json").read_text())
    m = intr["intrinsic_matrix"]  # Open3D's: column-major
    fx, fy, cx, cy = (float(m[k]) for k in (0, 4, 6, 7))
    disc = default_layout().disc_diameter_mm
    rows = []
    for line in (report / "results.jsonl").read_text().splitlines():
        res = json.loads(line)
        if "pair" not in res:
            continue
        name = Path(res["pair"]["color"]).name[: -len("_color.png")]
        t = truth["images"][name]
        pts = np.asarray(t["sticker_points_cam_m"], float)
        frac = np.asarray(t["visible_fraction"], float)
        seen = frac >= 0.5
        size = disc * fx / (pts[:, 2] * 1000.0)
        px = np.stack([fx * pts[:, 0] / pts[:, 2] + cx, fy * pts[:, 1] / pts[:, 2] + cy], 1)
        cents = np.asarray(
            [c if c is not None else (np.nan, np.nan) for c in res.get("centroids") or []],
            float,
        ).reshape(-1, 2)
        found = np.zeros(len(pts), bool)
        err = np.full(len(pts), np.nan)
        if len(cents) == len(pts):
            err = np.linalg.norm(cents - px, axis=1)
            found = np.isfinite(err) & (err < size / 2)
        look = t.get("render", {}).get("look", {})
        clipped = _clipped(folder / t["color"], px[np.isfinite(px).all(axis=1)])
        rows.append({
            "set": folder.name, "name": name, "truth": t["class"], "variant": t["variant"],
            "answer": res.get("predicted"), "confidence": res.get("confidence"),
            "reason": res.get("reason") or res.get("why") or "", "error": res.get("error"),
            "size_px": float(np.median(size[seen])) if seen.any() else float("nan"),
            "min_px": float(size[seen].min()) if seen.any() else float("nan"),
            "seen": int(seen.sum()), "found": int((found & seen).sum()),
            "missed": [int(k) for k in np.flatnonzero(seen & ~found)],
            "frac": frac, "pts": pts, "size": size, "err": err,
            "distance_m": t["camera"].get("distance_m"),
            "offset_px": t["camera"].get("offset_px"),
            "table": look.get("table", "matte"), "bar": look.get("bar_lamp", False),
            "bar_sticker": look.get("bar_sticker"), "clipped": clipped,
        })
    return rows


def _clipped(color_path: Path, sticker_px: np.ndarray) -> float:
    """Share of the napkin's pixels (the hull of its stickers' true centres) at 250 or
    more in a channel: how much of it auto exposure let clip."""
    import cv2

    img = cv2.imread(str(color_path), cv2.IMREAD_COLOR)
    if img is None or len(sticker_px) < 3:
        return float("nan")
    mask = np.zeros(img.shape[:2], np.uint8)
    cv2.fillConvexPoly(mask, cv2.convexHull(np.round(sticker_px).astype(np.int32)), 1)
    inside = mask.astype(bool)
    return float((img[inside].max(axis=1) >= 250).mean()) if inside.any() else float("nan")


def failure(row: dict[str, Any]) -> str:
    """What a pair not answered right is put down to (see the module's text)."""
    if row["answer"] == row["truth"]:
        return ""
    if row["size_px"] < MIN_STICKER_PX:
        return "beyond: stickers under 10 px"
    if row["missed"]:
        kinds: dict[str, list[str]] = {}
        for k in row["missed"]:
            b = row["bar_sticker"]
            near_bar = b is not None and np.linalg.norm(row["pts"][k] - row["pts"][b]) < 0.08
            if np.isfinite(row["err"][k]):
                kind, what = "misplaced", f"{k} ({row['err'][k]:.0f} px off)"
            elif near_bar and row["bar"]:
                kind, what = "washed out", str(k)
            elif row["clipped"] > 0.2:
                kind, what = "pale", str(k)
            elif row["frac"][k] < 0.9:
                kind, what = "partial", f"{k} ({row['frac'][k]:.0%} seen)"
            elif row["size"][k] < 13:
                kind, what = "small", f"{k} ({row['size'][k]:.0f} px)"
            else:
                kind, what = "missed", str(k)
            kinds.setdefault(kind, []).append(what)
        return "detector: " + "; ".join(f"{kind} {', '.join(v)}" for kind, v in kinds.items())
    return "classifier"


def markdown(rows: list[dict[str, Any]]) -> str:
    """The per-pair table and the breakdown."""
    out = ["| set | pair | truth | answer | conf | sticker px (min) | found/seen | "
           "table, lamp | distance, offset | napkin clipped | reason | put down to |",
           "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        answer = r["answer"] or ("error" if r["error"] else "cannot tell")
        conf = "" if r["confidence"] is None else f"{r['confidence']:.2f}"
        off = r["offset_px"] or [0, 0]
        reason = (r["error"] or r["reason"]).replace("|", "/")
        truth = r["truth"] + (f" {r['variant']}" if r["variant"] else "")
        out.append(
            f"| {r['set']} | {r['name']} | {truth} | {answer} | {conf} | "
            f"{r['size_px']:.1f} ({r['min_px']:.1f}) | "
            f"{r['found']}/{r['seen']} | {r['table']}{', bar' if r['bar'] else ''} | "
            f"{r['distance_m']:.2f} m, {np.hypot(*off):.0f} px | {r['clipped']:.0%} | "
            f"{reason} | {failure(r)} |"
        )
    n = len(rows)
    right = sum(r["answer"] == r["truth"] for r in rows)
    wrong = sum(r["answer"] is not None and r["answer"] != r["truth"] for r in rows)
    within = [r for r in rows if r["size_px"] >= MIN_STICKER_PX]
    w_right = sum(r["answer"] == r["truth"] for r in within)
    kinds: dict[str, int] = {}
    for r in rows:
        f = failure(r).split(":")[0]
        if f:
            kinds[f] = kinds.get(f, 0) + 1
    out += ["", f"**{right} of {n} right, {n - right - wrong} \"cannot tell\", {wrong} wrong**; "
            f"where the stickers are at least 10 px across {w_right} of {len(within)}.",
            "", "Not right, put down to: " + (", ".join(f"{k} {v}" for k, v in
                                                    sorted(kinds.items())) or "none") + "."]
    return "\n".join(out) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("sets", nargs="+", help="FOLDER:REPORT")
    ap.add_argument("--markdown", type=Path)
    args = ap.parse_args()
    rows = []
    for spec in args.sets:
        folder, report = spec.split(":")
        rows += _pairs(Path(folder), Path(report))
    text = markdown(rows)
    if args.markdown:
        args.markdown.write_text(text)
    print(text)


if __name__ == "__main__":
    main()
