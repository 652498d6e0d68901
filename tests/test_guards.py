"""The suite's own guards (tests/guards.py): a missing optional extra skips its tests
with the reason, and fails them in CI; a cached render is read-only."""

from __future__ import annotations

import importlib.metadata
import sys
from dataclasses import dataclass

import numpy as np
import pytest
from guards import EXTRAS, read_only, require_extra

MISSING = "dgli_no_such_module"


@pytest.fixture
def blocked(monkeypatch):
    """``import dgli_no_such_module`` fails (None in sys.modules: an ImportError)."""
    monkeypatch.setitem(sys.modules, MISSING, None)


@pytest.mark.parametrize("ci", [None, "false", "1"])
def test_a_missing_extra_skips_with_the_extra_named_outside_ci(blocked, monkeypatch, ci):
    if ci is None:
        monkeypatch.delenv("CI", raising=False)
    else:
        monkeypatch.setenv("CI", ci)
    with pytest.raises(pytest.skip.Exception) as info:
        require_extra(MISSING, "recordings")
    msg = str(info.value)
    assert msg.startswith(f"{MISSING} is missing (")
    assert "the 'recordings' extra, pip install '.[recordings]'" in msg


def test_a_missing_extra_fails_in_ci(blocked, monkeypatch):
    monkeypatch.setenv("CI", "true")
    with pytest.raises(pytest.fail.Exception, match=r"'realsense' extra.*CI must install"):
        require_extra(MISSING, "realsense")


def test_a_present_extra_is_imported_and_returned(monkeypatch):
    monkeypatch.setenv("CI", "true")
    assert require_extra("json", "none") is sys.modules["json"]


def test_the_extras_are_those_the_package_installs_the_modules_with():
    requires = importlib.metadata.requires("dgli_vision")
    for module, extra in EXTRAS.items():
        assert any(
            r.startswith(module) and r.endswith(f'extra == "{extra}"') for r in requires
        ), (module, extra, requires)


def test_read_only_reaches_every_array_of_a_sample():
    @dataclass(frozen=True)
    class Inner:
        points: np.ndarray

    @dataclass(frozen=True)
    class Sample:
        color: np.ndarray
        inner: Inner
        info: dict

    s = Sample(np.zeros(3), Inner(np.zeros(2)), {"mask": [np.zeros(1)], "n": 3})
    read_only(s)
    for a in (s.color, s.inner.points, s.info["mask"][0]):
        with pytest.raises(ValueError, match="read-only"):
            a[0] = 1
