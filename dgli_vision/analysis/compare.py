"""The paper's comparison of representations (Table 1) and its sequence analysis."""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..classifier.classify import Evidence, batch_distances
from ..classifier.references import ReferenceSet
from ..core.distance import davies_bouldin, pairwise_spearman
from ..core.errors import InvalidValueError
from ..core.json_ready import json_ready
from ..sim.database import StateRecords
from .baselines import corner_distances, pairwise_curve_distances, segment_distances

__all__ = [
    "COMPARE_COLUMN_NOTES",
    "NO_SEPARATION",
    "PAPER_TABLE1",
    "REPRESENTATIONS",
    "CompareTable",
    "SequenceAnalysis",
    "analyse_sequence",
    "compare_count",
    "compare_database",
    "dataset_matrices",
    "davies_bouldin_table",
    "matrix_count",
    "paper_columns",
    "sequence_outcomes",
]


def _dgli_with_visibility(records: StateRecords) -> NDArray[np.float64]:
    """The classifier's metric between samples: Spearman distance of the dGLI plus the
    mean disagreement of which stickers are visible (see
    :mod:`dgli_vision.classifier.classify`)."""
    vis = records.visible.astype(float)
    return pairwise_spearman(records.coordinates) + np.abs(vis[:, None] - vis[None]).mean(axis=2)


#: What each column of ``dgli compare`` groups, and why.
COMPARE_COLUMN_NOTES: dict[str, str] = {
    "database": "the simulated states by class (12 groups; a class pools its corners or "
    "sides, so a group holds shapes that differ by rotation of the fold)",
    "I, II, III": "the frames of each folding sequence by their true class",
    "database by variant": "by class and variant (44 groups); over and under mirror "
    "images are separate groups although the dGLI cannot tell them apart",
    "by variant, mirrors merged": "by class and variant with mirror images through the "
    "table merged (02/03 by corner, 09/10 by side, 05 XY/X with XY/Y; 32 groups, derived "
    "from the fold definitions): the dGLI of a mirror image is the same, so this is the "
    "grouping comparable to the paper's corner-specific classes, whose database has no "
    "fold under",
}

REPRESENTATIONS: dict[str, Callable[[StateRecords], NDArray[np.float64]]] = {
    "dgli": lambda r: pairwise_spearman(r.coordinates),
    "dgli+visibility": _dgli_with_visibility,
    "edges": lambda r: pairwise_spearman(
        segment_distances(r.sticker_points.reshape(len(r), -1, 2, 3))
    ),
    "corners": lambda r: pairwise_spearman(corner_distances(r.corner_points)),
    "frechet": lambda r: pairwise_curve_distances(r.boundary, "frechet"),
    "hausdorff": lambda r: pairwise_curve_distances(r.boundary, "hausdorff"),
}


#: The paper's Davies-Bouldin indices (its Table 1) that the documentation records, by
#: column and representation: the database column (the paper's corner-specific classes,
#: comparable to "by variant, mirrors merged") and sequence III's dGLI. The paper gives no
#: dGLI + visibility (it is this package's classifier metric) and the documentation keeps
#: no other of its values: those cells are None, never guessed.
PAPER_TABLE1: dict[str, dict[str, float]] = {
    "database": {"dgli": 0.73, "edges": 1.60, "frechet": 0.99, "hausdorff": 1.45},
    "III": {"dgli": 0.21},
}


def paper_columns(names: tuple[str, ...] = tuple(REPRESENTATIONS)) -> dict[str, object]:
    """The paper's values beside ours: ``{"columns": ["paper: database", "paper: III"],
    "rows": {name: [value or None per column]}}`` (:data:`PAPER_TABLE1`)."""
    return {
        "columns": [f"paper: {c}" for c in PAPER_TABLE1],
        "rows": {n: [PAPER_TABLE1[c].get(n) for c in PAPER_TABLE1] for n in names},
    }


def _records_key(records: StateRecords) -> tuple[int, ...]:
    """The same states (a grouping of the database shares its arrays): the same key."""
    return tuple(
        id(a)
        for a in (records.coordinates, records.boundary, records.sticker_points,
                  records.corner_points, records.visible)
    )


def _matrix(task: tuple[StateRecords, str]) -> NDArray[np.float64]:
    records, name = task
    return REPRESENTATIONS[name](records)


def dataset_matrices(
    datasets: dict[str, StateRecords],
    names: tuple[str, ...] = tuple(REPRESENTATIONS),
    *,
    jobs: int = 1,
    on_progress: Callable[[int], None] | None = None,
) -> dict[str, dict[str, NDArray[np.float64]]]:
    """Every data set's distance matrix under each representation, each distinct set of
    states once (the database's groupings share theirs).

    Parameters
    ----------
    datasets : dict of str to StateRecords
    names : tuple of str
    jobs : int, keyword-only
        Worker processes (the matrices do not depend on it).
    on_progress : callable, keyword-only, optional
        Called with 1 after each matrix.

    Returns
    -------
    dict
        Data set name -> representation -> matrix (n, n).
    """
    first: dict[tuple[int, ...], str] = {}
    for column, records in datasets.items():
        first.setdefault(_records_key(records), column)
    tasks = [(datasets[c], n) for c in first.values() for n in names]
    if jobs > 1:
        import multiprocessing

        ctx = multiprocessing.get_context("spawn")
        from ..core.parallel import die_with_parent

        with ProcessPoolExecutor(jobs, mp_context=ctx, initializer=die_with_parent) as pool:
            # the slow curve distances first, so that the workers end together
            order = sorted(range(len(tasks)), key=lambda k: tasks[k][1] not in _SLOW)
            futures = {pool.submit(_matrix, tasks[k]): k for k in order}
            done: dict[int, NDArray[np.float64]] = {}
            for future in as_completed(futures):
                done[futures[future]] = future.result()
                if on_progress:
                    on_progress(1)
        mats = [done[k] for k in range(len(tasks))]
    else:
        mats = []
        for task in tasks:
            mats.append(_matrix(task))
            if on_progress:
                on_progress(1)
    by_key: dict[tuple[int, ...], dict[str, NDArray[np.float64]]] = {}
    for (records, name), mat in zip(tasks, mats):
        by_key.setdefault(_records_key(records), {})[name] = mat
    return {column: by_key[_records_key(r)] for column, r in datasets.items()}


#: The representations whose matrices take seconds (curve distances): started first.
_SLOW = ("frechet", "hausdorff")


def matrix_count(datasets: dict[str, StateRecords], names: tuple[str, ...]) -> int:
    """How many matrices :func:`dataset_matrices` computes (for a progress bar)."""
    return len({_records_key(r) for r in datasets.values()}) * len(names)


def davies_bouldin_table(
    datasets: dict[str, StateRecords],
    names: tuple[str, ...] = tuple(REPRESENTATIONS),
    *,
    matrices: dict[str, dict[str, NDArray[np.float64]]] | None = None,
) -> dict[str, object]:
    """Davies-Bouldin index (lower is better) of each representation on each data set.

    Parameters
    ----------
    datasets : dict of str to StateRecords
        Column name -> samples labelled by class (``records.classes``).
    names : tuple of str
        Representations (rows).
    matrices : dict, keyword-only, optional
        :func:`dataset_matrices` of ``datasets`` (computed here when not given).

    Returns
    -------
    dict
        ``{"columns": [...], "rows": {name: [index per column]}}``.
    """
    mats = matrices if matrices is not None else dataset_matrices(datasets, names)
    rows: dict[str, list[float]] = {n: [] for n in names}
    for column, records in datasets.items():
        for n in names:
            rows[n].append(round(davies_bouldin(mats[column][n], np.asarray(records.classes)), 4))
    return {"columns": list(datasets), "rows": rows}


#: Above this a Davies-Bouldin index says two groups' centres coincide (the ratio's
#: denominator is rounding noise): shown as such, not as a number.
NO_SEPARATION = 1e6


@dataclass(frozen=True)
class CompareTable:
    """``dgli compare``'s result: the Davies-Bouldin index of each representation
    (``rows``: name -> index per column, lower is better) on each data set
    (``columns``), and the paper's values beside them (:func:`paper_columns`)."""

    columns: tuple[str, ...]
    rows: dict[str, list[float]]
    paper: dict[str, object]

    def to_json(self) -> dict[str, object]:
        """The JSON of ``dgli compare --json`` (and ``table.json``): an index above
        :data:`NO_SEPARATION` (two groups' centres coincide) is null."""
        return json_ready({
            "columns": list(self.columns),
            "rows": {
                name: [v if v < NO_SEPARATION else None for v in vals]
                for name, vals in self.rows.items()
            },
            "column_notes": COMPARE_COLUMN_NOTES,
            "paper": self.paper,
        })


def compare_count(records: StateRecords) -> int:
    """The distance matrices :func:`compare_database` computes (a progress bar's total)."""
    return matrix_count(compare_datasets(folded_by_class(records)), tuple(REPRESENTATIONS))


def compare_database(
    records: StateRecords,
    *,
    jobs: int = 1,
    on_progress: Callable[[int], None] | None = None,
) -> tuple[CompareTable, dict[str, NDArray[np.float64]], list[str]]:
    """``dgli compare``: the Davies-Bouldin table of every representation on the
    database (its folds laid flat, the paper's states) and the three sequences.

    Returns
    -------
    CompareTable
    dict of str to ndarray
        The database's distance matrix under each representation (for the heatmaps).
    list of str
        The class of each state of those matrices, in their order.
    """
    records = folded_by_class(records)
    datasets = compare_datasets(records)
    names = tuple(REPRESENTATIONS)
    matrices = dataset_matrices(datasets, names, jobs=jobs, on_progress=on_progress)
    table = davies_bouldin_table(datasets, names, matrices=matrices)
    table = CompareTable(tuple(table["columns"]), table["rows"], paper_columns(names))
    return table, matrices["database"], list(records.classes)


@dataclass(frozen=True)
class SequenceAnalysis:
    """Frame-by-frame analysis of a folding sequence.

    Attributes
    ----------
    distances : ndarray, shape (n, n)
        Spearman distances between the frames' dGLI coordinates.
    truth : tuple of str
        True class of every frame.
    predicted : tuple of str
        Each frame's own nearest class.
    smoothed : tuple of str
        The classes after smoothing over time (:mod:`dgli_vision.analysis.track`).
    true_changes, detected_changes : tuple of int
        Frames where the true / smoothed class differs from the previous frame's.
    reference_distances : ndarray, shape (n, K), optional
        Each frame's distance to every reference (what the smoothing weighs).
    """

    distances: NDArray[np.float64]
    truth: tuple[str, ...]
    predicted: tuple[str, ...]
    smoothed: tuple[str, ...]
    true_changes: tuple[int, ...]
    detected_changes: tuple[int, ...]
    reference_distances: NDArray[np.float64] | None = None

    @property
    def frame_accuracy(self) -> float:
        """Fraction of frames whose own predicted class is the true one."""
        return float(np.mean([t == p for t, p in zip(self.truth, self.predicted)]))

    @property
    def smoothed_accuracy(self) -> float:
        """Fraction of frames whose smoothed class is the true one."""
        return float(np.mean([t == p for t, p in zip(self.truth, self.smoothed)]))

    def to_json(self, name: str) -> dict[str, object]:
        """The JSON of ``dgli sequence NAME --json`` (docs/json.md)."""
        from ..sim.cloth.sequences import SEQUENCES

        return json_ready({
            "sequence": name,
            "description": SEQUENCES[name][0],
            "frames": len(self.truth),
            "truth": list(self.truth),
            "predicted": list(self.predicted),
            "smoothed": list(self.smoothed),
            "true_changes": list(self.true_changes),
            "detected_changes": list(self.detected_changes),
            "frame_accuracy": round(self.frame_accuracy, 4),
            "smoothed_accuracy": round(self.smoothed_accuracy, 4),
        })


def analyse_sequence(records: StateRecords, references: ReferenceSet) -> SequenceAnalysis:
    """Distance matrix of the frames, and the frames where the state changes.

    Each frame is compared with ``references`` as a camera straight above would see it
    (stickers hidden by cloth as evidence, coordinates of their segments removed, those
    on a flap held up unknown); the per-frame distances are smoothed over time with the
    tracker's hidden Markov model, and a change is a frame whose smoothed class differs
    from the previous frame's.
    """
    from .track import change_frames, smooth

    coords = records.hidden_coordinates()
    back = records.seen_back_faces()
    spread = records.seen_spreads_mm()
    told = records.visible | records.unknown
    evidence = Evidence(
        visible=records.visible,
        unknown=records.unknown,
        lifted=np.where(told, records.lifted, np.nan),
        # held up out of sight: the height its flap gives it
        heights_mm=np.where(told, records.sticker_points[..., 2] * 1e3, np.nan),
        past=np.where(records.unknown, np.asarray(records.past_vertical)[:, None], np.nan),
        back=back,
        spread_mm=spread,
    )
    dist = batch_distances(coords, evidence, references)
    predicted = tuple(references.references[int(np.argmin(d))].class_id for d in dist)
    smoothed = tuple(c for c, _ in smooth(dist, references)[0])
    return SequenceAnalysis(
        distances=pairwise_spearman(records.coordinates),
        truth=records.classes,
        predicted=predicted,
        smoothed=smoothed,
        true_changes=tuple(change_frames(records.classes)),
        detected_changes=tuple(change_frames(smoothed)),
        reference_distances=dist,
    )


def sequence_outcomes(
    name: str, records: StateRecords, analysis: SequenceAnalysis, references: ReferenceSet
) -> list:
    """The frames of a sequence as a recording's per-frame outcomes (named
    ``{name}_000``, ..., labelled with their true state, answered with their nearest
    reference, with their coordinates and distances): what
    :func:`~dgli_vision.analysis.track.track_outcomes` smooths into the timeline that
    ``dgli track`` reports."""
    from ..sources.labelled import LabelledPair
    from .evaluate import PairOutcome

    dist = analysis.reference_distances
    if dist is None:
        raise InvalidValueError("the analysis keeps no distances to the references")
    outs = []
    for k in range(len(records)):
        best = int(np.argmin(dist[k]))
        ref = references.references[best]
        pair = LabelledPair(f"{name}_{k:03d}", "", records.classes[k], records.variants[k])
        outs.append(
            PairOutcome(
                pair,
                ref.class_id,
                ref.variant,
                float(dist[k, best]),
                coordinates=tuple(float(v) for v in records.coordinates[k]),
                distances=tuple(float(v) for v in dist[k]),
            )
        )
    return outs


def sequence_records(name: str) -> StateRecords:
    """The simulator's frames of folding sequence ``name`` (I, II or III) as records
    named ``{name}_000``, ``{name}_001``, ..."""
    from ..sim.cloth.sequences import folding_sequence
    from ..sim.database import records_from_states

    frames = folding_sequence(name)
    return records_from_states([(f"{name}_{k:03d}", s) for k, s in enumerate(frames)])


def folded_by_class(records: StateRecords) -> StateRecords:
    """The paper's states of a database (every fold laid flat), sorted by class, then
    variant (stable)."""
    records = records.subset(records.folded)
    keys = [f"{c}/{v or ''}" for c, v in zip(records.classes, records.variants)]
    order = np.argsort(np.asarray(keys), kind="stable")
    return records.subset(order)


def compare_datasets(records: StateRecords) -> dict[str, StateRecords]:
    """The columns of ``dgli compare``: the database ``records`` (see
    :func:`folded_by_class`) labelled by class, the three folding sequences, the database
    labelled by class and variant, and by class and variant with mirror images merged."""
    import dataclasses

    from ..core.fold_graph import mirror_group

    by_variant = dataclasses.replace(
        records, classes=tuple(f"{c}/{v}" for c, v in zip(records.classes, records.variants))
    )
    mirrored = dataclasses.replace(
        records,
        classes=tuple(mirror_group(k) for k in zip(records.classes, records.variants)),
    )
    return {
        "database": records,
        **{n: sequence_records(n) for n in ("I", "II", "III")},
        "database by variant": by_variant,
        "by variant, mirrors merged": mirrored,
    }
