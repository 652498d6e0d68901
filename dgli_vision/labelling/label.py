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
from ..core.classes import CLASS_NAMES, LANDING_PAIRS
from ..core.errors import DgliError
from ..core.fold_graph import folds_of
from ..core.json_ready import json_ready
from ..core.layout import NapkinLayout, layout_of_size
from .distances import frame_distances, verdicts
from .episodes import ReadOptions, read_episode, read_rest
from .fold_mesh import mesh_flaps, mesh_fold_geometry
from .goal import GoalSpec, evaluate_goal
from .material import cloth_material, front_share
from .observe import BLOCK, observe_frames, place_stickers
from .predicates import hull_area_diagonal, predicates

__all__ = [
    "BACK_UP_SHARE",
    "BELOW_TABLE_SHARE",
    "TABLE_TOLERANCE_MM",
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
    below_mm : ndarray, shape (stop - start,), optional
        How far each frame's lowest point lies below the table (the rest frame's lowest
        point), mm (0 or less: on or above it).
    front : ndarray, shape (stop - start,), optional
        Each frame's :func:`~.material.front_share` (-1: the cloth lies turned over).
    flaps : list, optional
        Each frame's flaps found on the mesh (:meth:`~.fold_mesh.MeshFlap.to_json`).
    last : dict, optional
        In the part that holds the episode's last frame: ``{"position", "rest", "uv",
        "flaps"}`` (metres, metres, mm, its flaps) for ``--goal``.
    stickers : tuple of ndarray, optional
        Each frame's sticker centres (stop - start, 16, 3; metres, z up), which a camera
        above sees (stop - start, 16), which stand (1), lie (0) or are not told (NaN)
        and their heights above the table (mm at the references' napkin size; NaN not
        told) (stop - start, 16): for the state fit of each frame's verdict.
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
    below_mm: NDArray[np.float64] | None = None
    stickers: tuple[NDArray[np.float64], ...] | None = None
    front: NDArray[np.float64] | None = None
    flaps: list[list[dict[str, Any]]] | None = None
    last: dict[str, Any] | None = None


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
        material = cloth_material(episode, rest, options.size_mm, units=options.units)
    except DgliError as exc:
        return PartResult(str(path), part, error=str(exc))
    try:
        placement = place_stickers(material, refs.napkin_mm)
    except ValueError as exc:  # the layout refuses a cloth too small for the stickers
        return PartResult(str(path), part, error=f"'{path}': {exc}; are --units right?")
    except DgliError as exc:
        return PartResult(str(path), part, error=str(exc))
    start, stop = _blocks(episode.n_frames, part, n_parts)
    rest = episode.frames(0, 1)[0] if rest is None else rest
    table = float(rest[:, 2].min()) * material.scale
    area, diagonal = hull_area_diagonal(rest[None, material.coarse_ids, :2] * material.scale)
    flat = (float(area[0]), float(diagonal[0]))
    dist, n_unknown, n_known, og, below, front = [], [], [], [], [], []
    xyz, seen, standing, heights = [], [], [], []
    flaps: list[list[dict[str, Any]]] = []
    for a in range(start, stop, BLOCK):
        b = min(a + BLOCK, stop)
        frames = episode.frames(a, b) * material.scale
        ev = observe_frames(frames, material, placement)
        dist.append(frame_distances(ev, refs))
        xyz.append(ev.points_m)
        seen.append(ev.evidence.visible)
        standing.append(ev.evidence.lifted)
        heights.append(ev.evidence.heights_mm)
        n_unknown.append((ev.evidence.unknown & ~np.isfinite(ev.evidence.past)).sum(axis=1))
        n_known.append(ev.known_coordinates().sum(axis=1))
        coarse = frames[:, material.coarse_ids]
        pred = predicates(coarse, material.coarse_faces, flat)
        og.append(np.column_stack([pred.folded, pred.unfolded]))
        below.append((table - frames[..., 2].min(axis=1)) * 1e3)
        front.append(front_share(coarse, material.coarse_faces))
        if options.geometry:
            flaps += [[f.to_json() for f in mesh_flaps(pos, material)] for pos in frames]
        else:
            flaps += [[] for _ in frames]
    k = len(refs)
    info = {
        "n_frames": episode.n_frames,
        "vertices": episode.n_vertices,
        "grid": list(episode.grid) if episode.grid else None,
        "size_mm": list(material.size_mm),
    }

    last = None
    if stop == episode.n_frames and stop > start:
        final = episode.frames(stop - 1, stop)[0] * material.scale
        last = {"position": final, "rest": rest * material.scale, "uv": material.uv,
                "flaps": [f.to_json() for f in mesh_flaps(final, material)]}

    def joined(arrays: list, empty: NDArray) -> NDArray:
        return np.concatenate(arrays) if arrays else empty

    return PartResult(
        str(path),
        part,
        start,
        stop,
        joined(dist, np.zeros((0, k))),
        joined(n_unknown, np.zeros(0, np.intp)),
        joined(n_known, np.zeros(0, np.intp)),
        info,
        omnigibson=joined(og, np.zeros((0, 2), bool)),
        below_mm=joined(below, np.zeros(0)),
        front=joined(front, np.zeros(0)),
        flaps=flaps if options.geometry else None,
        last=last,
        stickers=(
            joined(xyz, np.zeros((0, 16, 3))), joined(seen, np.zeros((0, 16), bool)),
            joined(standing, np.zeros((0, 16))), joined(heights, np.zeros((0, 16))),
        ),
    )


#: A frame whose lowest point lies more than this (mm) below the rest frame's lowest
#: point (the table) is below the table: no cloth can be, unless the up axis's sign is
#: wrong (flaps folded over then hang under the table, wrinkles point down).
TABLE_TOLERANCE_MM = 1.0
#: An episode with at least this share of its frames below the table fails.
BELOW_TABLE_SHARE = 0.1
#: A frame whose :func:`~.material.front_share` is below this lies back face up (more
#: than 65% of it turned over: every fold turns at most half the cloth).
BACK_UP_SHARE = -0.3

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
    folds : tuple of dict
        The geometry of each fold of the frame's state (its verdict, else the smoothed
        state), measured on the mesh: the keys of a verdict's fold (``"fold"``,
        ``legs_mm``, ``tip_mm``, ``inset_mm``...; ``geometry_from`` ``"mesh"``).
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
    folds: tuple[dict[str, Any], ...] = ()

    def to_json(self) -> dict[str, Any]:
        """The frame's JSON object (the names of ``dgli label --json``)."""
        return json_ready({
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
            "folds": list(self.folds),
        })


@dataclass(frozen=True)
class EpisodeLabels:
    """An episode's frames and the changes of its smoothed state.

    ``changes``: (frame, (class, variant) before, (class, variant) after).
    """

    path: str
    frames: tuple[FrameLabel, ...]
    changes: tuple[tuple[int, tuple[str, str | None], tuple[str, str | None]], ...]
    info: dict[str, Any]
    goal: dict[str, Any] | None = None

    def to_json(self) -> dict[str, Any]:
        """The episode's JSON object (``goal``: with ``--goal``, see
        :func:`~.goal.evaluate_goal`)."""
        return json_ready({
            "path": self.path,
            **self.info,
            **({"goal": self.goal} if self.goal is not None else {}),
            "frames": [f.to_json() for f in self.frames],
            "changes": [
                {
                    "frame": t,
                    "from": {"class": a[0], "variant": a[1]},
                    "to": {"class": b[0], "variant": b[1]},
                }
                for t, a, b in self.changes
            ],
        })


@dataclass(frozen=True)
class EpisodeFailure:
    """An episode that could not be labelled, and the one-line reason."""

    path: str
    error: str


def _note(conf: float, best: int, refs: ReferenceSet, n_known: int) -> str | None:
    if best < 0:
        return f"too little seen: {n_known} cloth coordinates known, need {MIN_COORDINATES}"
    r = refs.references[best]
    pair = next((p for p in LANDING_PAIRS if r.class_id in p), None)
    moving = progress_of(r.stage)
    # the flap held up is one of the two corners whose landing tells the pair apart
    if pair is not None and moving is not None and moving["fold"][0] in (r.variant or "")[:2]:
        a, b = sorted(pair)
        return (
            f"cannot tell: a flap held up ({r.stage}): {a} {CLASS_NAMES[a]} and "
            f"{b} {CLASS_NAMES[b]} differ only in where it lands"
        )
    if conf < MIN_CONFIDENCE:
        r = refs.references[best]
        return (
            f"cannot tell: confidence {conf:.2f} < {MIN_CONFIDENCE:.2f} "
            f"(nearest {r.class_id} {r.name}{' ' + r.variant if r.variant else ''})"
        )
    return None


def _frame_list(flags: NDArray[np.bool_], most: int = 5) -> str:
    """``frames 3, 4, 9 and 2 more``."""
    ids = np.flatnonzero(flags)
    text = ", ".join(str(int(t)) for t in ids[:most])
    more = f" and {len(ids) - most} more" if len(ids) > most else ""
    return f"frame{'s' if len(ids) > 1 else ''} {text}{more}"


def _layer_notes(
    path: str, below: NDArray[np.float64], front: NDArray[np.float64]
) -> tuple[list[str | None], str | None]:
    """Each frame's note when the cloth lies below the table or turned over (None:
    neither), and the episode's error when so many frames lie below the table that the
    up axis's sign must be wrong."""
    low = below > TABLE_TOLERANCE_MM
    error = None
    if low.sum() and low.mean() >= BELOW_TABLE_SHARE:
        error = (
            f"'{path}': {_frame_list(low)} ({int(low.sum())} of {len(low)}) lie up to "
            f"{float(below.max()):.1f} mm below the table (the rest frame's lowest point): "
            "is the sign of --up-axis right?"
        )
    notes: list[str | None] = []
    for t in range(len(below)):
        if low[t]:
            notes.append(
                f"cannot tell: the cloth lies {below[t]:.1f} mm below the table (the rest "
                "frame's lowest point): is the sign of --up-axis right?"
            )
        elif front[t] < BACK_UP_SHARE:
            notes.append(
                f"cannot tell: back face up ({(1 - front[t]) / 2:.0%} of the cloth lies "
                "turned over)"
            )
        else:
            notes.append(None)
    return notes, error


def assemble(
    parts: list[PartResult], references: ReferenceSet, goal: GoalSpec | None = None
) -> EpisodeLabels | EpisodeFailure:
    """Join the parts of one episode (any order), classify and smooth its frames, and
    measure each frame's folds on the mesh; with ``goal``, judge the last frame against
    it (:func:`~.goal.evaluate_goal`).

    A frame lying below the table or turned over (back face up) gets no verdict (a note
    says which); an episode with :data:`BELOW_TABLE_SHARE` of its frames below the table
    fails (its up axis has the wrong sign)."""
    bad = next((p for p in parts if p.error is not None), None)
    if bad is not None:
        return EpisodeFailure(bad.path, bad.error)
    parts = sorted(parts, key=lambda p: p.start)
    dist = np.concatenate([p.distances for p in parts])
    n_unknown = np.concatenate([p.n_unknown for p in parts])
    n_known = np.concatenate([p.n_known for p in parts])
    og = np.concatenate([p.omnigibson for p in parts])
    below = np.concatenate([p.below_mm for p in parts])
    front = np.concatenate([p.front for p in parts])
    flaps = [f for p in parts for f in (p.flaps or [[] for _ in range(p.stop - p.start)])]
    layout = layout_of_size(tuple((parts[0].info or {}).get("size_mm") or (400.0, 400.0)))
    geometry_on = all(p.flaps is not None for p in parts)
    layer_notes, error = _layer_notes(parts[0].path, below, front)
    if error is not None:
        return EpisodeFailure(parts[0].path, error)
    v = verdicts(dist, references, n_unknown, n_known)
    refused = np.array([n is not None for n in layer_notes], dtype=bool)
    states, _ = smooth(np.where(refused[:, None], np.nan, dist), references)
    frames = []
    stickers = _joined_stickers(parts)
    for t in range(len(dist)):
        best, conf = int(v.best[t]), float(v.confidence[t])
        note = layer_notes[t] or _note(conf, best, references, int(n_known[t]))
        ref = references.references[best] if best >= 0 else None
        if note is None and ref is not None and stickers is not None:
            note = _outside_note(stickers, t, ref, layout) or _mesh_flap_note(flaps[t])
            conf = 0.0 if note is not None else conf
        answer = ref if note is None else None
        if refused[t]:
            best, conf = -1, 0.0
        key = (answer.class_id, answer.variant) if answer else states[t]
        words = sorted(folds_of(*key), key=lambda w: (" crossing " in w, w))
        geometry = [] if refused[t] or not geometry_on else mesh_fold_geometry(
            words, flaps[t], layout)
        frames.append(
            FrameLabel(
                index=t,
                class_id=answer.class_id if answer else None,
                variant=answer.variant if answer else None,
                progress=progress_of(answer.stage) if answer else None,
                confidence=round(conf, 4) if best >= 0 or refused[t] else None,
                distance=round(float(v.distance[t]), 6) if best >= 0 else None,
                smoothed_class=states[t][0],
                smoothed_variant=states[t][1],
                note=note,
                omnigibson=(bool(og[t, 0]), bool(og[t, 1])),
                folds=tuple({"fold": g.word, **g.to_json()} for g in geometry),
            )
        )
    changes = tuple((t, states[t - 1], states[t]) for t in change_frames(states))
    verdict = None
    last = next((p.last for p in parts if p.last is not None), None)
    if goal is not None and last is not None and frames:
        final = frames[-1]
        words = sorted(folds_of(*states[-1]), key=lambda w: (" crossing " in w, w))
        verdict = evaluate_goal(
            goal, states[-1], mesh_fold_geometry(words, last["flaps"], layout),
            last["position"], last["rest"], last["uv"], layout,
        )
        verdict["frame"] = final.index
    return EpisodeLabels(parts[0].path, tuple(frames), changes, dict(parts[0].info or {}),
                         verdict)


def _joined_stickers(parts: list[PartResult]) -> tuple | None:
    """The parts' sticker centres, sight and standing, joined in frame order (None when
    a part has none: an older worker's)."""
    if any(p.stickers is None for p in parts):
        return None
    return tuple(np.concatenate([p.stickers[k] for p in parts]) for k in range(4))


def _outside_note(
    stickers: tuple, t: int, ref: Any, layout: NapkinLayout
) -> str | None:
    """Why frame ``t``'s mesh is in none of the twelve states, or None: the stickers'
    places on the mesh against the nearest state's folds (the camera's state fit,
    :func:`~dgli_vision.classifier.state_fit.fit_state`), and whether the cloth is in a
    heap (:func:`~dgli_vision.classifier.known_states.crumpled_problem`)."""
    from types import SimpleNamespace

    from ..classifier.known_states import crumpled_problem
    from ..classifier.state_fit import fit_state

    xyz, seen, standing, heights = (a[t] for a in stickers)
    obs = SimpleNamespace(
        points_m=xyz, visible=seen, up=np.array([0.0, 0.0, 1.0]), lifted=standing,
        heights_mm=np.where(seen, heights, np.nan),
    )
    crumpled = crumpled_problem(obs, layout)
    if crumpled is not None:
        return f"cannot tell: {crumpled}"
    fit = fit_state(obs, ref.class_id, ref.variant, layout)
    return None if fit.fits else f"cannot tell: no known state fits: {fit.describe()}"


#: A flap found lying on the mesh farther than this (RMS, mm) from one rigid turn of the
#: flat cloth about its crease is folded more than once (a corner folded, then its tip
#: folded back; a napkin folded in quarters): the twelve states' flaps give 0-1 mm.
MESH_FLAP_RMS_MM = 10.0


def _mesh_flap_note(flaps: list[dict[str, Any]]) -> str | None:
    """Why the flaps found on a frame's mesh are no state's (a flap folded more than
    once, or a flap that holds no corner), or None."""
    for f in flaps:
        if f["rms_mm"] > MESH_FLAP_RMS_MM:
            return (
                f"cannot tell: no known state fits: the flap of {f['corners'] or 'no corner'} "
                f"lies {f['rms_mm']:.0f} mm (RMS) off one fold of the flat cloth: folded "
                "more than once"
            )
        if not f["corners"]:
            return (
                "cannot tell: no known state fits: a flap that holds no corner or side "
                f"({f['vertices']} vertices): a fold no known state has"
            )
    return None


def state_text(key: tuple[str, str | None]) -> str:
    """``"02 corner-over A"``."""
    return f"{key[0]} {CLASS_NAMES[key[0]]}" + (f" {key[1]}" if key[1] else "")
