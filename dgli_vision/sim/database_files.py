"""Simulated databases on disk: ``meshes/<id>.ply``, ``truth/<id>.json`` and ``index.json``."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..core.errors import InvalidInputError, OutputError
from ..core.io import (
    failed_part_way,
    guard_outputs,
    read_json,
    record_outputs,
    write_json,
    write_mesh_ply,
)

if TYPE_CHECKING:
    from .cloth.states import ClothState
    from .database import StateRecords

__all__ = [
    "DB_FORMAT",
    "read_database",
    "write_database",
]

DB_FORMAT = "dgli-simulated-db"


def write_database(
    out: str | Path,
    states: list[tuple[str, ClothState]],
    provenance: dict[str, Any],
    *,
    overwrite: bool = False,
) -> Path:
    """Write states as ``meshes/<id>.ply``, ``truth/<id>.json`` and ``index.json``.

    Existing files are replaced only if dgli wrote them or with ``overwrite``
    (:func:`guard_outputs`).

    Returns
    -------
    Path
        The index file.

    Raises
    ------
    OverwriteError
    OutputError
        A file that cannot be written (a full disk...): the states written before it
        are kept, recorded and named.
    """
    root = Path(out)
    planned = [
        *(root / "meshes" / f"{sid}.ply" for sid, _ in states),
        *(root / "truth" / f"{sid}.json" for sid, _ in states),
        root / "index.json",
    ]
    guard_outputs(planned, overwrite=overwrite)
    entries = []
    triangles = None
    written: list[Path] = []
    command = str(provenance.get("command", ""))
    for sid, state in states:
        if triangles is None:
            triangles = state.mesh.triangles()
        mesh, truth = root / "meshes" / f"{sid}.ply", root / "truth" / f"{sid}.json"
        try:
            write_mesh_ply(mesh, state.mesh.xyz, triangles)
            written.append(mesh)
            write_json(truth, _truth_of(sid, state))
            written.append(truth)
        except OutputError as exc:
            raise failed_part_way(exc, written, command) from None
        entries.append(
            {
                "id": sid,
                "class": state.class_id,
                "variant": state.variant,
                "mesh": f"meshes/{sid}.ply",
                "truth": f"truth/{sid}.json",
            }
        )
    index = root / "index.json"
    try:
        write_json(
            index,
            {"format": DB_FORMAT, "version": 1, "provenance": provenance, "states": entries},
        )
    except OutputError as exc:
        raise failed_part_way(exc, written, command) from None
    record_outputs(planned, command)
    return index


def _truth_of(sid: str, state: ClothState) -> dict[str, Any]:
    """The truth file of one state."""
    from .database import footprint_fraction

    return {
        "id": sid,
        "class": state.class_id,
        "name": state.name,
        "variant": state.variant,
        "sticker_points_m": np.round(state.sticker_points, 7).tolist(),
        "visible": state.visible.tolist(),
        "visible_fraction": np.round(state.visible_fraction, 4).tolist(),
        "coordinates": np.round(state.coordinates(), 10).tolist(),
        "corner_points_m": np.round(state.corner_points, 7).tolist(),
        "boundary_m": np.round(state.boundary, 7).tolist(),
        "footprint": footprint_fraction(state),
        "params": state.params,
    }


def _check_truth(
    truth: Any, truth_path: Path
) -> tuple[str, str, str | None, tuple[np.ndarray, ...]]:
    """A state's id, class, variant and arrays (sticker points, visibility, visible
    fractions, corners, boundary), each checked: known class and variant, the right
    shapes, finite numbers.

    Raises
    ------
    InvalidInputError
        Naming the truth file and what is wrong.
    """
    from ..core.classes import CLASS_NAMES, VARIANTS

    bad = f"state truth '{truth_path}'"
    try:
        sid, class_id = str(truth["id"]), str(truth["class"])
        variant = truth.get("variant")
        pts = np.asarray(truth["sticker_points_m"], dtype=np.float64).reshape(16, 3)
        v = np.asarray(truth["visible"], dtype=bool).reshape(16)
        f = np.asarray(truth["visible_fraction"], dtype=np.float64).reshape(16)
        cp = np.asarray(truth["corner_points_m"], dtype=np.float64).reshape(4, 3)
        bd = np.asarray(truth["boundary_m"], dtype=np.float64).reshape(-1, 3)
    except KeyError as exc:
        raise InvalidInputError(f"{bad} lacks {exc}") from None
    except (AttributeError, ValueError, TypeError) as exc:
        raise InvalidInputError(f"{bad} is malformed ({exc})") from None
    if class_id not in CLASS_NAMES:
        raise InvalidInputError(f"{bad} has unknown class {class_id!r}")
    if variant not in VARIANTS[class_id]:
        raise InvalidInputError(f"{bad}: {variant!r} is not a variant of class {class_id}")
    for name, values in (
        ("sticker_points_m", pts),
        ("visible_fraction", f),
        ("corner_points_m", cp),
        ("boundary_m", bd),
    ):
        if not np.isfinite(values).all():
            raise InvalidInputError(f"{bad}: {name} holds values that are not finite numbers")
    return sid, class_id, variant, (pts, v, f, cp, bd)


def read_database(path: str | Path) -> tuple[StateRecords, dict[str, Any]]:
    """Read a database folder (or its ``index.json``) into records and provenance.

    Raises
    ------
    UnreadableInputError, InvalidInputError
        Naming the file that is missing or wrong.
    """
    from ..core.dgli import cloth_coordinates
    from .database import StateRecords

    p = Path(path)
    index_path = p / "index.json" if p.is_dir() else p
    index = read_json(index_path, what="database index")
    if not isinstance(index, dict) or index.get("format") != DB_FORMAT:
        raise InvalidInputError(f"'{index_path}' is not a dgli simulated database index")
    root = index_path.parent
    ids, classes, variants, points, vis, frac, corners, boundary, stages = ([] for _ in range(9))
    footprint = []
    states = index.get("states")
    if not isinstance(states, list):
        raise InvalidInputError(f"database index '{index_path}' has no list of states")
    for k, entry in enumerate(states):
        if not isinstance(entry, dict) or not isinstance(entry.get("truth"), str):
            raise InvalidInputError(
                f"database index '{index_path}': state {k} does not name its truth file"
            )
        truth_path = root / entry["truth"]
        truth = read_json(truth_path, what="state truth")
        sid, class_id, variant, arrays = _check_truth(truth, truth_path)
        ids.append(sid)
        classes.append(class_id)
        variants.append(variant)
        params = truth.get("params")
        stages.append(str(params.get("stage", "")) if isinstance(params, dict) else "")
        pts, v, f, cp, bd = arrays
        points.append(pts)
        vis.append(v)
        frac.append(f)
        corners.append(cp)
        boundary.append(bd)
        fp = truth.get("footprint")
        footprint.append(float(fp) if isinstance(fp, (int, float)) else np.nan)
    if not ids:
        raise InvalidInputError(f"database '{index_path}' lists no states")
    pts = np.stack(points)
    records = StateRecords(
        tuple(ids),
        tuple(classes),
        tuple(variants),
        pts,
        np.stack(vis),
        np.stack(frac),
        cloth_coordinates(pts.reshape(len(ids), -1, 2, 3)),
        np.stack(corners),
        np.stack(boundary),
        tuple(stages),
        np.array(footprint, dtype=np.float64),
    )
    return records, dict(index.get("provenance") or {})
