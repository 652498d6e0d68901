"""The one JSON convention of dgli_vision's results.

Every result type that a command prints with ``--json`` (or keeps in a report's JSON
file) has a method ``to_json()`` that returns JSON-ready builtins: dicts with string
keys, lists, strings, numbers, booleans and None. :func:`json_ready` is what makes a
value so; ``json.dumps(result.to_json())`` is then strict JSON.
"""

from __future__ import annotations

import math
from typing import Any

__all__ = ["json_ready"]


def json_ready(value: Any) -> Any:
    """``value`` with every NaN or infinite float replaced by None (JSON's null), through
    dicts, lists and tuples (tuples become lists), numpy scalars as Python numbers:
    ``json.dumps`` would write NaN as a bare ``NaN``, which JSON readers other than
    Python's refuse, and refuses numpy's integers."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: json_ready(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_ready(v) for v in value]
    item = getattr(value, "item", None)  # a numpy scalar (np.int64, np.float32, np.bool_)
    if item is not None and getattr(value, "shape", None) == ():
        return json_ready(item())
    return value
