"""Labelled folders (``labels.csv`` or one folder per class): writing rendered samples, and
finding the pairs and their labels."""

from __future__ import annotations

import os
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..core.classes import class_id_of
from ..core.errors import InvalidInputError, InvalidValueError, OutputError, UnreadableInputError
from ..core.frame import RGBDFrame
from ..core.io import (
    check_input_file,
    failed_part_way,
    guard_outputs,
    record_outputs,
    write_json,
    write_text,
)
from .frames import read_frame, write_color, write_depth

__all__ = [
    "LabelProblem",
    "LabelledPair",
    "find_labelled_pairs",
    "find_pairs",
    "folder_intrinsics",
    "labelled_folder_files",
    "listed_files",
    "write_labelled_folder",
]


def labelled_folder_files(
    out: str | Path, names: Iterable[str], *, frames: bool = False
) -> list[Path]:
    """The files :func:`write_labelled_folder` writes for samples of these names
    (``frames``: with a ``frames.csv``)."""
    root = Path(out)
    pairs = [root / f"{n}_{kind}.png" for n in names for kind in ("color", "depth")]
    extra = [root / "frames.csv"] if frames else []
    return [*pairs, root / "intrinsics.json", root / "labels.csv", root / "truth.json", *extra]


def listed_files(folder: str | Path) -> list[str]:
    """The files a folder's listings name: the ``color`` and ``depth`` of each row of its
    ``frames.csv`` and ``labels.csv`` (relative to the folder), and those listings; what
    an earlier run there wrote (read leniently: an unreadable listing names nothing)."""
    import csv

    root = Path(folder)
    names: list[str] = []
    for listing in ("frames.csv", "labels.csv"):
        path = root / listing
        if not path.is_file():
            continue
        try:
            with path.open(newline="", encoding="utf-8-sig") as fh:
                for row in csv.DictReader(fh):
                    names += [v.strip() for k in ("color", "depth") if (v := row.get(k))]
        except (OSError, UnicodeDecodeError, csv.Error):
            continue
        names.append(listing)
    return names


def write_labelled_folder(
    out: str | Path,
    samples: list,
    provenance: dict[str, Any],
    *,
    overwrite: bool = False,
    times: list[float] | None = None,
) -> Path:
    """Write rendered samples as a labelled folder (SPEC section 4) with ``truth.json``.

    ``samples`` are :class:`~dgli_vision.sim.dataset.RenderedSample`; writes
    ``<name>_color.png``, ``<name>_depth.png``, ``intrinsics.json`` (of the first sample),
    ``labels.csv`` and ``truth.json``. Samples seen by another camera than the first (a
    ``vga`` or ``distortion-known`` condition drawn by ``combo``) go to a subfolder
    ``camera2/``, ``camera3/``... with its own ``intrinsics.json``, which readers of the
    folder use for the pairs in it. With ``times`` (seconds, one
    per sample) also ``frames.csv`` (``color,depth,time``: the frames of a recording in
    order). Existing files are replaced only if dgli wrote them or with ``overwrite``
    (:func:`guard_outputs`). Returns the labels file.

    Raises
    ------
    OverwriteError
    OutputError
        An image that cannot be written (a full disk...): the pairs written before it
        are kept, recorded and named.
    """
    root = Path(out)
    if not samples:
        raise InvalidValueError("no samples to write")
    cameras: list = []
    for s in samples:
        if s.result.intrinsics not in cameras:
            cameras.append(s.result.intrinsics)
    where = [_camera_folder(cameras.index(s.result.intrinsics)) for s in samples]
    planned = labelled_folder_files(root, [s.name for s in samples], frames=times is not None)
    planned += [
        root / sub / f"{s.name}_{kind}.png"
        for s, sub in zip(samples, where) if sub for kind in ("color", "depth")
    ]
    planned += [root / _camera_folder(k) / "intrinsics.json" for k in range(1, len(cameras))]
    guard_outputs(planned, overwrite=overwrite)
    if times is not None and len(times) != len(samples):
        raise InvalidValueError(f"{len(times)} times for {len(samples)} samples")
    rows = []
    truth = {}
    written: list[Path] = []
    for k, intr in enumerate(cameras):
        write_json(root / _camera_folder(k) / "intrinsics.json", intr.to_open3d_dict())
    for s, sub in zip(samples, where):
        color, depth = f"{sub}{s.name}_color.png", f"{sub}{s.name}_depth.png"
        try:
            write_color(root / color, s.result.color)
            written.append(root / color)
            write_depth(root / depth, s.result.depth_mm)
            written.append(root / depth)
        except OutputError as exc:
            raise failed_part_way(exc, written, str(provenance.get("command", ""))) from None
        rows.append((color, depth, s.state.class_id, s.state.variant or ""))
        truth[s.name] = {
            "color": color,
            "depth": depth,
            "class": s.state.class_id,
            "name": s.state.name,
            "variant": s.state.variant,
            "camera": {**s.camera, **s.result.pose.to_json()},
            "sticker_points_cam_m": np.round(s.result.sticker_points_cam, 6).tolist(),
            "visible": s.result.visible.tolist(),
            "visible_fraction": np.round(s.result.visible_fraction, 3).tolist(),
            "state_params": s.state.params,
            # a path-traced pair: its lights, materials and camera pipeline's draws
            **({"render": s.result.info} if s.result.info.get("engine") else {}),
        }
    from ..core.io import csv_table

    labels = root / "labels.csv"
    write_text(labels, csv_table(["color", "depth", "label", "variant"], rows))
    if times is not None:
        write_text(
            root / "frames.csv",
            csv_table(
                ["color", "depth", "time"],
                [(c, d, f"{t:.3f}") for (c, d, *_), t in zip(rows, times)],
            ),
        )
    write_json(root / "truth.json", {"provenance": provenance, "images": truth})
    record_outputs(
        [p for p in planned if p.exists()], str(provenance.get("command", ""))
    )
    return labels


def _camera_folder(k: int) -> str:
    """Subfolder (with its slash) of the pairs of the k-th camera of a folder: ``""``
    for the first."""
    return f"camera{k + 1}/" if k else ""


@dataclass(frozen=True)
class LabelledPair:
    """One colour + depth pair of a labelled folder, with its true class and variant.

    ``line`` is the pair's line in ``labels.csv`` (None for class folders); ``time`` is
    the frame's time in seconds in a recording (None when not known); ``intrinsics_file`` is
    the labelled folder's ``intrinsics.json`` for a pair in a class folder that has none
    of its own (:func:`folder_intrinsics`; None: the usual lookup).
    """

    color: str
    depth: str
    label: str
    variant: str | None = None
    line: int | None = None
    time: float | None = None
    intrinsics_file: str | None = field(default=None, kw_only=True)

    def load(self) -> RGBDFrame:
        """The validated frame (:func:`~dgli_vision.sources.frames.read_frame`, one thread).

        Raises
        ------
        UnreadableInputError, InvalidInputError, CalibrationError
        """
        return read_frame(self.color, self.depth, self.intrinsics_file, threads=False)

    def light(self) -> LabelledPair:
        """This pair as names only (what an outcome keeps)."""
        return self


@dataclass(frozen=True)
class LabelProblem:
    """A row of a labelled folder that cannot be used as it stands.

    Attributes
    ----------
    where : str
        ``labels.csv line 7`` or the pair's colour path (class folders).
    kind : str
        ``"unknown class"``, ``"unknown variant"``, ``"duplicate"`` or ``"missing file"``.
    message : str
        One line saying what is wrong.
    """

    where: str
    kind: str
    message: str


def folder_intrinsics(root: str | Path, color: str | Path) -> str | None:
    """The intrinsics a pair below ``root`` falls back on: ``root/intrinsics.json`` when
    the colour image lies in a subfolder (a class folder) without an ``intrinsics.json``
    of its own; None when the usual lookup (the colour image's folder) applies."""
    beside = Path(color).parent / "intrinsics.json"
    shared = Path(root) / "intrinsics.json"
    if Path(color).parent == Path(root) or beside.is_file() or not shared.is_file():
        return None
    return str(shared)


def _real_path(path: str) -> str:
    """The path with symbolic links resolved as far as they go (a link loop does not
    raise: reading the file reports it)."""
    return os.path.realpath(path)


def _unreadable(kind: str, path: str) -> str | None:
    """Why a pair's file cannot be read (missing, a link loop, a FIFO...), or None."""
    from ..core.errors import DgliError

    try:
        check_input_file(path, kind)
    except DgliError as exc:
        return str(exc)
    return None


def find_pairs(folder: str | Path) -> list[LabelledPair]:
    """The labelled pairs of a folder, strictly checked (see :func:`find_labelled_pairs`).

    Raises
    ------
    UnreadableInputError, InvalidInputError
    """
    return find_labelled_pairs(folder)[0]


def _check_labels(
    pairs: list[LabelledPair], where: list[str]
) -> tuple[list[LabelledPair], list[LabelProblem]]:
    """Split pairs into usable ones and problems (unknown class or variant, duplicates,
    missing files). Pairs with missing files stay usable: reading them fails and is
    reported with the batch."""
    from ..core.classes import CLASS_HINT, CLASS_NAMES, VARIANTS

    keep, problems = [], []
    seen: dict[tuple[str, str], str] = {}
    for pair, at in zip(pairs, where):
        if pair.label not in CLASS_NAMES:
            problems.append(
                LabelProblem(
                    at,
                    "unknown class",
                    f"{at}: class {pair.label!r} is not {CLASS_HINT}",
                )
            )
            continue
        if pair.variant is not None and pair.variant not in VARIANTS[pair.label]:
            allowed = ", ".join(v or "(none)" for v in VARIANTS[pair.label])
            problems.append(
                LabelProblem(
                    at,
                    "unknown variant",
                    f"{at}: variant {pair.variant!r} is not one of class {pair.label}'s "
                    f"({allowed})",
                )
            )
            continue
        key = (_real_path(pair.color), _real_path(pair.depth))
        if key in seen:
            problems.append(LabelProblem(at, "duplicate", f"{at}: the same pair as {seen[key]}"))
            continue
        seen[key] = at
        for kind, path in (("colour image", pair.color), ("depth image", pair.depth)):
            why = _unreadable(kind, path)
            if why is not None:
                problems.append(LabelProblem(at, "missing file", f"{at}: {why}"))
                break
        keep.append(pair)
    return keep, problems


def _pairs_from_labels_csv(root: Path, labels: Path) -> tuple[list[LabelledPair], list[str]]:
    """The pairs ``labels.csv`` lists, and where each is listed (``'<file>' line k``)."""
    import csv

    pairs, where = [], []
    try:
        with labels.open(newline="", encoding="utf-8-sig") as fh:  # a BOM is dropped
            reader = csv.DictReader(fh)
            missing = {"color", "depth", "label"} - set(reader.fieldnames or [])
            if missing:
                raise InvalidInputError(
                    f"labels file '{labels}' lacks column(s) {', '.join(sorted(missing))}; "
                    "expected color,depth,label[,variant]"
                )
            for k, row in enumerate(reader, start=2):
                label = (row.get("label") or "").strip()
                if not row.get("color") or not row.get("depth") or not label:
                    raise InvalidInputError(f"labels file '{labels}' line {k} is incomplete")
                variant = (row.get("variant") or "").strip() or None
                color = root / row["color"]
                pairs.append(
                    LabelledPair(
                        str(color),
                        str(root / row["depth"]),
                        class_id_of(label) or label,
                        variant,
                        k,
                        intrinsics_file=folder_intrinsics(root, color),
                    )
                )
                where.append(f"'{labels}' line {k}")
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise UnreadableInputError(f"cannot read labels file '{labels}': {exc}") from None
    return pairs, where


def _pairs_from_class_folders(root: Path) -> tuple[list[LabelledPair], list[str]]:
    """The pairs in class folders (``02_corner-over/<name>_color.png``) and their paths."""
    pairs, where = [], []
    for color in sorted(root.rglob("*_color.png")):
        rel = color.relative_to(root)
        if len(rel.parts) < 2:
            continue  # no class folder: unlabelled
        head = rel.parts[0]
        label = head[:2]
        if not label.isdigit():
            continue
        depth = color.with_name(color.name[: -len("_color.png")] + "_depth.png")
        intrinsics = folder_intrinsics(root, color)
        pairs.append(LabelledPair(str(color), str(depth), label, intrinsics_file=intrinsics))
        where.append(f"'{color}'")
    return pairs, where


def find_labelled_pairs(
    folder: str | Path, *, lenient: bool = False
) -> tuple[list[LabelledPair], list[LabelProblem]]:
    """The labelled pairs of a folder (SPEC section 4), sorted by colour path, and the
    problems found in its labels.

    Labels come from ``labels.csv`` (``color,depth,label[,variant]``, paths relative to
    the folder; UTF-8, with or without a byte-order mark) or, without it, from the first
    directory level below the folder, whose name starts with the class id
    (``02_corner-over/...``); pairs are ``<name>_color.png`` + ``<name>_depth.png``. A
    pair in a subfolder (a class folder) without an ``intrinsics.json`` of its own uses
    the labelled folder's (:func:`folder_intrinsics`).

    Every row is checked: an unknown class id, a variant the class does not have, or a
    pair listed twice is an error unless ``lenient``, which skips the row and lists it;
    a row whose files are missing is listed and kept (reading it fails, and a batch
    reports it among its failures).

    Returns
    -------
    pairs : list of LabelledPair
    problems : list of LabelProblem
        Each problem once, by line of ``labels.csv`` (or by pair for class folders).

    Raises
    ------
    UnreadableInputError, InvalidInputError
        The folder is missing, ``labels.csv`` is malformed, no pair is found, or (not
        ``lenient``) a row has an unknown class or variant or repeats another.
    """
    root = Path(folder)
    if not root.is_dir():
        raise UnreadableInputError(f"folder '{root}' does not exist or is not a directory")
    labels = root / "labels.csv"
    if labels.is_file():
        pairs, where = _pairs_from_labels_csv(root, labels)
    else:
        pairs, where = _pairs_from_class_folders(root)
    if not pairs:
        raise InvalidInputError(
            f"folder '{root}' holds no labelled pairs (no labels.csv and no "
            "<class>_*/<name>_color.png files)"
        )
    pairs, problems = _check_labels(pairs, where)
    fatal = [p for p in problems if p.kind != "missing file"]
    if fatal and not lenient:
        n = len(fatal) - 1
        more = f" (and {n} more bad row{'s' if n > 1 else ''})" if n else ""
        raise InvalidInputError(f"{fatal[0].message}{more}; fix the labels or use --lenient")
    if not pairs:
        raise InvalidInputError(f"folder '{root}' holds no usable labelled pairs")
    return sorted(pairs, key=lambda p: p.color), problems
