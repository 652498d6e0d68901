"""Cost of the reports: `dgli evaluate` and `dgli track` with and without `--report`.

A report must cost time and memory linear in the pairs: this script measures wall time
and peak memory (the dgli process's maximum resident set) of the same run with and
without `--report`, on

- N pairs whose files are missing (every pair fails; the report lists them all), and
- M real pairs (hard links to the shipped sample pairs, so nothing is rendered), and
- `dgli track` on M real frames.

Run from the repository root:

    .venv/bin/python benchmarks/report_scaling.py [--missing 20000] [--real 2000] [-j 2]

It prints a Markdown table with the ratios (report / no report); the goal is 2x at most.
"""

from __future__ import annotations

import argparse
import csv
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SAMPLES = ROOT / "sample_images"


def missing_folder(root: Path, n: int) -> Path:
    folder = root / "missing"
    folder.mkdir()
    rows = ["color,depth,label,variant"]
    rows += [f"m{k:06d}_color.png,m{k:06d}_depth.png,01," for k in range(n)]
    (folder / "labels.csv").write_text("\n".join(rows) + "\n")
    return folder


def real_folder(root: Path, n: int) -> Path:
    folder = root / "real"
    folder.mkdir()
    with open(SAMPLES / "labels.csv", newline="") as fh:
        samples = list(csv.DictReader(fh))
    rows = ["color,depth,label,variant"]
    for k in range(n):
        s = samples[k % len(samples)]
        color, depth = f"r{k:06d}_color.png", f"r{k:06d}_depth.png"
        os.link(SAMPLES / s["color"], folder / color)
        os.link(SAMPLES / s["depth"], folder / depth)
        rows.append(f"{color},{depth},{s['label']},{s['variant']}")
    (folder / "labels.csv").write_text("\n".join(rows) + "\n")
    shutil.copy(SAMPLES / "intrinsics.json", folder / "intrinsics.json")
    return folder


def measure(args: list[str]) -> tuple[float, float, int]:
    """Wall seconds, peak resident memory (GB) of the dgli process, exit code."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    t0 = time.perf_counter()
    proc = subprocess.Popen(
        [sys.executable, "-m", "dgli_vision", *args],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        env=env,
    )
    _, status, usage = os.wait4(proc.pid, 0)
    seconds = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    err = proc.stderr.read().decode() if proc.stderr else ""
    if proc.returncode not in (0, 1, 2):
        raise SystemExit(f"dgli {' '.join(args)} failed ({proc.returncode}): {err[-400:]}")
    return seconds, usage.ru_maxrss / 1e6, proc.returncode  # ru_maxrss is in kB on Linux


def compare(name: str, base: list[str], report: Path) -> list[str]:
    plain = measure(base)
    with_report = measure([*base, "--report", str(report)])
    return [
        name,
        f"{plain[0]:.1f} s, {plain[1]:.2f} GB",
        f"{with_report[0]:.1f} s, {with_report[1]:.2f} GB",
        f"{with_report[0] / plain[0]:.2f}x",
        f"{with_report[1] / plain[1]:.2f}x",
    ]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--missing", type=int, default=20_000, help="pairs of missing files")
    parser.add_argument("--real", type=int, default=2_000, help="real pairs (and frames)")
    parser.add_argument("-j", "--jobs", type=int, default=2)
    opts = parser.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        jobs = ["-j", str(opts.jobs)]
        if opts.missing:
            folder = missing_folder(root, opts.missing)
            rows.append(
                compare(
                    f"evaluate, {opts.missing:,} missing pairs",
                    ["evaluate", str(folder), *jobs],
                    root / "r-missing",
                )
            )
        if opts.real:
            folder = real_folder(root, opts.real)
            rows.append(
                compare(
                    f"evaluate, {opts.real:,} real pairs",
                    ["evaluate", str(folder), *jobs],
                    root / "r-real",
                )
            )
            rows.append(
                compare(
                    f"track, {opts.real:,} real frames",
                    ["track", str(folder), *jobs],
                    root / "r-track",
                )
            )
    header = ["case", "without --report", "with --report", "time ratio", "memory ratio"]
    print("| " + " | ".join(header) + " |")
    print("|" + "---|" * len(header))
    for row in rows:
        print("| " + " | ".join(row) + " |")


if __name__ == "__main__":
    main()
