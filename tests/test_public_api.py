"""The public API stays where users import it, whatever folder its code lives in."""

from __future__ import annotations

import importlib

import numpy as np
import pytest

PUBLIC = [
    ("dgli_vision", "classify_pair"),
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


def test_the_public_paths_are_the_library_not_copies() -> None:
    from dgli_vision.camera import Intrinsics
    from dgli_vision.dgli import cloth_coordinates
    from dgli_vision.distance import spearman_distance
    from dgli_vision.pipeline import classify_frame  # noqa: F401  (its own path works)

    segs = np.array([[[0, 0, 0], [1, 0, 0]], [[0, 1, 0.2], [0, 0.2, 1]]], dtype=float)
    assert cloth_coordinates(segs).shape == (1,)
    assert spearman_distance(np.arange(5.0), np.arange(5.0)) == pytest.approx(0.0)
    assert Intrinsics(640, 480, 500.0, 500.0, 319.5, 239.5).width == 640
