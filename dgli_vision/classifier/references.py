"""The reference set: one representative state per class and variant.

As in the paper, the representative of a group of simulated states is the sample
nearest (Spearman distance) to the group's centroid. Each reference also keeps how often
each sticker was visible in its group, which the classifier uses as evidence.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ..core.classes import CLASS_NAMES, VARIANTS
from ..core.distance import centred_unit_ranks, pairwise_spearman
from ..core.errors import ReferenceSetError, UnreadableInputError
from ..core.io import guard_outputs, read_json, record_outputs, write_json
from ..core.layout import layout_of_size, sticker_spreads_mm
from ..perception.tips import stage_tip_clear

if TYPE_CHECKING:
    from ..sim.database import StateRecords

__all__ = [
    "FORMAT",
    "Reference",
    "ReferenceSet",
    "build_references",
    "default_references_path",
    "load_references",
    "read_references",
    "references_from_dict",
    "write_references",
]

FORMAT = "dgli-references"
FORMAT_VERSION = 1

#: Where a wheel carries the shipped reference set (copied there by ``setup.py``).
#: Sticker pairs whose distances a reference keeps (16 stickers).
N_PAIRS = 120
PACKAGED_REFERENCES = "core/data/references/default.json"


@dataclass(frozen=True, eq=False)
class Reference:
    """A class representative.

    Attributes
    ----------
    class_id, name : str
    variant : str or None
    coordinates : ndarray, shape (28,)
        dGLI cloth coordinates of the representative (1/m).
    visible_rate : ndarray, shape (16,)
        Fraction of the group's states in which each sticker was visible.
    source : str
        Id of the representative state in its database.
    n_samples : int
        Size of the group.
    lifted_rate : ndarray, shape (16,)
        Fraction of the group's states in which each sticker stood more than
        ``classes.LIFTED_MM`` above the table (on a flap held up).
    stage : str
        ``""`` for a state with every fold laid flat; else the fold in progress and its
        angles (``"rising B over, 50-90 deg"``: below 90 degrees the state is still the
        one before that fold).
    height_range_mm : ndarray, shape (16, 2)
        Lowest and highest height of each sticker above the table over the group's
        states, mm (NaN: not known, as in sets written before heights were kept). A flap
        at 110 degrees stands as high as the fold is wide: a half fold's edge 150-190 mm,
        a strip's 90-120 mm, where their dGLI coordinates are nearly alike.
    past_rate : ndarray, shape (16,)
        Fraction of the group's states in which each sticker stands on a flap turned past
        90 degrees (0 for every state with its folds laid flat).
    footprint_range : ndarray, shape (2,)
        Smallest and largest table area the group's cloth covers, as fractions of the
        flat napkin's area (NaN: not known, as in sets written before it was kept).
    back_rate : ndarray, shape (4,)
        Fraction of the group's states in which each corner A-D shows its back face seen
        from above (on a flap folded over), over the states where its stickers tell
        (:func:`~dgli_vision.perception.handedness.corner_turns`); NaN where none tell,
        or as in sets written before it was kept.
    spread_range_mm : ndarray, shape (120, 2)
        Shortest and longest 3D distance between each pair of stickers (pairs in
        :func:`sticker_pairs` order) over the group's states, mm (NaN: not known, as in
        sets written before it was kept). The dGLI coordinates say how segments wind
        round each other, not how far apart they are: a flat napkin and two corners
        folded to the centre can rank their few known coordinates alike.
    """

    class_id: str
    name: str
    variant: str | None
    coordinates: NDArray[np.float64]
    visible_rate: NDArray[np.float64]
    source: str = ""
    n_samples: int = 1
    stage: str = ""
    lifted_rate: NDArray[np.float64] = field(default_factory=lambda: np.zeros(16))
    height_range_mm: NDArray[np.float64] = field(
        default_factory=lambda: np.full((16, 2), np.nan)
    )
    past_rate: NDArray[np.float64] = field(default_factory=lambda: np.zeros(16))
    footprint_range: NDArray[np.float64] = field(default_factory=lambda: np.full(2, np.nan))
    back_rate: NDArray[np.float64] = field(default_factory=lambda: np.full(4, np.nan))
    spread_range_mm: NDArray[np.float64] = field(
        default_factory=lambda: np.full((N_PAIRS, 2), np.nan)
    )


@dataclass(frozen=True, eq=False)
class ReferenceSet:
    """All references, with their provenance (command, seed, version)."""

    references: tuple[Reference, ...]
    provenance: dict[str, Any] = field(default_factory=dict)
    _stacks: dict[str, NDArray] = field(default_factory=dict, init=False, repr=False)
    _ranked: dict[bytes, NDArray] = field(default_factory=dict, init=False, repr=False)

    def _stacked(self, name: str) -> NDArray[np.float64]:
        """The references' ``name`` stacked, shape (k, ...), read-only; built once (the
        classifier reads them for every frame)."""
        if name not in self._stacks:
            a = np.stack([getattr(r, name) for r in self.references])
            a.flags.writeable = False
            self._stacks[name] = a
        return self._stacks[name]

    def __len__(self) -> int:
        return len(self.references)

    @property
    def napkin_mm(self) -> tuple[float, float] | None:
        """The napkin size (W, H) in mm the set was simulated for; None: the nominal one."""
        size = self.provenance.get("napkin_mm")
        if size is None:
            return None
        return float(size[0]), float(size[1])

    def matrix(self) -> NDArray[np.float64]:
        """Coordinates of all references, shape (k, 28)."""
        return self._stacked("coordinates")

    def ranked(self, known: NDArray[np.bool_]) -> NDArray[np.float64]:
        """The references' coordinates ``known`` (bool, shape (28,)) ranked, centred and
        scaled (:func:`~dgli_vision.core.distance.centred_unit_ranks`), shape
        (k, known.sum()), read-only: what every frame with these coordinates known is
        correlated with. Kept per mask (a camera sees the same few masks frame after
        frame)."""
        key = np.asarray(known, dtype=bool).tobytes()
        out = self._ranked.get(key)
        if out is None:
            sub = self.matrix()[:, np.asarray(known, dtype=bool)]
            if np.isnan(sub).any():
                raise ValueError("references contain NaN coordinates")
            out = centred_unit_ranks(sub)
            out.flags.writeable = False
            if len(self._ranked) >= 64:  # at most ~4 MB (64 x 304 x 28 floats)
                self._ranked.clear()
            self._ranked[key] = out
        return out

    def visible_rates(self) -> NDArray[np.float64]:
        """Sticker visibility rates of all references, shape (k, 16)."""
        return self._stacked("visible_rate")

    def past_rates(self) -> NDArray[np.float64]:
        """Rates of each sticker standing on a flap past vertical, shape (k, 16)."""
        return self._stacked("past_rate")

    def height_ranges(self) -> NDArray[np.float64]:
        """Lowest and highest height of each sticker, mm, shape (k, 16, 2)."""
        return self._stacked("height_range_mm")

    def class_codes(self) -> NDArray[np.intp]:
        """A number for each reference's class (equal numbers, equal classes), shape (k,),
        read-only; built once."""
        if "class_codes" not in self._stacks:
            ids = [r.class_id for r in self.references]
            a = np.unique(np.array(ids, dtype=object), return_inverse=True)[1].ravel()
            a.flags.writeable = False
            self._stacks["class_codes"] = a
        return self._stacks["class_codes"]

    def height_bounds(self) -> tuple[NDArray[np.float64], NDArray[np.float64], bool]:
        """The height ranges split for the classifier's per-frame use: lows and highs,
        one row per sticker, shape (16, k) each (contiguous: a frame's terms take the rows
        of the stickers it tells), and whether every range is known; built once."""
        if "height_lo" not in self._stacks:
            r = self.height_ranges()
            for name, a in (
                ("height_lo", np.ascontiguousarray(r[..., 0].T)),
                ("height_hi", np.ascontiguousarray(r[..., 1].T)),
                ("height_kept", np.asarray(np.isfinite(r).all())),
            ):
                a.flags.writeable = False
                self._stacks[name] = a
        s = self._stacks
        return s["height_lo"], s["height_hi"], bool(s["height_kept"])

    def footprint_ranges(self) -> NDArray[np.float64]:
        """Smallest and largest footprint (fraction of the napkin's area), shape (k, 2)."""
        return self._stacked("footprint_range")

    def spread_ranges(self) -> NDArray[np.float64]:
        """Shortest and longest distance of each sticker pair, mm, shape (k, 120, 2)."""
        return self._stacked("spread_range_mm")

    def spread_bounds(self) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
        """The sticker-pair ranges split for the classifier's per-frame use: lows and
        highs, one row per pair, shape (120, k) each (contiguous: a frame's terms take the
        rows of the pairs it tells), and which pairs every reference keeps a range of,
        shape (120,); built once."""
        if "spread_lo" not in self._stacks:
            r = self.spread_ranges()
            for name, a in (
                ("spread_lo", np.ascontiguousarray(r[..., 0].T)),
                ("spread_hi", np.ascontiguousarray(r[..., 1].T)),
                ("spread_kept", np.isfinite(r).all(axis=(0, 2))),
            ):
                a.flags.writeable = False
                self._stacks[name] = a
        return self._stacks["spread_lo"], self._stacks["spread_hi"], self._stacks["spread_kept"]

    def by_row(self, name: str) -> NDArray[np.float64]:
        """The references' table ``name`` (the rates ``"lifted_rate"``, ``"past_rate"``,
        ``"back_rate"``, or ``"tip_clear"``: :meth:`tip_clear`) with one row per sticker
        or corner, shape (16 or 4, k), contiguous, read-only; built once (a frame's terms
        take the rows it tells, and sum over rows, not over short columns)."""
        key = name + " by row"
        if key not in self._stacks:
            table = self.tip_clear() if name == "tip_clear" else self._stacked(name)
            a = np.ascontiguousarray(table.T)
            a.flags.writeable = False
            self._stacks[key] = a
        return self._stacks[key]

    def tip_clear(self) -> NDArray[np.float64]:
        """The share of each corner's tip place each reference leaves bare table, shape
        (k, 4) (:func:`~dgli_vision.perception.tips.stage_tip_clear`, at the napkin size
        the references were built for); built once."""
        if "tip_clear" not in self._stacks:
            layout = layout_of_size(self.napkin_mm)
            a = np.array(
                [stage_tip_clear(r.class_id, r.variant, r.stage, layout) for r in self.references]
            )
            a.flags.writeable = False
            self._stacks["tip_clear"] = a
        return self._stacks["tip_clear"]

    def back_rates(self) -> NDArray[np.float64]:
        """Rates of each corner showing its back face, shape (k, 4) (NaN: not known)."""
        return self._stacked("back_rate")

    def to_json(self) -> dict[str, Any]:
        """The JSON object of the set (what ``references/default.json`` holds;
        :func:`references_from_dict` reads it back)."""
        return {
            "format": FORMAT,
            "version": FORMAT_VERSION,
            "coordinates": "dGLI of segment pairs 0-1, 0-2, ..., 6-7 (SPEC section 2), 1/m",
            "provenance": self.provenance,
            "references": [
                {
                    "class": r.class_id,
                    "name": r.name,
                    "variant": r.variant,
                    "source": r.source,
                    "n_samples": r.n_samples,
                    **({"stage": r.stage} if r.stage else {}),
                    "coordinates": [round(float(v), 10) for v in r.coordinates],
                    "visible_rate": [round(float(v), 4) for v in r.visible_rate],
                    **(
                        {"lifted_rate": [round(float(v), 4) for v in r.lifted_rate]}
                        if r.lifted_rate.any()
                        else {}
                    ),
                    **(
                        {"past_rate": [round(float(v), 4) for v in r.past_rate]}
                        if r.past_rate.any()
                        else {}
                    ),
                    **(
                        {"height_range_mm": [[round(float(v), 1) for v in lh]
                                             for lh in r.height_range_mm]}
                        if np.isfinite(r.height_range_mm).all()
                        else {}
                    ),
                    **(
                        {"footprint_range": [round(float(v), 4) for v in r.footprint_range]}
                        if np.isfinite(r.footprint_range).all()
                        else {}
                    ),
                    **(
                        {"back_rate": [round(float(v), 4) if np.isfinite(v) else None
                                       for v in r.back_rate]}
                        if np.isfinite(r.back_rate).any()
                        else {}
                    ),
                    **(
                        {"spread_range_mm": [[round(float(v)) for v in lh]
                                             for lh in r.spread_range_mm]}
                        if np.isfinite(r.spread_range_mm).all()
                        else {}
                    ),
                }
                for r in self.references
            ],
        }


def build_references(
    records: StateRecords, *, provenance: dict[str, Any] | None = None
) -> ReferenceSet:
    """Pick the representative of every (class, variant, stage) group of ``records``.

    States with a fold in progress (``records.stages``) form groups of their own, one
    per fold and angle bin, so that a frame taken mid-fold finds a near reference of its
    class.

    Parameters
    ----------
    records : StateRecords
        Simulated states with all stickers known.
    provenance : dict, optional, keyword-only
        How the records were made; stored with the set.

    Returns
    -------
    ReferenceSet
        References in class, variant, then stage order.
    """
    groups: dict[tuple[str, str | None, str], list[int]] = {}
    for i, key in enumerate(zip(records.classes, records.variants, records.stages)):
        groups.setdefault(key, []).append(i)
    heights = records.sticker_points[..., 2] * 1e3
    back = records.corner_turns
    spread = sticker_spreads_mm(records.sticker_points * 1e3)
    past = records.lifted & records.past_vertical[:, None]
    refs = []
    for (class_id, variant, stage), members in sorted(
        groups.items(), key=lambda kv: (kv[0][0], kv[0][1] or "", kv[0][2])
    ):
        coords = records.coordinates[members]
        centroid = coords.mean(axis=0, keepdims=True)
        best = members[int(np.argmin(pairwise_spearman(coords, centroid)[:, 0]))]
        refs.append(
            Reference(
                class_id=class_id,
                name=CLASS_NAMES[class_id],
                variant=variant,
                coordinates=records.coordinates[best].copy(),
                # a sticker on a flap held up is seen or unknown, never evidence of a fold
                visible_rate=(records.visible | records.unknown)[members].mean(axis=0),
                source=records.ids[best],
                n_samples=len(members),
                stage=stage,
                lifted_rate=records.lifted[members].mean(axis=0),
                height_range_mm=np.stack([heights[members].min(axis=0),
                                          heights[members].max(axis=0)], axis=1),
                past_rate=past[members].mean(axis=0),
                footprint_range=np.array([records.footprint[members].min(),
                                          records.footprint[members].max()]),
                back_rate=_back_rate(back[members]),
                spread_range_mm=np.stack([spread[members].min(axis=0),
                                          spread[members].max(axis=0)], axis=1),
            )
        )
    return ReferenceSet(tuple(refs), dict(provenance or {}))


def _back_rate(turns: NDArray[np.float64]) -> NDArray[np.float64]:
    """Share of -1 among the told (non-zero) turns of each corner, shape (4,); NaN where
    none tells."""
    told = (turns != 0).sum(axis=0)
    back = (turns < 0).sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(told > 0, back / np.maximum(told, 1), np.nan)


def _optional_array(
    item: dict[str, Any],
    key: str,
    shape: tuple[int, ...],
    missing: float,
    source: str,
    k: int,
    what: str,
) -> NDArray[np.float64]:
    """``item[key]`` as an array of ``shape``, filled with ``missing`` when the field is
    absent (sets written before it was kept).

    Raises
    ------
    ReferenceSetError
        When the field is there but not numbers of that shape.
    """
    value = item.get(key)
    if value is None:
        return np.full(shape, missing)
    try:
        out = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        out = np.zeros(0)
    if out.shape != shape:
        raise ReferenceSetError(f"'{source}': reference {k} needs {shape[0]} {what}")
    return out


def references_from_dict(data: Any, *, source: str = "references") -> ReferenceSet:
    """Validate and load the parsed JSON of a reference set.

    Raises
    ------
    ReferenceSetError
        Naming ``source`` and what is wrong.
    """
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise ReferenceSetError(
            f'\'{source}\' is not a dgli reference set (no "format": "{FORMAT}")'
        )
    if data.get("version") != FORMAT_VERSION:
        raise ReferenceSetError(
            f"'{source}' has reference format version {data.get('version')!r}; "
            f"expected {FORMAT_VERSION}"
        )
    refs = []
    for k, item in enumerate(data.get("references") or []):
        try:
            class_id = str(item["class"])
            coords = np.asarray(item["coordinates"], dtype=np.float64)
            rate = np.asarray(item["visible_rate"], dtype=np.float64)
        except (KeyError, TypeError, ValueError) as exc:
            raise ReferenceSetError(f"'{source}': reference {k} is malformed ({exc})") from None
        if class_id not in CLASS_NAMES:
            raise ReferenceSetError(f"'{source}': reference {k} has unknown class {class_id!r}")
        variant = item.get("variant")
        if variant not in VARIANTS[class_id]:
            allowed = ", ".join(v or "null" for v in VARIANTS[class_id])
            raise ReferenceSetError(
                f"'{source}': reference {k} of class {class_id} has variant {variant!r}, "
                f"which is not one of class {class_id}'s ({allowed})"
            )
        if coords.shape != (28,) or not np.isfinite(coords).all():
            raise ReferenceSetError(f"'{source}': reference {k} needs 28 finite coordinates")
        if rate.shape != (16,):
            raise ReferenceSetError(f"'{source}': reference {k} needs 16 visibility rates")
        lifted = _optional_array(item, "lifted_rate", (16,), 0.0, source, k, "lifted rates")
        past = _optional_array(
            item, "past_rate", (16,), 0.0, source, k, "past-vertical rates"
        )
        heights = _optional_array(
            item, "height_range_mm", (16, 2), np.nan, source, k,
            "height ranges [lowest, highest]",
        )
        footprint = _optional_array(
            item, "footprint_range", (2,), np.nan, source, k,
            "footprint fractions [smallest, largest]",
        )
        back = _optional_array(
            item, "back_rate", (4,), np.nan, source, k, "back-face rates (or null)"
        )
        spread = _optional_array(
            item, "spread_range_mm", (N_PAIRS, 2), np.nan, source, k,
            "sticker-pair distance ranges [shortest, longest]",
        )
        if not ((back >= 0) & (back <= 1) | np.isnan(back)).all():
            raise ReferenceSetError(f"'{source}': reference {k} has back-face rates outside 0-1")
        for name, rates in (("visible", rate), ("lifted", lifted), ("past-vertical", past)):
            if not ((rates >= 0) & (rates <= 1)).all():  # NaN fails too
                raise ReferenceSetError(
                    f"'{source}': reference {k} has {name} rates outside 0-1 (or not numbers)"
                )
        n_samples = item.get("n_samples", 1)
        if not isinstance(n_samples, int) or isinstance(n_samples, bool) or n_samples < 1:
            raise ReferenceSetError(
                f"'{source}': reference {k} has n_samples {n_samples!r}; expected a positive "
                "integer"
            )
        refs.append(
            Reference(
                class_id,
                CLASS_NAMES[class_id],
                variant,
                coords,
                rate,
                str(item.get("source", "")),
                n_samples,
                str(item.get("stage") or ""),
                lifted,
                heights,
                past,
                footprint,
                back,
                spread,
            )
        )
    if len({r.class_id for r in refs}) < 2:
        raise ReferenceSetError(f"'{source}' holds fewer than two classes")
    return ReferenceSet(tuple(refs), dict(data.get("provenance") or {}))


def default_references_path() -> Path:
    """The shipped reference set.

    In order: ``$DGLI_REFERENCES``; ``references/default.json`` of the source tree this
    package runs from (a clone); the copy packaged inside an installed wheel.
    """
    env = os.environ.get("DGLI_REFERENCES")
    if env:
        return Path(env)
    tree = Path(__file__).resolve().parents[2]  # dgli_vision/classifier/references.py
    if (tree / "pyproject.toml").is_file() and (tree / "references" / "default.json").is_file():
        return tree / "references" / "default.json"
    return Path(str(resources.files("dgli_vision").joinpath(PACKAGED_REFERENCES)))


def load_references(path: str | Path | None = None) -> ReferenceSet:
    """Load a reference set file (default: :func:`default_references_path`).

    Raises
    ------
    UnreadableInputError, ReferenceSetError
        Missing, unreadable or malformed file.
    """
    if path is None:
        path = default_references_path()
        if not path.is_file():
            raise UnreadableInputError(
                f"no reference set at '{path}': give --references FILE or set DGLI_REFERENCES"
            )
    return _warmed(read_references(path))


def _warmed(refs: ReferenceSet) -> ReferenceSet:
    """``refs`` with what a frame classified would otherwise build or import on its first
    use, in the middle of a real-time loop: the stacked per-reference arrays the
    classifier reads (about 3 ms), ``numpy.ma`` (about 9 ms: ``np.unique``, which the
    perception calls every frame, imports it on its first call) and the tips' table
    (:meth:`ReferenceSet.tip_clear`, about 9 ms, read by the first frame that tells its
    corners' tip places: it doubled that frame's time)."""
    import numpy.ma  # noqa: F401

    for name in ("coordinates", "visible_rate", "lifted_rate", "past_rate", "back_rate",
                 "footprint_range"):
        refs._stacked(name)
    refs.class_codes()
    refs.height_bounds()
    refs.spread_bounds()
    for name in ("lifted_rate", "past_rate", "back_rate", "tip_clear"):
        refs.by_row(name)
    layout_of_size(refs.napkin_mm)
    refs.tip_clear()
    return refs


def read_references(path: str | Path) -> ReferenceSet:
    """Load a reference set file (see :mod:`dgli_vision.classifier.references`)."""
    return references_from_dict(read_json(path, what="reference set"), source=str(path))


def write_references(path: str | Path, refs: ReferenceSet, *, overwrite: bool = False) -> None:
    """Write a reference set as JSON (replacing a file only if dgli wrote it, or with
    ``overwrite``)."""
    guard_outputs([path], overwrite=overwrite)
    write_json(path, refs.to_json())
    record_outputs([path], str(refs.provenance.get("command", "")))
