"""Labelled folders (``labels.csv`` or one folder per class): writing rendered samples, and
finding the pairs and their labels."""

from __future__ import annotations

import json
import os
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..core.classes import class_id_of
from ..core.errors import InvalidInputError, InvalidValueError, OutputError, UnreadableInputError
from ..core.frame import RGBDFrame
from ..core.io import check_input_file, guard_outputs
from .frames import read_frame

__all__ = [
    "LabelProblem",
    "LabelledFolderWriter",
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
    (:func:`guard_outputs`). The pairs are written one by one
    (:class:`LabelledFolderWriter`). Returns the labels file.

    Raises
    ------
    OverwriteError
    OutputError
        An image that cannot be written (a full disk...): the pairs written before it
        are kept, listed, recorded and named.
    """
    root = Path(out)
    if not samples:
        raise InvalidValueError("no samples to write")
    if times is not None and len(times) != len(samples):
        raise InvalidValueError(f"{len(times)} times for {len(samples)} samples")
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
    writer = LabelledFolderWriter(root, provenance, [s.name for s in samples],
                                  frames=times is not None, overwrite=overwrite)
    for k, s in enumerate(samples):
        writer.add(s, None if times is None else times[k])
    return writer.labels


class LabelledFolderWriter:
    """Writes rendered samples into a labelled folder one at a time, as they come: each
    pair's colour and depth, then ``labels.csv``, ``truth.json`` (and ``frames.csv``)
    listing every pair written so far, in the order of ``names``, with the pairs
    ``kept`` from an interrupted run. Every file is written whole and recorded before it
    is renamed into place (:func:`~dgli_vision.core.io.write_recorded`), and the
    listings after the images: a process killed at any instant (SIGKILL too) leaves a
    folder whose listings name exactly its complete pairs, which ``--resume`` keeps.

    The caller has checked the files with :func:`guard_outputs`.

    Parameters
    ----------
    out : str or Path
    provenance : dict
        ``truth.json``'s ``"provenance"`` (its ``"command"`` goes to the record).
    names : sequence of str
        Every pair of the set, in the order the listings give them.
    frames : bool, keyword-only
        Write ``frames.csv`` (a recording's frames and their times).
    kept : dict, keyword-only, optional
        Name -> a pair an earlier run left (``label_row``, ``frame_row`` and ``truth``,
        :class:`~dgli_vision.sim.dataset.KeptPair`), listed with the new ones.
    overwrite : bool, keyword-only
        Replace a user's file where a pair goes (each pair's files are checked with
        :func:`guard_outputs` before they are written: a camera's subfolder is known
        only when its first pair comes).
    """

    def __init__(
        self,
        out: str | Path,
        provenance: dict[str, Any],
        names: Iterable[str],
        *,
        frames: bool = False,
        kept: dict[str, Any] | None = None,
        overwrite: bool = False,
    ) -> None:
        self.root = Path(out)
        self.overwrite = overwrite
        self.labels = self.root / "labels.csv"
        self.provenance = provenance
        self.command = str(provenance.get("command", ""))
        self.names = list(names)
        self.frames = frames
        self._label_rows: dict[str, tuple[str, ...]] = {}
        self._frame_rows: dict[str, tuple[str, ...]] = {}
        self._truth: dict[str, Any] = {}
        self._truth_text: dict[str, str] = {}  # each entry's JSON, as truth.json nests it
        for name, pair in (kept or {}).items():
            self._label_rows[name] = tuple(pair.label_row)
            if pair.frame_row is not None:
                self._frame_rows[name] = tuple(pair.frame_row)
            self._truth[name] = pair.truth
        self._cameras: list = []
        self.written = 0

    def add(self, sample: Any, time_s: float | None = None) -> None:
        """Write one :class:`~dgli_vision.sim.dataset.RenderedSample` (``time_s``: its
        time in the recording, for ``frames.csv``) and list it.

        Raises
        ------
        OutputError
            The pair, or a listing, could not be written: naming it, and the pairs
            written before it, which are kept and listed.
        """
        import cv2

        from ..core.io import csv_table, image_bytes, write_recorded

        files: list[tuple[Path, bytes]] = []
        intr = sample.result.intrinsics
        if intr not in self._cameras:
            self._cameras.append(intr)
            k = len(self._cameras) - 1
            text = json.dumps(intr.to_open3d_dict(), indent=1) + "\n"
            files.append((self.root / _camera_folder(k) / "intrinsics.json", text.encode()))
        sub = _camera_folder(self._cameras.index(intr))
        color, depth = f"{sub}{sample.name}_color.png", f"{sub}{sample.name}_depth.png"
        depth_mm = sample.result.depth_mm
        if depth_mm.dtype != np.uint16:
            raise InvalidValueError(f"depth must be uint16, got {depth_mm.dtype}")
        try:
            files.append((self.root / color, image_bytes(
                self.root / color, cv2.cvtColor(sample.result.color, cv2.COLOR_RGB2BGR))))
            files.append((self.root / depth, image_bytes(self.root / depth, depth_mm)))
        except OutputError as exc:
            raise self._failed(exc) from None
        guard_outputs([path for path, _ in files], overwrite=self.overwrite)
        state = sample.state
        self._label_rows[sample.name] = (color, depth, state.class_id, state.variant or "")
        if self.frames:
            self._frame_rows[sample.name] = (color, depth, f"{time_s or 0.0:.3f}")
        self._truth[sample.name] = {
            "color": color,
            "depth": depth,
            "class": state.class_id,
            "name": state.name,
            "variant": state.variant,
            "camera": {**sample.camera, **sample.result.pose.to_json()},
            "sticker_points_cam_m": np.round(sample.result.sticker_points_cam, 6).tolist(),
            "visible": sample.result.visible.tolist(),
            "visible_fraction": np.round(sample.result.visible_fraction, 3).tolist(),
            "state_params": state.params,
            # a path-traced pair: its lights, materials and camera pipeline's draws
            **({"render": sample.result.info} if sample.result.info.get("engine") else {}),
        }
        order = [n for n in self.names if n in self._truth]
        files.append((self.root / "truth.json", self._truth_json(order).encode()))
        if self.frames:
            files.append((self.root / "frames.csv", csv_table(
                ["color", "depth", "time"], [self._frame_rows[n] for n in order]
            ).encode()))
        files.append((self.labels, csv_table(
            ["color", "depth", "label", "variant"], [self._label_rows[n] for n in order]
        ).encode()))
        # the images first, then the listings that name them, labels.csv last: a pair it
        # lists has its truth (and frame) entry, which --resume needs to keep it
        try:
            write_recorded(files, self.command)
        except OutputError as exc:  # not listed: the listings on disk do not name it
            for rows in (self._label_rows, self._frame_rows, self._truth, self._truth_text):
                rows.pop(sample.name, None)
            raise self._failed(exc) from None
        self.written += 1

    def _truth_json(self, order: list[str]) -> str:
        """``truth.json``'s text, ``{"provenance", "images"}`` with ``order``'s entries,
        exactly as ``json.dumps(..., indent=1)`` writes it, from each entry's text made
        once (rewritten after every pair, the whole file would cost a set of N pairs
        N^2 / 2 entries' encoding)."""
        for name in order:
            if name not in self._truth_text:
                self._truth_text[name] = _indented(json.dumps(self._truth[name], indent=1), 2)
        provenance = _indented(json.dumps(self.provenance, indent=1), 1)
        images = ",\n".join(f"  {json.dumps(n)}: {self._truth_text[n]}" for n in order)
        images = f"{{\n{images}\n }}" if order else "{}"
        return f'{{\n "provenance": {provenance},\n "images": {images}\n}}\n'

    def _failed(self, exc: OutputError) -> OutputError:
        """``exc`` naming the pairs kept (those listed before the failed one)."""
        kept = len(self._truth)
        if not kept:
            return OutputError(f"{exc}; no pair was written before it")
        pairs = "the pair" if kept == 1 else f"the {kept} pairs"
        return OutputError(
            f"{exc}; {pairs} written before it are kept and listed in '{self.labels}'"
        )


def _indented(text: str, depth: int) -> str:
    """JSON ``text`` written with ``indent=1`` as it reads nested ``depth`` levels deep
    (its lines after the first moved right by ``depth`` spaces; a JSON string holds no
    raw newline, so every newline is one of the layout's)."""
    return text.replace("\n", "\n" + " " * depth)


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


def _file_identity(path: str) -> tuple[int, int] | str:
    """The file ``path`` names, by its identity on disk, ``(st_dev, st_ino)``: the same
    for two names of one file, whether a symbolic link or a hard link joins them. A path
    that cannot be looked up (missing, a link loop: reading it reports why) is its path
    with symbolic links resolved as far as they go."""
    try:
        st = os.stat(path)
    except (OSError, ValueError):
        return os.path.realpath(path)
    return st.st_dev, st.st_ino


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
    from ..core.classes import CLASS_HINT, CLASS_NAMES, OUTSIDE, VARIANTS, digits_note

    keep, problems = [], []
    seen: dict[tuple[Any, Any], str] = {}  # by the files' identity: links are the same pair
    for pair, at in zip(pairs, where):
        if pair.label == OUTSIDE and pair.variant is not None:
            problems.append(
                LabelProblem(
                    at, "unknown variant",
                    f"{at}: a state outside the twelve ({OUTSIDE}) has no variant, "
                    f"got {pair.variant!r}",
                )
            )
            continue
        if pair.label not in CLASS_NAMES and pair.label != OUTSIDE:
            problems.append(
                LabelProblem(
                    at,
                    "unknown class",
                    f"{at}: class {pair.label!r}{digits_note(pair.label)} is not "
                    f"{CLASS_HINT}",
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
        key = (_file_identity(pair.color), _file_identity(pair.depth))
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


def _outside_or(label: str) -> str:
    """``"none"`` (a state outside the twelve) for that label in any case, else the
    label as written (an unknown class, reported as such)."""
    from ..core.classes import OUTSIDE

    return OUTSIDE if label.strip().lower() == OUTSIDE else label


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
                        class_id_of(label) or _outside_or(label),
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
