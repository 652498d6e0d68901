"""Running the command line in tests: in process (click's runner) or as a process of its
own, and the one error line a failed command leaves (shared by the tests of bad input)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def one_error_line(result, code: int = 2) -> str:
    """The one ``error:`` line of a failed command (other lines on stderr are notes)."""
    assert result.exit_code == code, result.output
    lines = [ln for ln in result.output.splitlines() if ln.startswith(("error:", "Error:"))]
    assert len(lines) == 1, result.output
    return lines[0]


def run_process(args: list[object], **kwargs) -> subprocess.CompletedProcess:
    """``python -m dgli_vision ARGS`` in a process of its own, from the repository;
    stderr captured unless told otherwise."""
    kwargs.setdefault("stderr", subprocess.PIPE)
    return subprocess.run(
        [sys.executable, "-m", "dgli_vision", *map(str, args)],
        cwd=ROOT,
        text=True,
        timeout=120,
        **kwargs,
    )
