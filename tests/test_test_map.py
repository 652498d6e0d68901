"""tests/README.md's table names every module of the package, and only test files that
exist (issue 42: a maintainer changing a module finds its tests there)."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
ROW = re.compile(r"^\| `(dgli_vision/[^`]+\.py)` \| ([^|]*) \| ([^|]*) \|$")


def _rows() -> dict[str, set[str]]:
    rows: dict[str, set[str]] = {}
    for line in (ROOT / "tests" / "README.md").read_text().splitlines():
        m = ROW.match(line)
        if m:
            named = re.findall(r"\btest_\w+\.py\b", m.group(2) + m.group(3))
            rows[m.group(1)] = set(named)
    return rows


def test_every_module_of_the_package_has_a_row_naming_test_files_that_exist():
    rows = _rows()
    modules = {p.relative_to(ROOT).as_posix() for p in (ROOT / "dgli_vision").rglob("*.py")}
    no_row = sorted(modules - set(rows))
    assert not no_row, f"modules missing from tests/README.md (scripts/test_map.py): {no_row}"
    gone = sorted(set(rows) - modules)
    assert not gone, f"rows of tests/README.md for modules that are gone: {gone}"
    named = set().union(*rows.values())
    missing = {n for n in named if not (ROOT / "tests" / n).is_file()}
    assert not missing, f"tests/README.md names test files that do not exist: {missing}"
