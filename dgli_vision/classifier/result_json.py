"""The JSON object of one classified frame (``dgli classify --json``, docs/json.md).

Kept beside the pipeline rather than in it: :meth:`FrameResult.to_json` calls
:func:`frame_result_json`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from ..core.json_ready import json_ready

if TYPE_CHECKING:
    from .pipeline import FrameResult

__all__ = ["frame_result_json"]


def frame_result_json(result: FrameResult, color: str, depth: str) -> dict[str, Any]:
    """The JSON object of ``dgli classify --json`` for one classified pair
    (:meth:`FrameResult.to_json`; its keys: docs/json.md)."""
    found = result.observation.visible
    p = result.prediction
    out: dict[str, Any] = {"color": color, "depth": depth}
    if p is None:
        guess = result.best_guess
        out.update(
            {
                "class": None,
                "name": None,
                "variant": None,
                "distance": None,
                "runner_up": None,
                "confidence": None if guess is None else guess.confidence,
                "reason": result.reason,
            }
        )
    else:
        ru = p.runner_up
        out.update(
            {
                "class": p.class_id,
                "name": p.name,
                "variant": p.variant,
                "distance": round(p.distance, 6),
                "confidence": p.confidence,
                "runner_up": None
                if ru is None
                else {
                    "class": ru.class_id,
                    "name": ru.name,
                    "variant": ru.variant,
                    "distance": round(ru.distance, 6),
                },
            }
        )
    unknown = result.observation.unknown
    evidence = result.observation.evidence
    out["stickers"] = {
        "found": int(found.sum()),
        "missing": np.flatnonzero(~found).tolist(),
        "unknown": {str(i): evidence.reasons[i] for i in np.flatnonzero(unknown)}
        if evidence is not None
        else {},
    }
    out["candidates"] = [
        {"class": c, "variant": v, "distance": d} for c, v, d in result.candidates
    ]
    if p is None:
        out["why"] = {
            "kind": result.why,
            "classes": [c for c, _, _ in result.candidates[:2]],
            "stickers": out["stickers"],
        }
    if result.affordances is not None:
        out.update(result.affordances.to_json())
    out["coordinates"] = [
        None if not np.isfinite(v) else round(float(v), 8) for v in result.coordinates
    ]
    return json_ready(out)
