"""Label an episode: every frame's state, smoothed over the episode as ``dgli track`` does.

The work comes in parts (:func:`label_part`): a part reads the episode, finds its
material coordinates and labels a run of whole :data:`~.observe.BLOCK`-frame blocks, so
that however an episode is split (``-j``, a Dask cluster) every frame gets the same
numbers. :func:`assemble` joins the parts of an episode, takes each frame's verdict and
smooths the states with the tracker's hidden Markov model over the fold graph.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..analysis.track import change_frames, smooth
from ..classifier.classify import MIN_CONFIDENCE, MIN_COORDINATES
from ..classifier.references import ReferenceSet, load_references
from ..core.classes import CLASS_NAMES
from ..core.errors import DgliError
from .distances import frame_distances, verdicts
from .episodes import ReadOptions, read_episode, read_rest
from .material import cloth_material
from .observe import BLOCK, observe_frames, place_stickers
from .predicates import hull_area_diagonal, predicates

__all__ = [
    "EpisodeFailure",
    "EpisodeLabels",
    "FrameLabel",
    "PartResult",
    "assemble",
    "cached_references",
    "label_part",
    "progress_of",
]


@dataclass(frozen=True, eq=False)
class PartResult:
    """The frames ``start..stop`` of one episode, or why the episode could not be read.

    Attributes
    ----------
    path : str
    part : int
    start, stop : int
    distances : ndarray, shape (stop - start, K)
        To every reference; NaN rows for frames with too little seen.
    n_unknown, n_known : ndarray of int, shape (stop - start,)
        Stickers not told (for the confidence) and coordinates used, per frame.
    info : dict
        The episode's frames, vertices, grid and size.
    omnigibson : ndarray of bool, shape (stop - start, 2), optional
        OmniGibson's ``Folded`` and ``Unfolded`` of each frame (:mod:`.predicates`).
    error : str or None
        The one-line error that stopped the episode.
    """

    path: str
    part: int
    start: int = 0
    stop: int = 0
    distances: NDArray[np.float64] | None = None
    n_unknown: NDArray[np.intp] | None = None
    n_known: NDArray[np.intp] | None = None
    info: dict[str, Any] | None = None
    error: str | None = None
    omnigibson: NDArray[np.bool_] | None = None


@lru_cache(maxsize=4)
def cached_references(path: str | None) -> ReferenceSet:
    """The reference set of ``path`` (None: the shipped one), loaded once per process."""
    return load_references(path)


def _blocks(n_frames: int, part: int, n_parts: int) -> tuple[int, int]:
    """Frames ``(start, stop)`` of part ``part`` of ``n_parts``: whole blocks."""
    n_blocks = -(-n_frames // BLOCK)
    bounds = np.linspace(0, n_blocks, n_parts + 1).round().astype(int)
    return min(bounds[part] * BLOCK, n_frames), min(bounds[part + 1] * BLOCK, n_frames)


def label_part(
    path: str,
    options: ReadOptions,
    references_path: str | None,
    part: int = 0,
    n_parts: int = 1,
) -> PartResult:
    """Read an episode and label part ``part`` of ``n_parts`` of its frames.

    Never raises for bad input: the error is in :attr:`PartResult.error` (a batch goes
    on past a bad episode). The references are loaded once per process.
    """
    try:
        refs = cached_references(references_path)
        episode = read_episode(path, options)
        rest = read_rest(options)
        material = cloth_material(episode, rest, options.size_mm)
        placement = place_stickers(material, refs.napkin_mm)
    except DgliError as exc:
        return PartResult(str(path), part, error=str(exc))
    except ValueError as exc:  # the layout refuses a cloth too small for the stickers
        return PartResult(str(path), part, error=f"'{path}': {exc}; are --units right?")
    start, stop = _blocks(episode.n_frames, part, n_parts)
    rest = episode.frames(0, 1)[0] if rest is None else rest
    area, diagonal = hull_area_diagonal(rest[None, material.coarse_ids, :2] * material.scale)
    flat = (float(area[0]), float(diagonal[0]))
    dist, n_unknown, n_known, og = [], [], [], []
    for a in range(start, stop, BLOCK):
        b = min(a + BLOCK, stop)
        frames = episode.frames(a, b) * material.scale
        ev = observe_frames(frames, material, placement)
        dist.append(frame_distances(ev, refs))
        n_unknown.append((ev.unknown & ~np.isfinite(ev.past)).sum(axis=1))
        n_known.append(ev.known_coordinates().sum(axis=1))
        pred = predicates(frames[:, material.coarse_ids], material.coarse_faces, flat)
        og.append(np.column_stack([pred.folded, pred.unfolded]))
    k = len(refs)
    info = {
        "n_frames": episode.n_frames,
        "vertices": episode.n_vertices,
        "grid": list(episode.grid) if episode.grid else None,
        "size_mm": list(material.size_mm),
    }
    return PartResult(
        str(path),
        part,
        start,
        stop,
        np.concatenate(dist) if dist else np.zeros((0, k)),
        np.concatenate(n_unknown) if n_unknown else np.zeros(0, np.intp),
        np.concatenate(n_known) if n_known else np.zeros(0, np.intp),
        info,
        omnigibson=np.concatenate(og) if og else np.zeros((0, 2), bool),
    )


_STAGE = re.compile(r"(settling|rising) (.+?), (\d+)-(\d+) deg")


def progress_of(stage: str) -> dict[str, Any] | None:
    """A reference's fold in progress as ``{"fold", "past_90", "angle_deg"}``; None for
    a state with every fold laid flat."""
    m = _STAGE.fullmatch(stage or "")
    if m is None:
        return None
    return {
        "fold": m.group(2),
        "past_90": m.group(1) == "settling",
        "angle_deg": [int(m.group(3)), int(m.group(4))],
    }


@dataclass(frozen=True)
class FrameLabel:
    """One frame's state.

    Attributes
    ----------
    index : int
    class_id, variant : str or None
        The frame's own verdict (None: cannot tell, see ``note``).
    progress : dict or None
        The fold in progress of the nearest reference (:func:`progress_of`).
    confidence : float or None
    distance : float or None
        To the nearest reference (None: too little seen).
    smoothed_class, smoothed_variant : str, str or None
        The state after smoothing over the episode.
    note : str or None
        Why there is no verdict.
    omnigibson : tuple of bool or None
        OmniGibson's ``Folded`` and ``Unfolded`` on the same frame, for comparison.
    """

    index: int
    class_id: str | None
    variant: str | None
    progress: dict[str, Any] | None
    confidence: float | None
    distance: float | None
    smoothed_class: str
    smoothed_variant: str | None
    note: str | None = None
    omnigibson: tuple[bool, bool] | None = None

    def to_dict(self) -> dict[str, Any]:
        """The frame's JSON object (the names of ``dgli label --json``)."""
        return {
            "index": self.index,
            "class": self.class_id,
            "variant": self.variant,
            "progress": self.progress,
            "confidence": self.confidence,
            "smoothed": {"class": self.smoothed_class, "variant": self.smoothed_variant},
            "distance": self.distance,
            "note": self.note,
            "omnigibson": None
            if self.omnigibson is None
            else {"folded": self.omnigibson[0], "unfolded": self.omnigibson[1]},
        }


@dataclass(frozen=True)
class EpisodeLabels:
    """An episode's frames and the changes of its smoothed state.

    ``changes``: (frame, (class, variant) before, (class, variant) after).
    """

    path: str
    frames: tuple[FrameLabel, ...]
    changes: tuple[tuple[int, tuple[str, str | None], tuple[str, str | None]], ...]
    info: dict[str, Any]

    def to_dict(self) -> dict[str, Any]:
        """The episode's JSON object."""
        return {
            "path": self.path,
            **self.info,
            "frames": [f.to_dict() for f in self.frames],
            "changes": [
                {
                    "frame": t,
                    "from": {"class": a[0], "variant": a[1]},
                    "to": {"class": b[0], "variant": b[1]},
                }
                for t, a, b in self.changes
            ],
        }


@dataclass(frozen=True)
class EpisodeFailure:
    """An episode that could not be labelled, and the one-line reason."""

    path: str
    error: str


def _note(conf: float, best: int, refs: ReferenceSet, n_known: int) -> str | None:
    if best < 0:
        return f"too little seen: {n_known} cloth coordinates known, need {MIN_COORDINATES}"
    if conf < MIN_CONFIDENCE:
        r = refs.references[best]
        return (
            f"cannot tell: confidence {conf:.2f} < {MIN_CONFIDENCE:.2f} "
            f"(nearest {r.class_id} {r.name}{' ' + r.variant if r.variant else ''})"
        )
    return None


def assemble(parts: list[PartResult], references: ReferenceSet) -> EpisodeLabels | EpisodeFailure:
    """Join the parts of one episode (any order), classify and smooth its frames."""
    bad = next((p for p in parts if p.error is not None), None)
    if bad is not None:
        return EpisodeFailure(bad.path, bad.error)
    parts = sorted(parts, key=lambda p: p.start)
    dist = np.concatenate([p.distances for p in parts])
    n_unknown = np.concatenate([p.n_unknown for p in parts])
    n_known = np.concatenate([p.n_known for p in parts])
    og = np.concatenate([p.omnigibson for p in parts])
    v = verdicts(dist, references, n_unknown, n_known)
    states, _ = smooth(dist, references)
    frames = []
    for t in range(len(dist)):
        best, conf = int(v.best[t]), float(v.confidence[t])
        note = _note(conf, best, references, int(n_known[t]))
        ref = references.references[best] if best >= 0 else None
        answer = ref if note is None else None
        frames.append(
            FrameLabel(
                index=t,
                class_id=answer.class_id if answer else None,
                variant=answer.variant if answer else None,
                progress=progress_of(answer.stage) if answer else None,
                confidence=round(conf, 4) if best >= 0 else None,
                distance=round(float(v.distance[t]), 6) if best >= 0 else None,
                smoothed_class=states[t][0],
                smoothed_variant=states[t][1],
                note=note,
                omnigibson=(bool(og[t, 0]), bool(og[t, 1])),
            )
        )
    changes = tuple((t, states[t - 1], states[t]) for t in change_frames(states))
    return EpisodeLabels(parts[0].path, tuple(frames), changes, dict(parts[0].info or {}))


def state_text(key: tuple[str, str | None]) -> str:
    """``"02 corner-over A"``."""
    return f"{key[0]} {CLASS_NAMES[key[0]]}" + (f" {key[1]}" if key[1] else "")
