"""The frames of a recording, in order: a folder of colour + depth pairs.

A recording is a folder of ``<name>_color.png`` / ``<name>_depth.png`` pairs, in the
order given by a ``frames.csv`` (``color,depth[,time]``, paths relative to the folder)
or, without one, by name. A ``labels.csv`` (the labelled-folder format) labels the
frames, so that a tracker can score itself.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

from .errors import InvalidInputError, UnreadableInputError
from .labelled import LabelledPair, find_labelled_pairs

__all__ = ["Recording", "read_recording"]


@dataclass(frozen=True)
class Recording:
    """The frames of a recording.

    Attributes
    ----------
    frames : tuple of LabelledPair
        In order; ``label`` is ``""`` for an unlabelled frame.
    times : tuple of float or None
        Seconds from ``frames.csv``, None where not given.
    labelled : bool
        Every frame carries a label.
    source : str
        The folder.
    """

    frames: tuple[LabelledPair, ...]
    times: tuple[float | None, ...]
    labelled: bool
    source: str


def _frames_csv(path: Path, root: Path) -> tuple[list[LabelledPair], list[float | None]]:
    pairs, times = [], []
    try:
        with path.open(newline="", encoding="utf-8") as fh:
            reader = csv.DictReader(fh)
            missing = {"color", "depth"} - set(reader.fieldnames or [])
            if missing:
                raise InvalidInputError(
                    f"frames file '{path}' lacks column(s) {', '.join(sorted(missing))}; "
                    "expected color,depth[,time]"
                )
            for k, row in enumerate(reader, start=2):
                if not row.get("color") or not row.get("depth"):
                    raise InvalidInputError(f"frames file '{path}' line {k} is incomplete")
                t = (row.get("time") or "").strip()
                try:
                    times.append(float(t) if t else None)
                except ValueError:
                    raise InvalidInputError(
                        f"frames file '{path}' line {k}: time {t!r} is not a number"
                    ) from None
                pairs.append(LabelledPair(str(root / row["color"]), str(root / row["depth"]), ""))
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise UnreadableInputError(f"cannot read frames file '{path}': {exc}") from None
    return pairs, times


def read_recording(folder: str | Path) -> Recording:
    """The frames of ``folder`` in order, labelled when it has a ``labels.csv``.

    Raises
    ------
    UnreadableInputError, InvalidInputError
        The folder is missing, a CSV file is malformed, or no frame is found.
    """
    root = Path(folder)
    if not root.is_dir():
        raise UnreadableInputError(f"folder '{root}' does not exist or is not a directory")
    listing = root / "frames.csv"
    if listing.is_file():
        pairs, times = _frames_csv(listing, root)
    else:
        pairs = []
        for color in sorted(root.rglob("*_color.png")):
            depth = color.with_name(color.name[: -len("_color.png")] + "_depth.png")
            pairs.append(LabelledPair(str(color), str(depth), ""))
        times = [None] * len(pairs)
    if not pairs:
        raise InvalidInputError(
            f"folder '{root}' holds no frames (no frames.csv and no <name>_color.png files)"
        )
    labelled = False
    if (root / "labels.csv").is_file():
        known, _ = find_labelled_pairs(root, lenient=True)
        by_color = {str(Path(p.color).resolve()): p for p in known}
        found = [by_color.get(str(Path(p.color).resolve())) for p in pairs]
        labelled = all(f is not None for f in found)
        pairs = [
            LabelledPair(p.color, p.depth, f.label, f.variant, f.line) if f else p
            for p, f in zip(pairs, found)
        ]
    return Recording(tuple(pairs), tuple(times), labelled, str(root))
