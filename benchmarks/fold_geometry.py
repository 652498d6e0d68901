"""How precise the fold geometry is (legs, tips, insets, offsets) against the simulator's
truth, and how long it takes (the figures of docs/folds.md).

Usage: python benchmarks/fold_geometry.py FOLDER [FOLDER ...] [--json OUT.json]
       [--markdown OUT.md] [--repeat N]

Each FOLDER is a set rendered by ``dgli render`` (its ``truth.json`` holds every fold's
true crease, ``state_params.creases_mm``). Every pair is classified; for each fold of a
verdict that names the true state, the measured sizes are compared with the sizes of the
true crease (:func:`dgli_vision.core.fold_measure.fold_measures`):

- length errors: each leg (mm), the tip (distance, mm), the inset and the offset (mm);
- angle errors: skew and turn (degrees);
- coverage: the share of values whose error is within twice the reported sd;
- null: the share of folds with no sizes (and why);
- per class: the share of its folds given sizes, and of those from the napkin's outline
  (``geometry_from`` ``"outline"``: half and diagonal folds, flaps under) rather than the
  stickers, with their length errors.

The time of the geometry alone (:func:`dgli_vision.classifier.fold_geometry.fit_folds`
on the frame's observation, the best of ``--repeat`` runs) is given per frame.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from collections import Counter, defaultdict
from pathlib import Path
from typing import Any

import numpy as np

from dgli_vision.classifier.affordances import _plan
from dgli_vision.classifier.fold_geometry import fit_folds
from dgli_vision.classifier.pipeline import classify_frame
from dgli_vision.classifier.references import load_references
from dgli_vision.core.fold_measure import Crease, fold_measures
from dgli_vision.core.layout import layout_of_size
from dgli_vision.sources.frames import read_frame


def _errors(
    word: str, got: dict[str, Any], truth: dict[str, Any]
) -> list[tuple[str, float, float | None]]:
    """(quantity, error, sd) of every value of one fold measured (None sd: not given)."""
    out = []
    for key, want in truth.items():
        have = got.get(key)
        sd_key = key.replace("_mm", "_sd_mm").replace("_deg", "_sd_deg")
        sd = got.get(sd_key)
        if have is None:
            continue
        if key == "legs_mm":
            for edge, w in want.items():
                if have.get(edge) is not None and w is not None:
                    out.append(("leg", have[edge] - w, (sd or {}).get(edge)))
        elif key == "tip_mm":
            out.append(("tip", math.dist(have, want), sd))
        else:
            name = key.split("_")[0]
            out.append((name, have - want, sd))
    return out


def measure(folder: Path, references, repeat: int) -> dict[str, Any]:
    """Every pair of one rendered folder: its fold errors and timings."""
    truth = json.loads((folder / "truth.json").read_text())["images"]
    layout = layout_of_size(references.napkin_mm)
    rows, times, nulls, skipped, folds = [], [], Counter(), Counter(), []
    for name, t in truth.items():
        creases = (t.get("state_params") or {}).get("creases_mm") or {}
        if not creases:
            continue
        frame = read_frame(folder / t["color"], folder / t["depth"])
        result = classify_frame(frame, references, layout=layout)
        p = result.prediction
        if p is None or (p.class_id, p.variant) != (t["class"], t["variant"]):
            why = "cannot tell the state" if p is None else "verdict not the true state"
            skipped[why] += 1
            # (its folds are not compared: counted apart, per class)
            folds += [{"pair": name, "class": t["class"], "fold": w, "from": None,
                       "why": why, "untold": True} for w in creases]
            continue
        obs = result.observation
        plan = _plan(p.class_id, p.variant, layout)
        best = math.inf
        for _ in range(repeat):
            t0 = time.perf_counter()
            fit_folds(obs, plan.folds, plan.sticker_part, layout)
            best = min(best, time.perf_counter() - t0)
        times.append(best * 1e3)
        for f in p.folds:
            g = f.geometry
            if f.fold not in creases or g is None:
                continue
            want = fold_measures(f.fold, Crease.through(*creases[f.fold]), layout)
            got = g.to_json()
            folds.append({"pair": name, "class": t["class"], "fold": f.fold,
                          "from": None if g.why is not None else g.source, "why": g.why,
                          "untold": False})
            if g.why is not None:
                nulls[g.why] += 1
                continue
            for q, err, sd in _errors(f.fold, got, want):
                rows.append({"pair": name, "class": t["class"], "fold": f.fold, "q": q,
                             "err": err, "sd": sd, "from": g.source})
    return {"rows": rows, "times_ms": times, "nulls": dict(nulls), "skipped": dict(skipped),
            "folds": folds}


def class_table(folds: list[dict[str, Any]], rows: list[dict[str, Any]]) -> list[str]:
    """Per class: the folds rendered, those of pairs whose state was not told (or told
    as another), of the others those given sizes and those from the outline, and the
    length errors (median / p90 / max, mm) and coverage of each source."""
    lines = ["| class | folds rendered | state not told (or another) | given sizes "
             "(of the folds of right verdicts) | from the outline | outline: length median "
             "/ p90 / max (mm), within 2 sd | stickers: length median / p90 (mm) |",
             "|---|---|---|---|---|---|---|"]
    for cid in sorted({f["class"] for f in folds}):
        rendered = [f for f in folds if f["class"] == cid]
        mine = [f for f in rendered if not f["untold"]]
        if not mine:
            continue
        given = sum(f["from"] is not None for f in mine)
        outline = sum(f["from"] == "outline" for f in mine)
        o = summary([r for r in rows if r["class"] == cid and r["from"] == "outline"])
        st = summary([r for r in rows if r["class"] == cid and r["from"] == "stickers"])
        def f(v: Any) -> str:
            return "-" if v is None else f"{v:g}"

        lines.append(
            f"| {cid} | {len(rendered)} | {len(rendered) - len(mine)} | "
            f"{given} of {len(mine)} ({given / len(mine):.0%}) | {outline} | "
            f"{f(o['median_mm'])} / {f(o['p90_mm'])} / {f(o['max_mm'])}, "
            f"{f(o['coverage_2sd'])} | {f(st['median_mm'])} / {f(st['p90_mm'])} |"
        )
    return lines


def summary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Median and 90th percentile of the length errors, the angles' too, and coverage."""
    lengths = [abs(r["err"]) for r in rows if r["q"] in ("leg", "tip", "inset", "offset")]
    angles = [abs(r["err"]) for r in rows if r["q"] in ("skew", "turn")]
    with_sd = [r for r in rows if r["sd"] is not None]
    covered = [abs(r["err"]) <= 2.0 * r["sd"] for r in with_sd]

    def q(v: list[float], p: float) -> float | None:
        return round(float(np.quantile(v, p)), 2) if v else None

    return {
        "n_lengths": len(lengths),
        "median_mm": q(lengths, 0.5),
        "p90_mm": q(lengths, 0.9),
        "max_mm": q(lengths, 1.0),
        "n_angles": len(angles),
        "median_deg": q(angles, 0.5),
        "p90_deg": q(angles, 0.9),
        "coverage_2sd": round(float(np.mean(covered)), 3) if covered else None,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("folders", nargs="+", type=Path)
    ap.add_argument("--json", type=Path)
    ap.add_argument("--markdown", type=Path)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--references", type=Path)
    args = ap.parse_args()
    refs = load_references(args.references)
    report: dict[str, Any] = {}
    lines = [
        "| set | folds measured | null | length median / p90 / max (mm) "
        "| angle median / p90 (deg) | within 2 sd | geometry ms/frame (median / max) |",
        "|---|---|---|---|---|---|---|",
    ]
    per_class: dict[str, list] = defaultdict(list)
    for folder in args.folders:
        m = measure(folder, refs, args.repeat)
        s = summary(m["rows"])
        t = m["times_ms"]
        s.update(nulls=m["nulls"], skipped=m["skipped"],
                 ms_median=round(float(np.median(t)), 3) if t else None,
                 ms_max=round(float(np.max(t)), 3) if t else None, frames=len(t))
        report[folder.name] = {**s, "rows": m["rows"], "folds": m["folds"]}
        for r in m["rows"]:
            per_class[r["class"]].append(r)
        n_null = sum(m["nulls"].values())
        lines.append(
            f"| {folder.name} | {len({(r['pair'], r['fold']) for r in m['rows']})} | {n_null} | "
            f"{s['median_mm']} / {s['p90_mm']} / {s['max_mm']} | "
            f"{s['median_deg']} / {s['p90_deg']} | "
            f"{s['coverage_2sd']} | {s['ms_median']} / {s['ms_max']} |"
        )
    lines += ["", "| class | values | length median / p90 (mm) | within 2 sd |",
              "|---|---|---|---|"]
    report["per_class"] = {}
    for cid in sorted(per_class):
        s = summary(per_class[cid])
        report["per_class"][cid] = s
        lines.append(f"| {cid} | {s['n_lengths']} | {s['median_mm']} / {s['p90_mm']} | "
                     f"{s['coverage_2sd']} |")
    all_folds = [f for name in args.folders for f in report[name.name]["folds"]]
    all_rows = [r for name in args.folders for r in report[name.name]["rows"]]
    lines += ["", *class_table(all_folds, all_rows)]
    text = "\n".join(lines)
    print(text)
    pooled = [r for name, s in report.items() if name != "per_class" for r in s["rows"]]
    if len(args.folders) > 1:
        report["all"] = summary(pooled)
        print("all:", report["all"])
    for name, s in report.items():
        if name not in ("per_class", "all"):
            print(name, "null:", s["nulls"], "skipped:", s["skipped"])
    if args.json:
        args.json.write_text(json.dumps(report, indent=1))
    if args.markdown:
        args.markdown.write_text(text + "\n")


if __name__ == "__main__":
    main()
