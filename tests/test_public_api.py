"""The public API stays where users import it, whatever folder its code lives in."""

from __future__ import annotations

import importlib

import numpy as np
import pytest

PUBLIC = [
    ("dgli_vision", "classify_pair"),
    ("dgli_vision", "plan"),
    ("dgli_vision", "verify"),
    ("dgli_vision.dgli", "gli"),
    ("dgli_vision.dgli", "dgli"),
    ("dgli_vision.dgli", "cloth_coordinates"),
    ("dgli_vision.distance", "spearman_distance"),
    ("dgli_vision.camera", "Intrinsics"),
    ("dgli_vision.cli", "main"),
    ("dgli_vision.cli", "classify_main"),
]


@pytest.mark.parametrize(("module", "name"), PUBLIC)
def test_the_documented_import_paths_work(module: str, name: str) -> None:
    assert callable(getattr(importlib.import_module(module), name))


def test_the_public_paths_are_the_library_itself() -> None:
    import dgli_vision.camera
    import dgli_vision.core.camera
    import dgli_vision.core.dgli
    import dgli_vision.core.distance
    import dgli_vision.dgli
    import dgli_vision.distance

    for public, core in (
        (dgli_vision.dgli, dgli_vision.core.dgli),
        (dgli_vision.distance, dgli_vision.core.distance),
        (dgli_vision.camera, dgli_vision.core.camera),
    ):
        assert public.__all__ == core.__all__
        for name in core.__all__:
            assert getattr(public, name) is getattr(core, name)
    segs = np.array([[[0, 0, 0], [1, 0, 0]], [[0, 1, 0.2], [0, 0.2, 1]]], dtype=float)
    assert dgli_vision.dgli.cloth_coordinates(segs).shape == (1,)
    assert dgli_vision.distance.spearman_distance(np.arange(5.0), np.arange(5.0)) == 0.0


def test_no_folder_imports_from_a_folder_above_it() -> None:
    """The layering of docs/architecture.md: no import circle between folders."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
    try:
        import architecture
    finally:
        sys.path.pop(0)
    files, deps = architecture.read_package()
    floor = architecture.floors(deps, sorted(files))
    climbs = [(a, b) for a in deps for b in deps[a] if floor[b] >= floor[a]]
    assert climbs == []
    assert floor["core"] == 0 and floor["cli"] == max(floor.values())

