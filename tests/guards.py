"""Guards of the suite: an optional extra that must be there, and cached renders that
tests share, made read-only.

``require_extra("rosbags")`` imports a module of an optional extra (``pyproject.toml``)
and returns it. Where it is missing the test is skipped with the reason, except in CI
(the environment variable ``CI`` is ``true``): CI installs every extra, so a missing
one there is a failure, not tens of silent skips.
"""

from __future__ import annotations

import dataclasses
import importlib
import os
from types import ModuleType

import numpy as np
import pytest

#: The optional extra (``pip install '.[EXTRA]'``) each module comes with.
EXTRAS = {"rosbags": "recordings", "pyrealsense2": "realsense"}


def require_extra(module: str, extra: str | None = None) -> ModuleType:
    """Import ``module`` of an optional extra, or skip (fail in CI) saying which.

    Parameters
    ----------
    module : str
        ``"rosbags"``, ``"pyrealsense2"``.
    extra : str, optional
        The extra that installs it (default: from :data:`EXTRAS`).

    Returns
    -------
    module
        The imported module.
    """
    extra = extra or EXTRAS[module]
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        missing = str(exc)
    reason = (
        f"{module} is missing ({missing}): the '{extra}' extra, "
        f"pip install '.[{extra}]' (scripts/setup.sh --test installs it)"
    )
    if os.environ.get("CI") == "true":
        pytest.fail(f"{reason}; CI must install every extra", pytrace=False)
    pytest.skip(reason, allow_module_level=True)


def read_only(obj: object, seen: set[int] | None = None) -> None:
    """Make every array in ``obj`` (its dataclass fields, dicts, lists and tuples, all
    the way down) read-only: a cached render that tests share then fails loudly where a
    test, or the code under test, writes into it."""
    seen = set() if seen is None else seen
    if id(obj) in seen:
        return
    seen.add(id(obj))
    if isinstance(obj, np.ndarray):
        obj.flags.writeable = False
    elif dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        for f in dataclasses.fields(obj):
            read_only(getattr(obj, f.name), seen)
    elif isinstance(obj, dict):
        for v in obj.values():
            read_only(v, seen)
    elif isinstance(obj, (list, tuple)):
        for v in obj:
            read_only(v, seen)
