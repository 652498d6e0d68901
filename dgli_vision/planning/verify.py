"""Did the fold work? The state after a fold and its geometry against what was planned.

A robot that has made a fold looks again: :func:`verify_fold` takes that frame's
verdict, the state it expected and, optionally, the fold's planned sizes (a corner's
legs or where its tip should land, a strip's or half fold's inset, a diagonal fold's
offset from its diagonal), and says whether
the fold succeeded: the expected state, and every planned size within the tolerance
(20 mm by default, the tolerance of the simulation benchmarks' per-point success is
45 mm). It fails with the reason (wrong state; crease 34 mm off; corner B 52 mm short of
its target), and cannot tell when the state or the sizes cannot be told (with why), or
when a size is within the tolerance by less than twice its uncertainty.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..core.classes import CORNERS, OUTSIDE
from ..core.errors import InvalidValueError
from ..core.fold_graph import StateKey, folds_of
from ..core.fold_measure import (
    Crease,
    crease_distance_mm,
    edge_name,
    fold_kind,
    fold_measures,
    planned_crease,
)
from ..core.layout import NapkinLayout
from ..core.why import OUTSIDE_KINDS

__all__ = ["DEFAULT_TOLERANCE_MM", "FoldCheck", "check_request", "parse_legs", "verify_fold"]

#: How far (mm) a planned size may be missed.
DEFAULT_TOLERANCE_MM = 20.0


@dataclass(frozen=True)
class FoldCheck:
    """The verdict on one fold.

    Attributes
    ----------
    success : bool or None
        True: the expected state, every planned size within tolerance; False: not (see
        ``reasons``); None: cannot tell.
    state, expect : StateKey or None
        The state seen (None: not told) and the one expected.
    fold : str or None
        The fold whose sizes were checked.
    errors : dict
        ``crease_mm`` (the largest distance of either crease's ends on the napkin from
        the other), ``legs_mm`` (edge -> measured minus planned), ``tip_mm`` (distance
        of the tip from its target), ``tip_short_mm`` (how far short of the target
        along the corner's way, negative beyond it), ``inset_mm``, ``skew_deg``,
        ``offset_mm``, ``turn_deg``.
    measured : dict or None
        The fold's geometry as measured (the keys of a verdict's fold).
    planned : dict or None
        The planned sizes (the same keys).
    reasons : list of str
        Why it failed or cannot be told; empty on success.
    tolerance_mm : float
    """

    success: bool | None
    state: StateKey | None
    expect: StateKey
    fold: str | None
    errors: dict[str, Any] = field(default_factory=dict)
    measured: dict[str, Any] | None = None
    planned: dict[str, Any] | None = None
    reasons: tuple[str, ...] = ()
    tolerance_mm: float = DEFAULT_TOLERANCE_MM

    @property
    def outcome(self) -> str:
        """``"success"``, ``"failed"`` or ``"cannot tell"``."""
        return {True: "success", False: "failed", None: "cannot tell"}[self.success]

    def line(self) -> str:
        """One readable line."""
        what = _name(self.expect)
        if self.success:
            told = "; ".join(_summary(self.errors)) or "no size planned"
            return f"success: {what} reached ({told}; tolerance {self.tolerance_mm:g} mm)"
        return f"{self.outcome}: " + "; ".join(self.reasons)

    def to_json(self) -> dict[str, Any]:
        """``{"outcome", "success", "state", "expect", "fold", "errors", "measured",
        "planned", "reasons", "tolerance_mm"}``."""
        return {
            "outcome": self.outcome,
            "success": self.success,
            "state": None if self.state is None else {"class": self.state[0],
                                                      "variant": self.state[1]},
            "expect": {"class": self.expect[0], "variant": self.expect[1]},
            "fold": self.fold,
            "errors": _round(self.errors),
            "measured": self.measured,
            "planned": _round(self.planned),
            "reasons": list(self.reasons),
            "tolerance_mm": self.tolerance_mm,
        }


def _round(v: Any) -> Any:
    if v is None:
        return None
    if isinstance(v, dict):
        return {k: _round(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_round(x) for x in v]
    if isinstance(v, float):
        return round(v, 1) if math.isfinite(v) else None
    return v


def _name(key: StateKey | None) -> str:
    if key is None:
        return "none"
    return f"{key[0]}/{key[1]}" if key[1] else key[0]


def _summary(errors: dict[str, Any]) -> list[str]:
    out = []
    if errors.get("crease_mm") is not None:
        out.append(f"crease {errors['crease_mm']:.0f} mm off")
    if errors.get("tip_mm") is not None:
        out.append(f"tip {errors['tip_mm']:.0f} mm from its target")
    for edge, e in (errors.get("legs_mm") or {}).items():
        if e is not None:
            out.append(f"leg {edge} {round(e):+d} mm")
    if errors.get("inset_mm") is not None:
        out.append(f"inset {round(errors['inset_mm']):+d} mm")
    if errors.get("offset_mm") is not None:
        out.append(f"offset {round(errors['offset_mm']):+d} mm")
    return out


def parse_legs(text: str) -> dict[str, float]:
    """``"AB=180,DA=175"`` (``AD`` is read as ``DA``) -> ``{"AB": 180.0, "DA": 175.0}``;
    both legs must be of one corner.

    Raises
    ------
    InvalidValueError
        With what is wrong.
    """
    legs: dict[str, float] = {}
    for part in text.split(","):
        key, sep, value = part.strip().partition("=")
        key = key.strip().upper()
        if not sep or len(key) != 2 or any(c not in CORNERS for c in key) or key[0] == key[1]:
            raise InvalidValueError(f"expected EDGE=MM pairs such as AB=180,DA=175, got {part!r}")
        name = edge_name(key[0], key[1])
        if name not in ("AB", "BC", "CD", "DA"):
            raise InvalidValueError(f"{key!r} is a diagonal, not an edge")
        try:
            legs[name] = float(value)
        except ValueError:
            raise InvalidValueError(f"leg {key}: {value!r} is not a number of mm") from None
        if not 0 < legs[name] < 1000 or not math.isfinite(legs[name]):
            raise InvalidValueError(f"leg {key}: {value} mm is out of range")
    if len(legs) != 2:
        raise InvalidValueError("give both legs of the corner, e.g. AB=180,DA=175")
    first, second = legs
    common = set(first) & set(second)
    if len(common) != 1:
        raise InvalidValueError(f"legs {' and '.join(legs)} do not meet at one corner")
    return legs


def _corner_of_legs(legs: dict[str, float]) -> str:
    a, b = list(legs)
    return (set(a) & set(b)).pop()


def check_request(
    expect: StateKey,
    *,
    legs: dict[str, float] | None = None,
    inset_mm: float | None = None,
    tip_mm: tuple[float, float] | None = None,
    offset_mm: float | None = None,
) -> None:
    """Refuse a request that no frame could satisfy, before any is looked at: planned
    sizes of a fold the expected state does not have (a corner's legs for a strip,
    corner A's legs for 04/CD), or sizes of one corner for a class whose variant is not
    given (``--expect 04 --legs AB=180,DA=180``: 04/AB or 04/DA?).

    Raises
    ------
    InvalidValueError
        One line naming the mistake and what would be right.
    """
    from ..core.classes import VARIANTS

    given = [n for n, v in (("legs", legs or None), ("inset", inset_mm), ("tip", tip_mm),
                            ("offset", offset_mm)) if v is not None]
    if len(given) > 1:
        raise InvalidValueError(
            f"give one of legs, inset, tip, offset, not {' and '.join(given)}")
    if not given:
        return
    cid, variant = expect
    variants = (variant,) if variant is not None else VARIANTS[cid]
    if legs:
        corner = _corner_of_legs(legs)
        what, wanted = f"legs {','.join(f'{e}={v:g}' for e, v in legs.items())}", corner
        kind = "corner"
    elif inset_mm is not None:
        what, wanted, kind = f"an inset of {inset_mm:g} mm", None, "side"
    elif offset_mm is not None:
        what, wanted, kind = f"an offset of {offset_mm:g} mm", None, "diagonal"
    else:
        what, wanted, kind = "a tip target", None, "corner"

    def fits(v: str | None) -> bool:
        kinds = [fold_kind(w) for w in folds_of(cid, v)]
        return any(k == kind and (wanted is None or name == wanted) for k, name in kinds)

    fitting = [v for v in variants if fits(v)]
    shown = _name(expect)
    if not fitting:
        words = sorted({w for v in variants for w in folds_of(cid, v)})
        corners = sorted({n for w in words for k, n in [fold_kind(w)] if k == "corner"})
        if not words:
            has = "has no fold"
        elif wanted and corners:
            listed = ", ".join(corners[:-1]) + " and " + corners[-1] if len(corners) > 1 \
                else corners[0]
            has = f"folds corner{'s' if len(corners) > 1 else ''} {listed}"
            has += f", not corner {wanted}"
        else:
            named = {"corner": "corner", "side": "strip or half", "diagonal": "diagonal"}
            has = f"has no {named[kind]} fold"
        raise InvalidValueError(f"--expect {shown} {has}: {what} cannot be checked against it")
    if variant is None and legs and len(VARIANTS[cid]) > 1:
        states = " or ".join(f"{cid}/{v}" for v in fitting)
        raise InvalidValueError(
            f"--expect {cid} names no variant, and {what} are corner {wanted}'s: give "
            f"--expect {states} (the states of {cid} that fold corner {wanted})"
        )


def verify_fold(
    result: Any,
    expect: StateKey,
    layout: NapkinLayout,
    *,
    fold: str | None = None,
    legs: dict[str, float] | None = None,
    inset_mm: float | None = None,
    tip_mm: tuple[float, float] | None = None,
    crease: Crease | None = None,
    tolerance_mm: float = DEFAULT_TOLERANCE_MM,
    offset_mm: float | None = None,
) -> FoldCheck:
    """Did the fold reach ``expect`` with the planned sizes?

    Parameters
    ----------
    result : FrameResult
        The frame after the fold, classified
        (:func:`~dgli_vision.classifier.pipeline.classify_frame`).
    expect : StateKey
        The state the fold should make (a variant of None accepts any).
    layout : NapkinLayout
    fold : str, optional
        The fold word whose sizes are checked (default: the one the sizes name).
    legs, inset_mm, tip_mm : optional
        The planned sizes: a corner's two legs (edge -> mm), a strip's or half fold's
        inset, or where a corner's tip should land (material mm).
    crease : Crease, optional
        The planned crease itself (a plan's step), instead of the sizes.
    tolerance_mm : float
    offset_mm : float, optional
        A diagonal fold's planned offset from its diagonal (mm, positive towards the
        moving corner; :func:`~dgli_vision.core.fold_measure.fold_measures`).

    Returns
    -------
    FoldCheck
    """
    p = result.prediction
    base = {"expect": expect, "tolerance_mm": tolerance_mm}
    if p is None and result.why is not None and str(result.why) in OUTSIDE_KINDS:
        # the fold left the napkin in none of the twelve states: it went wrong
        why = (result.reason or "").removeprefix("cannot tell: ")
        return FoldCheck(False, (OUTSIDE, None), fold=fold, reasons=(
            f"the napkin is in no known state, expected {_name(expect)}: {why}",), **base)
    if p is None:
        why = result.reason or "the state cannot be told"
        return FoldCheck(None, None, fold=fold, reasons=(f"cannot tell the state: {why}",),
                         **base)
    state = (p.class_id, p.variant)
    if p.class_id != expect[0] or (expect[1] is not None and p.variant != expect[1]):
        return FoldCheck(False, state, fold=fold, reasons=(
            f"wrong state: {_name(state)} ({p.name}), expected {_name(expect)}",), **base)
    sized = (legs or inset_mm is not None or tip_mm is not None or crease is not None
             or offset_mm is not None)
    if not sized:
        return FoldCheck(True, state, fold=fold, **base)
    words = folds_of(*expect) if expect[1] is not None else tuple(f.fold for f in p.folds)
    seen = {f.fold: f for f in p.folds}
    if fold is None:
        fold = _pick_fold(words, seen, legs, inset_mm, tip_mm, offset_mm)
    if fold is None or fold not in seen:
        what = "the legs' corner" if legs else "a fold of that kind"
        return FoldCheck(False, state, fold=fold, reasons=(
            f"{_name(state)} has no fold of {what}",), **base)
    g = seen[fold].geometry
    if g is None or g.why is not None or g.crease is None:
        why = g.why if g is not None else "not measured"
        return FoldCheck(None, state, fold=fold, reasons=(
            f"cannot tell the fold's geometry ({fold}): {why}",), **base)
    target = crease or planned_crease(fold, layout, legs=legs, inset_mm=inset_mm, tip_mm=tip_mm,
                                      offset_mm=offset_mm or 0.0)
    if target is None:
        return FoldCheck(False, state, fold=fold, reasons=(
            f"the sizes given do not make a fold {fold!r}",), **base)
    return _compare(state, expect, fold, g, target, layout, tolerance_mm,
                    tip_given=tip_mm is not None)


def _pick_fold(words, seen, legs, inset_mm, tip_mm, offset_mm=None) -> str | None:
    """The fold the planned sizes name."""
    if legs:
        corner = _corner_of_legs(legs)
        return next((w for w in words if fold_kind(w) == ("corner", corner)), None)
    if inset_mm is not None:
        return next((w for w in words if fold_kind(w)[0] == "side"), None)
    if offset_mm is not None:
        return next((w for w in words if fold_kind(w)[0] == "diagonal"), None)
    corners = [w for w in words if fold_kind(w)[0] == "corner"]
    if len(corners) <= 1:
        return corners[0] if corners else None
    best, where = None, math.inf  # the corner fold whose tip lies nearest the target
    for w in corners:
        g = seen.get(w) and seen[w].geometry
        tip = None if not g else g.values.get("tip_mm")
        if tip is not None and math.dist(tip, tip_mm) < where:
            best, where = w, math.dist(tip, tip_mm)
    return best or corners[0]


def _compare(
    state: StateKey,
    expect: StateKey,
    fold: str,
    g: Any,
    target: Crease,
    layout: NapkinLayout,
    tol: float,
    *,
    tip_given: bool,
) -> FoldCheck:
    """The planned fold ``target`` against the fold measured ``g``."""
    planned = fold_measures(fold, target, layout)
    errors: dict[str, Any] = {"crease_mm": crease_distance_mm(g.crease, target, layout)}
    checks: list[tuple[str, float, float | None]] = []  # (what, |error|, sd)
    kind, name = fold_kind(fold)
    sd_line = _line_sd(g)
    if errors["crease_mm"] is not None:
        checks.append(("crease", errors["crease_mm"], sd_line))
    fails, unsure = [], []
    if kind == "corner":
        errors["legs_mm"] = {
            e: None if (v is None or planned["legs_mm"].get(e) is None)
            else v - planned["legs_mm"][e]
            for e, v in g.values["legs_mm"].items()
        }
        for e, err in errors["legs_mm"].items():
            if err is not None:
                checks.append((f"leg {e}", abs(err), (g.sd.get("legs_sd_mm") or {}).get(e)))
        tip, want = np.asarray(g.values["tip_mm"]), np.asarray(planned["tip_mm"])
        corner = np.asarray(layout.corner_uv[CORNERS.index(name)], dtype=float)
        way = want - corner
        way = way / max(float(np.linalg.norm(way)), 1e-9)
        errors["tip_mm"] = float(np.linalg.norm(tip - want))
        errors["tip_short_mm"] = float((want - tip) @ way)
        checks.append(("tip", errors["tip_mm"], g.sd.get("tip_sd_mm")))
    elif kind == "side":
        errors["inset_mm"] = g.values["inset_mm"] - planned["inset_mm"]
        errors["skew_deg"] = g.values["skew_deg"] - planned["skew_deg"]
        checks.append(("inset", abs(errors["inset_mm"]), g.sd.get("inset_sd_mm")))
    else:
        errors["offset_mm"] = g.values["offset_mm"] - planned["offset_mm"]
        errors["turn_deg"] = g.values["turn_deg"] - planned["turn_deg"]
        checks.append(("offset", abs(errors["offset_mm"]), g.sd.get("offset_sd_mm")))
    for what, err, sd in checks:
        if err > tol:
            fails.append(_fail_text(what, err, errors, name, planned, kind, tip_given))
        elif sd is not None and err + 2.0 * sd > tol:
            unsure.append(f"{what} {err:.0f} mm off, within {tol:g} mm by less than twice "
                          f"its uncertainty ({sd:.0f} mm)")
    success: bool | None = True
    reasons: tuple[str, ...] = ()
    if fails:
        success, reasons = False, tuple(dict.fromkeys(fails))
    elif unsure:
        success, reasons = None, tuple(unsure)
    return FoldCheck(success, state, expect, fold, errors, g.to_json(), planned, reasons, tol)


def _fail_text(what, err, errors, corner, planned, kind, tip_given) -> str:
    if what == "tip":
        short = errors["tip_short_mm"]
        target = ", ".join(f"{v:.0f}" for v in planned["tip_mm"])
        way = "short of" if short >= 0 else "beyond"
        return (f"corner {corner} {abs(short):.0f} mm {way} its target ({target}) "
                f"and {err:.0f} mm from it")
    if what == "crease":
        return f"crease {err:.0f} mm off the planned one"
    if what.startswith("leg"):
        e = what.split()[1]
        signed = errors["legs_mm"][e]
        return f"leg {e} {abs(signed):.0f} mm {'longer' if signed > 0 else 'shorter'} than planned"
    if what == "inset":
        return f"inset {errors['inset_mm']:+.0f} mm from the planned {planned['inset_mm']:.0f} mm"
    if what == "offset":
        return (f"offset {errors['offset_mm']:+.0f} mm from the planned "
                f"{planned['offset_mm']:.0f} mm")
    return f"{what} {err:.0f} mm off"


def _line_sd(g: Any) -> float | None:
    """The largest sd (mm) of the measured crease's place: that of its legs, tip or
    inset, whichever is largest."""
    mm = [v for k, v in g.sd.items() if k.endswith("_mm") and not isinstance(v, dict) and v]
    legs = g.sd.get("legs_sd_mm") or {}
    mm += [x for x in legs.values() if x is not None]
    return max(mm) if mm else None
