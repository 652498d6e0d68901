"""``dgli verify``: did the fold work? The state after a fold and its geometry against
what was planned (docs/folds.md)."""

from __future__ import annotations

import json
import sys

import click

from .errors import handle_errors
from .options import (
    extrinsics_option,
    intrinsics_option,
    json_option,
    mirroring_option,
    references_option,
)
from .output import echo


def _state(ctx: click.Context, param: click.Parameter, value: str | None):
    from ..planning.plan import parse_state

    if value is None:
        return None
    try:
        return parse_state(value, need_variant=False)
    except ValueError as exc:
        raise click.BadParameter(str(exc)) from None


def _legs(ctx: click.Context, param: click.Parameter, value: str | None):
    from ..planning.verify import parse_legs

    if value is None:
        return None
    try:
        return parse_legs(value)
    except ValueError as exc:
        raise click.BadParameter(str(exc)) from None


def _tip(ctx: click.Context, param: click.Parameter, value: str | None):
    if value is None:
        return None
    parts = value.split(",")
    try:
        tip = tuple(float(v) for v in parts)
    except ValueError:
        tip = ()
    if len(tip) != 2 or not all(-1000 < v < 2000 for v in tip):
        raise click.BadParameter(f"expected U,V in mm on the flat napkin, got {value!r}")
    return tip


def report(check, as_json: bool, extrinsics=None) -> None:
    """Print a :class:`~dgli_vision.planning.verify.FoldCheck` (its JSON's 3D points, if
    any, in the frame of ``extrinsics``, named by ``"frame"``) and exit 1 unless it
    succeeded."""
    from ..core.extrinsics import in_frame

    echo(json.dumps(in_frame(check.to_json(), extrinsics)) if as_json else check.line())
    if not check.success:
        sys.exit(1)


@click.command("verify")
@click.argument("color", type=click.Path())
@click.argument("depth", type=click.Path())
@click.option("--expect", callback=_state, required=True,
              help="The state the fold should make: 02/B, 09/CD, 04/AB (a class alone "
                   "accepts any variant).")
@click.option("--legs", callback=_legs,
              help="The corner fold's planned legs, mm: AB=180,DA=175.")
@click.option("--inset", type=click.FloatRange(0, 1000, min_open=True),
              help="The strip's or half fold's planned inset, mm.")
@click.option("--tip", callback=_tip, help="Where the corner should land: U,V in mm.")
@click.option("--offset", type=click.FloatRange(-1000, 1000),
              help="The diagonal fold's planned offset from its diagonal, mm (positive "
                   "towards the moving corner; 0: on the diagonal).")
@click.option("--tolerance", type=click.FloatRange(0, 1000, min_open=True), default=20.0,
              show_default=True, help="How far (mm) a planned size may be missed.")
@intrinsics_option
@references_option
@extrinsics_option
@mirroring_option
@json_option("Print the verdict, with every error, as one JSON object.")
@handle_errors
def verify_cmd(
    color: str,
    depth: str,
    expect,
    legs,
    inset: float | None,
    tip,
    offset: float | None,
    tolerance: float,
    intrinsics: str | None,
    references_path: str | None,
    extrinsics_path: str | None,
    mirroring: str | None,
    as_json: bool,
) -> None:
    """Did the fold work? Classify COLOR DEPTH (taken after the fold) and check it is
    the --expect state with the planned sizes (one of --legs, --inset, --tip, --offset) within
    --tolerance. Exit 0: success; 1: failed or cannot tell, with the reason (wrong
    state, crease 34 mm off, corner B 52 mm short of its target); 2: bad input.
    """
    from ..classifier.pipeline import classify_frame
    from ..classifier.references import load_references
    from ..core.extrinsics import read_extrinsics
    from ..core.layout import layout_of_size
    from ..planning.verify import check_request, verify_fold
    from ..sources.frames import read_frame

    given = [n for n, v in (("--legs", legs), ("--inset", inset), ("--tip", tip),
                            ("--offset", offset)) if v is not None]
    if len(given) > 1:
        raise click.UsageError(
            f"give one of --legs, --inset, --tip, --offset, not {' and '.join(given)}")
    check_request(expect, legs=legs, inset_mm=inset, tip_mm=tip,
                  offset_mm=offset)  # a mistake: exit 2
    extrinsics = read_extrinsics(extrinsics_path) if extrinsics_path else None
    refs = load_references(references_path)
    layout = layout_of_size(refs.napkin_mm)
    frame = read_frame(color, depth, intrinsics)
    result = classify_frame(frame, refs, layout=layout, mirroring=mirroring)
    check = verify_fold(result, expect, layout, legs=legs, inset_mm=inset, tip_mm=tip,
                        offset_mm=offset, tolerance_mm=tolerance)
    report(check, as_json, extrinsics)
