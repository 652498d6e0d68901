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



def test_moved_names_are_still_found_where_they_were():
    """RGBDFrame lives in core and the cloth regions in stage 1 of perception; their old
    import paths name the same objects."""
    from dgli_vision.core.frame import RGBDFrame
    from dgli_vision.perception import footprint, regions
    from dgli_vision.sources.frames import RGBDFrame as old_frame

    assert old_frame is RGBDFrame
    for name in ("ClothRegions", "cloth_cells", "cloth_regions"):
        assert getattr(footprint, name) is getattr(regions, name)
    # the footprint's parameters are the regions' and its own: the same fields as before
    fields = footprint.FootprintParams(cell_px=4)
    assert (fields.cell_px, fields.close_cells, fields.table_margin) == (4, 7, 0.15)
    assert isinstance(fields, regions.RegionParams) and fields.max_fraction == 1.06
