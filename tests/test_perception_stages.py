"""The stage order perception/__init__ documents is the order of its imports: a module
imports only from its own or earlier stages (and from core), never from a later one."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PERCEPTION = Path(__file__).resolve().parents[1] / "dgli_vision" / "perception"

#: Each module's stage (perception/__init__'s list). 0: helpers of any stage, which
#: import no other perception module (the rigid fit, the parameters tree); 6: the
#: frame's whole path (observe, which runs every stage) and tools beside it (calibration).
STAGES = {
    "rigid": 0,
    "params": 0,
    "napkin": 1,
    "regions": 1,
    "detections": 2,
    "labels": 2,
    "blobs": 2,
    "washed": 2,
    "detect": 2,
    "lift": 3,
    "scale": 3,
    "evidence": 4,
    "partial": 4,
    "agreement": 4,
    "flaps": 5,
    "shade": 5,
    "footprint": 5,
    "handedness": 5,
    "tips": 5,
    "calibrate": 6,
    "lens": 6,
    "observe": 6,
}


def _imported(path: Path) -> set[str]:
    """The perception modules ``path`` imports (relative imports of one dot), anywhere
    in it (an import inside a function counts)."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.level == 1:
            if node.module:
                out.add(node.module.split(".")[0])
            else:  # from . import x
                out.update(a.name for a in node.names)
    return out


def test_every_module_has_a_stage():
    modules = {p.stem for p in PERCEPTION.glob("*.py")} - {"__init__"}
    assert modules == set(STAGES)


@pytest.mark.parametrize("module", sorted(STAGES))
def test_a_module_imports_no_later_stage(module):
    later = {
        m for m in _imported(PERCEPTION / f"{module}.py") if STAGES[m] > STAGES[module]
    }
    assert not later, f"{module} (stage {STAGES[module]}) imports {sorted(later)}"


def test_a_helper_imports_no_stage():
    helpers = [m for m, s in STAGES.items() if s == 0]
    for module in helpers:
        assert not _imported(PERCEPTION / f"{module}.py"), module
