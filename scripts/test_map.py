"""Print the table of tests/README.md: each module of the package and the test files that
exercise it.

A test file exercises a module when it imports it (at the top or inside a test), or runs
the command that lives in it (``main`` with CliRunner, ``python -m dgli_vision``, a
subprocess of ``dgli``): ``["evaluate", ...]`` counts for ``cli/evaluate.py``. A module no
test file imports gets the test files of the package modules that import it ("through").
The helpers of the suite (render_cache.py, cli_runs.py, ...) count for the test files
that use them.

Usage: ``python scripts/test_map.py`` prints the table; ``python scripts/test_map.py
--write`` puts it in place of the one in tests/README.md. tests/test_test_map.py checks
that every module has a row.
"""

from __future__ import annotations

import ast
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PKG = ROOT / "dgli_vision"
TESTS = ROOT / "tests"

#: command name -> the module under cli/ that defines it
COMMANDS = {
    "bench": "bench", "calibrate": "calibrate", "classify": "classify",
    "compare": "compare", "sequence": "compare", "coords": "napkin", "stickers": "napkin",
    "evaluate": "evaluate", "extract": "extract", "label": "label", "plan": "plan",
    "references": "references", "render": "render", "robustness": "robustness",
    "simulate": "simulate", "track": "track", "verify": "verify", "watch": "watch",
    "write-recording": "write_recording",
}  # fmt: skip


#: test files found by reading them, beyond their imports (checked by hand)
BY_HAND = {
    # sheen renders, whose washed-out stickers it finds, classified right or cannot-tell
    "dgli_vision.perception.washed": {"test_conditions_new.py", "test_confident_wrong.py"},
    # the lock, journal, stop signals and --resume of the long runs
    "dgli_vision.cli.runs": {
        "test_edges.py",
        "test_label_edges.py",
        "test_run_integrity.py",
        "test_second_run.py",
    },
}


def package_modules() -> list[str]:
    """Dotted names of every module of the package (``dgli_vision.core.io``, ...)."""
    names = []
    for path in sorted(PKG.rglob("*.py")):
        parts = path.relative_to(ROOT).with_suffix("").parts
        names.append(".".join(parts[:-1] if parts[-1] == "__init__" else parts))
    return names


def module_path(name: str) -> str:
    """``dgli_vision.core.io`` -> ``dgli_vision/core/io.py`` (a package: its __init__)."""
    p = ROOT / Path(*name.split("."))
    return (p / "__init__.py" if p.is_dir() else p.with_suffix(".py")).relative_to(ROOT).as_posix()


def imported(tree: ast.AST, here: str, known: set[str]) -> set[str]:
    """Package modules ``tree`` imports (``here``: its own dotted package, for relative
    imports)."""
    found: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            bases = [a.name for a in node.names]
            names: list[str] = []
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                up = here.split(".")[: len(here.split(".")) - node.level + 1]
                base = ".".join([*up, base] if base else up)
            bases, names = [base], [a.name for a in node.names]
        else:
            continue
        for base in bases:
            for cand in [base, *(f"{base}.{n}" for n in names)]:
                while cand and cand not in known:
                    cand = cand.rpartition(".")[0]
                if cand.startswith("dgli_vision"):
                    found.add(cand)
    return found


def commands(tree: ast.AST) -> set[str]:
    """cli modules whose command a list literal starts with (``["render", ...]``,
    ``[*DGLI, "render", ...]``, ``[sys.executable, "-m", "dgli_vision", "render"]``)."""
    found = set()
    for node in ast.walk(tree):
        if not isinstance(node, ast.List):
            continue
        elts = [e for e in node.elts if not isinstance(e, ast.Starred)]
        strs = [
            e.value for e in elts[:4] if isinstance(e, ast.Constant) and isinstance(e.value, str)
        ]
        if "dgli_vision" in strs and "-m" in strs:  # python -m dgli_vision
            found.add("dgli_vision.__main__")
        for s in strs[:1] + strs[1:][: 3 if "dgli_vision" in strs else 0]:
            if s in COMMANDS:
                found.add(f"dgli_vision.cli.{COMMANDS[s]}")
    return found


def table() -> str:
    mods = package_modules()
    known = set(mods)
    # the package's own imports, to find the tests of a module imported only within it
    importers: dict[str, set[str]] = defaultdict(set)
    for m in mods:
        tree = ast.parse((ROOT / module_path(m)).read_text())
        here = m if module_path(m).endswith("__init__.py") else m.rpartition(".")[0]
        for dep in imported(tree, here, known) - {m}:
            importers[dep].add(m)
    helpers = {
        p.stem: imported(ast.parse(p.read_text()), "tests", known)
        | commands(ast.parse(p.read_text()))
        for p in TESTS.glob("*.py")
        if not p.name.startswith("test_") and p.name != "conftest.py"
    }
    direct: dict[str, set[str]] = defaultdict(set)
    for p in sorted(TESTS.glob("test_*.py")):
        tree = ast.parse(p.read_text())
        hit = imported(tree, "tests", known) | commands(tree)
        for helper, via in helpers.items():
            if f"import {helper}" in p.read_text() or f"from {helper} " in p.read_text():
                hit |= via
        if hit & {f"dgli_vision.cli.{c}" for c in COMMANDS.values()} or "dgli_vision.cli" in hit:
            hit |= {"dgli_vision.cli", "dgli_vision.cli.main", "dgli_vision.cli.errors"}
        for m in hit:
            direct[m].add(p.name)
    for m, names in BY_HAND.items():
        direct[m] |= names
    rows = ["| module | test files that import it or run its command | through |", "|---|---|---|"]
    for m in mods:
        through: set[str] = set()
        if not direct[m]:
            for up in importers[m]:
                through |= direct[up]
        rows.append(
            f"| `{module_path(m)}` | {', '.join(sorted(direct[m])) or '-'} | "
            f"{', '.join(sorted(through)) or ('-' if direct[m] else '(none)')} |"
        )
    return "\n".join(rows)


def write(readme: Path = TESTS / "README.md") -> None:
    """Replace the table in ``readme`` (from its ``| module |`` header to the first line
    that is not a table row) with :func:`table`."""
    lines = readme.read_text().splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("| module |"))
    end = start
    while end < len(lines) and lines[end].startswith("|"):
        end += 1
    lines[start:end] = table().splitlines()
    readme.write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    import sys

    if sys.argv[1:] == ["--write"]:
        write()
    else:
        print(table())
