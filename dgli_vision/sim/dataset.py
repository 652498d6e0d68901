"""Labelled synthetic RGB-D sets: random cameras and scenes around simulated states."""

from __future__ import annotations

from collections.abc import Container, Iterator, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from ..core.camera import DEFAULT_INTRINSICS, CameraPose, Intrinsics, look_at_table
from ..core.classes import CORNERS
from ..core.errors import InvalidValueError
from ..core.layout import NapkinLayout, default_layout
from .cloth.outside import OUTSIDE_KINDS, OUTSIDE_LABEL, sample_outside
from .cloth.sequences import SEQUENCES, sequence_progress, sequence_state, sequence_steps
from .cloth.states import CLASS_IDS, VARIANTS, ClothState, sample_state
from .conditions import Conditions, Grasp, draw_conditions, draw_lens, held_corner, turn_over
from .render import Lighting, RenderResult, SensorModel, render

__all__ = [
    "SEQUENCE_FRAME_SECONDS",
    "KeptPair",
    "RenderedSample",
    "kept_pairs",
    "random_camera",
    "render_sample",
    "render_samples",
    "render_sequence",
    "sample_name",
]

#: Time between the frames of a rendered sequence (``frames.csv``), seconds.
SEQUENCE_FRAME_SECONDS = 0.5

#: Nominal scene of SPEC section 4: straight down from 520 mm.
NOMINAL_HEIGHT_M = 0.52
#: The ``vga`` condition's camera: 640 x 480, fx = fy = 500, 600-850 mm away.
VGA_INTRINSICS = Intrinsics(640, 480, 500.0, 500.0, 319.5, 239.5)
VGA_HEIGHT_RANGE_M = (0.60, 0.85)


def _fits_all(
    states: list[ClothState], pose: CameraPose, intrinsics: Intrinsics, margin_px: float
) -> bool:
    return all(_fits(s, pose, intrinsics, margin_px) for s in states)


def _fits(state: ClothState, pose: CameraPose, intrinsics: Intrinsics, margin_px: float) -> bool:
    pix = intrinsics.project(pose.world_to_camera(state.mesh.xyz[::7]))
    return bool(
        (pix[:, 0] >= margin_px).all()
        and (pix[:, 0] <= intrinsics.width - 1 - margin_px).all()
        and (pix[:, 1] >= margin_px).all()
        and (pix[:, 1] <= intrinsics.height - 1 - margin_px).all()
    )


def random_camera(
    state: ClothState,
    rng: np.random.Generator,
    *,
    intrinsics: Intrinsics = DEFAULT_INTRINSICS,
    nominal: bool = False,
    height_range_m: tuple[float, float] = (0.45, 0.70),
    max_tilt_deg: float = 12.0,
    distance_range_m: tuple[float, float] | None = None,
    min_tilt_deg: float = 0.0,
) -> tuple[CameraPose, dict[str, float]]:
    """A camera that sees the whole napkin: height, tilt and yaw drawn at random.

    The camera aims near the napkin's centre; draws that leave part of the napkin out of
    view (20 px margin) are redrawn, higher up if need be. With ``distance_range_m`` the
    camera's distance from the napkin along its axis is drawn instead of its height (a
    robot's head camera: far and tilted), the tilt between ``min_tilt_deg`` and
    ``max_tilt_deg``.

    Returns
    -------
    pose : CameraPose
    info : dict
        ``height_m``, ``tilt_deg``, ``tilt_direction_deg``, ``yaw_deg``.
    """
    centre = state.mesh.xyz[:, :2].mean(axis=0)
    lo, hi = height_range_m
    for attempt in range(200):
        if nominal:
            info = {
                "height_m": NOMINAL_HEIGHT_M,
                "tilt_deg": 0.0,
                "tilt_direction_deg": 0.0,
                "yaw_deg": float(rng.uniform(0, 360)) if attempt else 0.0,
            }
        else:
            grow = min(1.0, attempt / 100)  # after many misses, favour higher cameras
            if distance_range_m is None:
                height = float(rng.uniform(lo + grow * (hi - lo) * 0.5, hi))
                tilt = float(rng.uniform(min_tilt_deg, max_tilt_deg))
            else:  # (the distance along the axis; the height follows from the tilt)
                near, far = distance_range_m
                distance = float(rng.uniform(near + grow * (far - near) * 0.5, far))
                tilt = float(rng.uniform(min_tilt_deg, max_tilt_deg))
                height = distance * float(np.cos(np.radians(tilt)))
            info = {
                "height_m": height,
                "tilt_deg": tilt,
                "tilt_direction_deg": float(rng.uniform(0, 360)),
                "yaw_deg": float(rng.uniform(0, 360)),
            }
        target = (*(centre + (0 if nominal else rng.uniform(-0.02, 0.02, 2))), 0.0)
        pose = look_at_table(
            info["height_m"],
            tilt_rad=np.radians(info["tilt_deg"]),
            tilt_direction_rad=np.radians(info["tilt_direction_deg"]),
            yaw_rad=np.radians(info["yaw_deg"]),
            target=target,
        )
        if _fits(state, pose, intrinsics, 20.0):
            return pose, info
    raise InvalidValueError("no camera pose in range sees the whole napkin")


@dataclass(frozen=True, eq=False)
class RenderedSample:
    """One rendered pair with its labels."""

    name: str
    state: ClothState
    result: RenderResult
    camera: dict[str, Any]
    lighting: Lighting
    conditions: Conditions = field(default_factory=Conditions)


def render_samples(
    per_class: int,
    seed: int,
    *,
    classes: tuple[str, ...] = CLASS_IDS,
    nominal: bool = False,
    clean: bool = False,
    intrinsics: Intrinsics = DEFAULT_INTRINSICS,
    conditions: tuple[str, ...] = (),
    layout: NapkinLayout | None = None,
) -> Iterator[RenderedSample]:
    """Render ``per_class`` pairs of every class (variants in turn, starting at the
    seed's), deterministically.

    Sample ``k`` of class ``c`` draws everything (state, camera, lighting, noise) from a
    generator seeded by ``(seed, c, k)`` on a stream of its own, so it never repeats a
    state of the simulated database made with the same seed. ``conditions`` (names of
    :data:`dgli_vision.sim.conditions.CONDITION_NAMES`) are drawn from a further stream, so
    the same seed gives the same states and cameras with and without them (``vga``
    changes the camera). ``layout`` gives another napkin size (fold sizes scale with it,
    and the camera stands back for a larger napkin).
    """
    for class_id in classes:
        for k in range(per_class):
            yield render_sample(
                class_id,
                k,
                seed,
                nominal=nominal,
                clean=clean,
                intrinsics=intrinsics,
                conditions=conditions,
                layout=layout,
            )


def sample_name(class_id: str, k: int) -> str:
    """Name of sample ``k`` of a class in a rendered folder (``"05_003"``)."""
    return f"{class_id}_{k:03d}"


#: Classes whose last fold tucks the cloth under the napkin.
UNDER_CLASSES = ("03", "10")


def _grasped_state(
    class_id: str,
    variant: str | None,
    rng: np.random.Generator,
    layout: NapkinLayout,
    grasp: Grasp,
) -> ClothState:
    """A state of the class with a gripper holding the corner of its last fold, that fold
    turned ``grasp.settle_deg`` (past 90 degrees, or laid flat); a flat napkin has a first
    corner rising (below 90 degrees). ``params["held_corner"]`` names the held corner."""
    if class_id == "01":
        first = CORNERS[grasp.corner]
        state = sample_state("02", first, rng, layout=layout, last_fold_deg=grasp.rise_deg)
    else:
        deg = grasp.settle_deg if grasp.settle_deg < 180 else None
        if class_id in UNDER_CLASSES:
            # a corner or side tucked under is held at the fold once it lies there: the
            # simulator's half-way tuck lifts the whole napkin onto the flap beneath it,
            # which no robot does
            deg = None
        state = sample_state(class_id, variant, rng, layout=layout, last_fold_deg=deg)
    corner = held_corner(state.params["folds"][-1], grasp)
    return replace(state, params={**state.params, "held_corner": corner})


def _sequence_held_corner(steps: list, state: ClothState, layout: NapkinLayout, grasp: Grasp):
    """The corner the gripper holds in a frame of a sequence: that of the fold in
    progress, or of the fold just made (the first fold's on the flat napkin)."""
    fold = steps[max(len(state.params["angles_deg"]) - 1, 0)]
    dist = np.linalg.norm(layout.corner_uv - np.asarray(fold.flap), axis=1)
    nearest = [c for c, d in zip(CORNERS, dist) if d <= dist.min() + 1.0]  # 2 for a side
    return nearest[grasp.corner % len(nearest)]


def _set_lens(cond: Conditions, seed: int) -> Conditions:
    """Under ``distortion-known``, the one lens of the whole set (drawn from its seed), so
    that every pair of a folder shares the intrinsics that carry its coefficients."""
    if not cond.distortion_known:
        return cond
    return replace(cond, distortion=draw_lens(np.random.default_rng([seed, 37])))


def _camera_for(
    cond: Conditions, intrinsics: Intrinsics, layout: NapkinLayout
) -> tuple[Intrinsics, tuple[float, float]]:
    """The camera and its height range (m) under the drawn conditions (``vga`` swaps
    both); the range moves back in proportion for a napkin larger than the nominal one."""
    intr, (lo, hi) = (
        (VGA_INTRINSICS, VGA_HEIGHT_RANGE_M)
        if "vga" in cond.names
        else (
            intrinsics,
            (0.45, 0.70),
        )
    )
    grow = max(1.0, *layout.fold_scale)
    return intr, (lo * grow, hi * grow)


def _camera_range(cond: Conditions) -> dict[str, Any]:
    """:func:`random_camera`'s distance and tilt under ``far`` or ``head`` (nothing
    otherwise: the data set's heights and tilts)."""
    if cond.camera_range_m is None:
        return {}
    lo, hi = cond.tilt_range_deg
    return {"distance_range_m": cond.camera_range_m, "min_tilt_deg": lo, "max_tilt_deg": hi}


def render_sample(
    class_id: str,
    k: int,
    seed: int,
    *,
    nominal: bool = False,
    clean: bool = False,
    intrinsics: Intrinsics = DEFAULT_INTRINSICS,
    conditions: tuple[str, ...] = (),
    layout: NapkinLayout | None = None,
) -> RenderedSample:
    """Sample ``k`` of class ``class_id`` of :func:`render_samples` (same arguments);
    ``class_id`` ``"none"``: a state outside the twelve, of kind ``OUTSIDE_KINDS[k % 8]``
    (:func:`~dgli_vision.sim.cloth.outside.sample_outside`)."""
    layout = layout or default_layout()
    outside = class_id == OUTSIDE_LABEL
    # (a state outside the twelve draws from streams of its own: class number 0)
    number = 0 if outside else int(class_id)
    options = (None,) if outside else VARIANTS[class_id]
    rng = np.random.default_rng([seed, number, k, 7])
    cond = _set_lens(
        draw_conditions(conditions, np.random.default_rng([seed, number, k, 23])), seed
    )
    intr, heights = _camera_for(cond, intrinsics, layout)
    variant = options[(k + seed) % len(options)]
    if outside:
        state = sample_outside(OUTSIDE_KINDS[k % len(OUTSIDE_KINDS)], rng, layout=layout)
    elif cond.grasp is not None:
        state = _grasped_state(class_id, variant, rng, layout, cond.grasp)
    else:
        state = sample_state(class_id, variant, rng, layout=layout)
    if cond.backface_axis_deg is not None:
        state = turn_over(state, cond.backface_axis_deg, layout)
    pose, camera = random_camera(
        state, rng, intrinsics=intr, nominal=nominal, height_range_m=heights,
        **_camera_range(cond),
    )
    lighting = Lighting() if nominal else Lighting.random(rng)
    sensor = SensorModel(enabled=not clean)
    result = render(
        state,
        pose,
        intrinsics=intr,
        lighting=lighting,
        sensor=sensor,
        rng=rng,
        conditions=cond,
        layout=layout,
    )
    return RenderedSample(sample_name(class_id, k), state, result, camera, lighting, cond)


def render_sequence(
    name: str,
    n_frames: int,
    seed: int,
    *,
    nominal: bool = False,
    clean: bool = False,
    intrinsics: Intrinsics = DEFAULT_INTRINSICS,
    conditions: tuple[str, ...] = (),
    layout: NapkinLayout | None = None,
    progress: list[float] | None = None,
    skip: Container[int] = (),
) -> Iterator[RenderedSample]:
    """Render folding sequence ``name`` as ``n_frames`` frames of one recording.

    The frames are spread evenly over the sequence's folds, from flat to the last fold
    laid flat, each labelled by SPEC's 90-degree rule. The seed draws the fold sizes
    (within the ranges of the sequence's classes), the wrinkles, the napkin's place, the
    camera, the light and the capture conditions once for the whole recording; only the
    sensor noise changes from frame to frame. The camera sees the whole napkin in every
    frame.

    Parameters
    ----------
    progress : list of float, keyword-only, optional
        Render the frames at these points of the sequence instead (``k + f``: the first
        ``k`` folds laid flat and fold ``k + 1`` turned ``180 f`` degrees); the scene is
        the same as for the evenly spread frames.
    skip : container of int, keyword-only, optional
        Frames not to render (kept from an interrupted run); the others are the same.

    Yields
    ------
    RenderedSample
        Named ``"<name>_<frame>"`` (``"II_007"``); ``state.params["progress"]`` is where
        the frame is in the sequence.
    """
    if name not in SEQUENCES:
        raise InvalidValueError(
            f"unknown sequence {name!r}; expected one of {', '.join(SEQUENCES)}"
        )
    index = list(SEQUENCES).index(name)
    layout = layout or default_layout()
    rng = np.random.default_rng([seed, 1000 + index])
    cond = _set_lens(
        draw_conditions(conditions, np.random.default_rng([seed, 1000 + index, 23])), seed
    )
    intr, heights = _camera_for(cond, intrinsics, layout)
    steps = sequence_steps(name, layout, rng=rng)
    states = _SequenceStates(
        name, steps, layout, cond, [seed, 1000 + index, 5], _sequence_scene(rng, nominal)
    )
    if progress is None:
        progress = sequence_progress(name, n_frames)
    pose, camera = _sequence_camera(states, rng, intr, heights, nominal=nominal)
    lighting = Lighting() if nominal else Lighting.random(rng)
    sensor = SensorModel(enabled=not clean)
    for k, p in enumerate(progress):
        if k in skip:
            continue
        state = states.at(p)
        result = render(
            state,
            pose,
            intrinsics=intr,
            lighting=lighting,
            sensor=sensor,
            rng=np.random.default_rng([seed, 1000 + index, k, 7]),
            conditions=cond,
            layout=layout,
        )
        yield RenderedSample(f"{name}_{k:03d}", state, result, camera, lighting, cond)


def _sequence_scene(rng: np.random.Generator, nominal: bool) -> dict[str, Any]:
    """The wrinkles, yaw and place of a sequence's napkin, drawn once for the recording
    (none of them on a nominal scene)."""
    return {
        "wrinkle_mm": 0.0 if nominal else float(rng.uniform(0, 8)),
        "yaw": 0.0 if nominal else float(rng.uniform(0, 2 * np.pi)),
        "offset_m": (0.0, 0.0) if nominal else tuple(rng.uniform(-0.03, 0.03, size=2)),
    }


@dataclass(frozen=True)
class _SequenceStates:
    """The cloth states of one rendered sequence: the same folds, wrinkles, place and
    conditions at every point of it.

    Attributes
    ----------
    name : str
    steps : list
        The sequence's folds (:func:`dgli_vision.sim.cloth.sequences.sequence_steps`).
    layout : NapkinLayout
    cond : Conditions
        The recording's conditions (``grasp`` holds a corner, ``backface`` turns it over).
    wrinkle_seed : list of int
        Seeds the same wrinkles in every frame.
    scene : dict
        :func:`_sequence_scene`.
    """

    name: str
    steps: list
    layout: NapkinLayout
    cond: Conditions
    wrinkle_seed: list[int]
    scene: dict[str, Any]

    def at(self, p: float) -> ClothState:
        """The state at point ``p`` of the sequence (see :func:`render_sequence`)."""
        state = sequence_state(
            self.name,
            p,
            steps=self.steps,
            layout=self.layout,
            rng=np.random.default_rng(self.wrinkle_seed),
            **self.scene,
        )
        if self.cond.grasp is not None:
            corner = _sequence_held_corner(self.steps, state, self.layout, self.cond.grasp)
            state = replace(state, params={**state.params, "held_corner": corner})
        if self.cond.backface_axis_deg is not None:
            state = turn_over(state, self.cond.backface_axis_deg, self.layout)
        return state


def _sequence_camera(
    states: _SequenceStates,
    rng: np.random.Generator,
    intr: Intrinsics,
    heights: tuple[float, float],
    *,
    nominal: bool,
) -> tuple[CameraPose, dict[str, Any]]:
    """A camera that sees the napkin at every stage of the sequence, flaps held up
    included (50 draws at most)."""
    n_steps = len(states.steps)
    probes = [states.at(p) for p in np.linspace(0, n_steps, 4 * n_steps + 1)]
    for _ in range(50):
        pose, camera = random_camera(
            probes[0], rng, intrinsics=intr, nominal=nominal, height_range_m=heights
        )
        if _fits_all(probes, pose, intr, 10.0):
            return pose, camera
    raise InvalidValueError(f"no camera pose in range sees the whole of sequence {states.name}")


# --- going on with an interrupted render -------------------------------------------------


@dataclass(frozen=True)
class KeptPair:
    """A pair an earlier render of the same set left complete: its rows of ``labels.csv``
    and ``frames.csv`` (None without one) and its ``truth.json`` entry."""

    name: str
    label_row: tuple[str, ...]
    frame_row: tuple[str, ...] | None
    truth: dict[str, Any]


def _csv_rows(path: Path) -> tuple[list[str], list[tuple[str, ...]]]:
    import csv

    from ..core.errors import UnreadableInputError

    if not path.is_file():
        return [], []
    try:
        with path.open(newline="", encoding="utf-8") as fh:
            rows = [tuple(r) for r in csv.reader(fh)]
    except (OSError, UnicodeDecodeError) as exc:
        raise UnreadableInputError(f"cannot read '{path}': {exc}") from None
    return (list(rows[0]), rows[1:]) if rows else ([], [])


def kept_pairs(
    out: str | Path, provenance: dict[str, Any], names: Sequence[str]
) -> dict[str, KeptPair]:
    """The pairs of ``names`` that an earlier, interrupted ``dgli render`` of the same set
    left complete in ``out`` (listed in its ``labels.csv`` and ``truth.json``, both files
    there), for ``--resume``.

    Raises
    ------
    ResumeMismatchError
        The earlier render was of another set: its provenance (seed, classes, frames,
        conditions, size, ...) differs from ``provenance`` (the command and the package
        version aside), or there is none.
    """
    from ..core.io import read_json
    from ..core.run_lock import check_resume, run_header

    root = Path(out)
    truth_path = root / "truth.json"
    if not truth_path.is_file():
        return {}
    truth = read_json(truth_path, what="truth file")
    volatile = ("command", "package_version")

    def fields(prov: Any) -> dict[str, Any]:
        return {"options": {k: v for k, v in prov.items() if k not in volatile}}

    earlier = truth.get("provenance") if isinstance(truth, dict) else None
    first = run_header("render", fields(earlier)) if isinstance(earlier, dict) else None
    check_resume(truth_path, first, run_header("render", fields(provenance)))
    _, labels = _csv_rows(root / "labels.csv")
    _, frames = _csv_rows(root / "frames.csv")
    label_of = {r[0]: r for r in labels if r}
    frame_of = {r[0]: r for r in frames if r}
    images = truth.get("images") or {}
    kept = {}
    for name in names:
        entry = images.get(name)
        color, depth = f"{name}_color.png", f"{name}_depth.png"
        if (
            isinstance(entry, dict)
            and color in label_of
            and (root / color).is_file()
            and (root / depth).is_file()
        ):
            kept[name] = KeptPair(name, label_of[color], frame_of.get(color), entry)
    return kept


def render_plan(
    per_class: int,
    sequence: str | None,
    frames: int,
    *,
    by_number: bool = False,
    outside: int = 0,
) -> tuple[list[str], list[tuple[str, int]]]:
    """The names of the pairs of a set to render and, for a set of classes (no
    ``sequence``), each pair's class and number: ``per_class`` pairs of every class and
    ``outside`` states outside the twelve (class ``"none"``, last), or the ``frames``
    frames of folding ``sequence``. ``by_number``: every class's first pair, then every
    class's second... (a slow render stopped part-way has every class)."""
    if sequence:
        return [f"{sequence}_{k:03d}" for k in range(frames)], []
    if by_number:
        cases = [(c, k) for k in range(per_class) for c in CLASS_IDS]
    else:
        cases = [(c, k) for c in CLASS_IDS for k in range(per_class)]
    cases += [(OUTSIDE_LABEL, k) for k in range(outside)]
    return [sample_name(c, k) for c, k in cases], cases
