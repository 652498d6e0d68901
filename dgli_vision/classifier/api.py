"""One call from code: a colour + depth pair, from files or from a live camera, to a
verdict."""

from __future__ import annotations

import math
from dataclasses import replace
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from ..core.camera import DEFAULT_INTRINSICS, Intrinsics
from ..core.errors import CalibrationError, DetectionError, DgliError, InvalidInputError
from ..core.why import WhyKind
from ..sources.frames import (
    RGBDFrame,
    check_intrinsics,
    read_color,
    read_depth,
    read_frame,
    read_intrinsics,
)
from .classify import MIN_CONFIDENCE, Prediction, StickerIds

if TYPE_CHECKING:
    from ..perception.params import PipelineParams
from .references import ReferenceSet, load_references

__all__ = ["classify_pair", "frame_from", "reference_set_of"]


@lru_cache(maxsize=4)
def _references(path: str | None) -> ReferenceSet:
    return load_references(path)


def _check_source(value: object, what: str) -> None:
    """A path or an array; anything else is a mistake in the caller's code."""
    if not isinstance(value, (str, Path, np.ndarray)) and not hasattr(value, "__array__"):
        raise InvalidInputError(
            f"{what} must be a file path or a numpy array; got {type(value).__name__}"
        )


def _color_array(color: NDArray) -> NDArray[np.uint8]:
    a = np.asarray(color)
    if a.ndim != 3 or a.shape[2] != 3:
        raise InvalidInputError(f"colour array has shape {a.shape}; expected (H, W, 3) RGB")
    if a.dtype == np.uint16:
        a = ((a.astype(np.uint32) * 255 + 32767) // 65535).astype(np.uint8)
    if a.dtype != np.uint8:
        raise InvalidInputError(f"colour array is {a.dtype}; expected uint8 (or uint16) RGB")
    return np.ascontiguousarray(a)


def _depth_array(depth: NDArray) -> NDArray[np.uint16]:
    a = np.asarray(depth)
    if a.ndim == 3 and a.shape[2] == 1:
        a = a[..., 0]
    if a.ndim != 2 or a.dtype != np.uint16:
        raise InvalidInputError(
            f"depth array is {a.dtype} of shape {a.shape}; expected (H, W) uint16 in mm"
        )
    return np.ascontiguousarray(a)


def classify_pair(
    color: str | Path | NDArray,
    depth: str | Path | NDArray,
    intrinsics: Intrinsics | str | Path | None = None,
    references: ReferenceSet | str | Path | None = None,
    *,
    colours: dict[str, tuple[int, int, int]] | None = None,
    extrinsics: object = None,
    mirroring: str | None = None,
    params: object = None,
) -> Prediction:
    """Classify one registered colour + depth pair.

    Parameters
    ----------
    color : path or ndarray
        A colour image file, or an RGB array (H, W, 3) of uint8 (uint16 is scaled).
    depth : path or ndarray
        A 16-bit depth PNG, or a uint16 array (H, W) in mm registered to the colour
        image (0 = no reading).
    intrinsics : Intrinsics or path, optional
        Default: ``intrinsics.json`` beside a colour image file, else the nominal
        1280 x 720 Kinect camera.
    references : ReferenceSet or path, optional
        Default: the shipped reference set (loaded once and kept).
    colours : dict, keyword-only, optional
        Calibrated sticker colours (``dgli calibrate``).
    extrinsics : Extrinsics, path or (4, 4) array, keyword-only, optional
        The camera-to-base transform (:mod:`dgli_vision.core.extrinsics`): the corners'
        points and the folds' lines are then in the robot's base frame (as with
        ``--extrinsics``); default the camera frame.
    mirroring : {"no", "yes", "unknown"}, keyword-only, optional
        Whether the camera mirrors its image left to right (as ``--mirroring``): default
        as the intrinsics declare (``"mirrored"``, written by ``dgli calibrate``), else
        ``"no"``. ``"yes"`` reads the frame un-mirrored; ``"unknown"`` keeps 02, 03, 09
        and 10 below confidence 0.5 (a napkin back face up under a mirroring camera shows
        their twin: docs/robustness.md).
    params : PipelineParams, DetectorParams or path, keyword-only, optional
        Every perception stage's parameters
        (:class:`~dgli_vision.perception.params.PipelineParams`), or a JSON file of
        overrides (:func:`~dgli_vision.perception.params.read_params`, as ``--params``);
        default: the defaults.

    Returns
    -------
    Prediction
        A verdict for every frame that could be read. A class (``class_id``, ``name``,
        ``variant``) with its ``confidence`` and ``reason`` None; or "cannot tell", as
        the command line says it: ``class_id``, ``name`` and ``variant`` None
        (``"class": null`` in ``--json``), ``reason`` one line starting ``cannot
        tell:`` and ``why`` its kind (:data:`~dgli_vision.classifier.pipeline.WHY_KINDS`:
        too few stickers seen, the confidence below
        :data:`~dgli_vision.classifier.classify.MIN_CONFIDENCE` (0.25), a check of the
        frame that failed; ``colour channels`` for an array that reads with its red and
        blue channels swapped, "BGR?"). A "cannot tell" keeps the nearest states in
        ``candidates`` (empty, with ``distance`` NaN and ``confidence`` 0, when too
        little was seen to rank any). ``stickers`` lists the stickers found, hidden by
        cloth and unknown (with why) in both cases. So ``p.class_id is None`` is the one
        test for "cannot tell".

    Raises
    ------
    DgliError
        Only for input that is not an RGB-D frame: an unreadable file, an array of the
        wrong shape or type, bad intrinsics, references or colours (one line naming the
        file or array and the problem).
    """
    from ..core.extrinsics import extrinsics_of
    from ..core.handedness import camera_mirroring

    ext = extrinsics_of(extrinsics)
    if mirroring is not None:
        camera_mirroring(mirroring)  # a bad value: one line, before any reading
    p = _classified(
        color, depth, intrinsics, references, colours, mirroring, _params_of(params)
    )
    return p if ext is None else _in_frame(p, ext)


def _in_frame(p: Prediction, ext: object) -> Prediction:
    """``p`` with its corners' points and its folds' lines in the frame of ``ext``."""
    from ..core.extrinsics import moved_point
    from .affordances import CornerMap

    corners = CornerMap(replace(c, point=moved_point(ext, c.point)) for c in p.corners.values())
    folds = tuple(
        f if f.line is None else replace(f, line=tuple(moved_point(ext, q) for q in f.line))
        for f in p.folds
    )
    return replace(p, corners=corners, folds=folds)


def _params_of(params: object) -> PipelineParams:
    """The parameters tree ``params`` names: itself, the defaults with a
    ``DetectorParams``, a JSON file's overrides, or the defaults (None)."""
    from ..perception.params import params_of, read_params

    if isinstance(params, (str, Path)):
        return read_params(params)
    return params_of(params)  # type: ignore[arg-type]


def _classified(
    color: object,
    depth: object,
    intrinsics: object,
    references: object,
    colours: object,
    mirroring: str | None = None,
    params: PipelineParams | None = None,
) -> Prediction:
    """:func:`classify_pair`'s verdict in the camera frame."""
    from .pipeline import classify_frame

    frame = frame_from(color, depth, intrinsics)
    refs = reference_set_of(references)
    colours = _check_colours(colours)
    try:
        result = classify_frame(
            frame, refs, colours=colours, min_confidence=MIN_CONFIDENCE, mirroring=mirroring,
            params=params,
        )
    except DetectionError as exc:  # no table in the depth: read, but nothing to rank
        return _cannot_tell(str(exc), WhyKind.TOO_FEW.value)
    swapped = _bgr_reading(color, frame, refs, colours, result, params)
    if swapped is not None:
        reason = (
            f"cannot tell: colour channels swapped (BGR?): with red and blue swapped it "
            f"reads as {swapped.class_id} {swapped.name} at confidence "
            f"{swapped.confidence:.2f}; is the colour array BGR, as OpenCV reads images? "
            "classify_pair takes RGB (pass color[..., ::-1])"
        )
        if result.best_guess is None:
            return _cannot_tell(
                f"{reason}; as given: {result.reason}", WhyKind.CHANNELS.value, result
            )
        # the reading as given means nothing: no confidence in it
        guess = replace(result.best_guess, confidence=0.0)
        result = replace(
            result, prediction=None, best_guess=guess, reason=reason, why=WhyKind.CHANNELS.value
        )
    if result.best_guess is None:  # too few stickers to rank the references
        return _cannot_tell(result.reason or "", result.why or WhyKind.TOO_FEW.value, result)
    told = result.prediction is None
    p = replace(
        result.best_guess,
        reason=_told(result.reason) if told else None,
        why=result.why if told else None,
        stickers=_sticker_ids(result),
        candidates=result.candidates,
    )
    if told:  # the nearest states stay in candidates; no class contradicts the reason
        p = replace(p, class_id=None, name=None, variant=None)
    return p


def _told(reason: str | None) -> str:
    """A reason as the API gives it: one line starting ``cannot tell:``."""
    reason = reason or "no class"
    return reason if reason.startswith("cannot tell") else f"cannot tell: {reason}"


def _cannot_tell(reason: str, why: str, result: object | None = None) -> Prediction:
    """A "cannot tell" with no state ranked (too little seen): no class, no candidates,
    distance NaN, confidence 0; the stickers and corners of ``result`` when there is one
    (a ``FrameResult``)."""
    from .affordances import CornerMap

    stickers = _sticker_ids(result) if result is not None else StickerIds(())
    aff = getattr(result, "affordances", None)
    return Prediction(
        class_id=None, name=None, variant=None, distance=math.nan, runner_up=None,
        margin=math.nan, confidence=0.0, reason=_told(reason), why=why,
        stickers=stickers, corners=aff.corners if aff is not None else CornerMap(),
    )


#: Stickers whose disc is yellow (corner B): with red and blue swapped a yellow disc
#: turns cyan, which is no sticker's colour, so a BGR array shows none of them.
_YELLOW = (2, 3, 4, 5)


def _bgr_reading(
    color: object, frame: RGBDFrame, refs: ReferenceSet, colours: object, result: object,
    params: PipelineParams,
) -> Prediction | None:
    """The verdict of a colour array read with its red and blue channels swapped, when
    the stickers' palette fits the swapped channels better (a BGR array, as OpenCV reads
    images); else None.

    Looked at only when the array shows no yellow sticker (a BGR array never does) and,
    read swapped, shows a yellow disc (:func:`_swapped_yellow`, from the colour labels
    alone), so a frame with its yellow stickers in view, or under a gripper, is
    classified once: the swapped reading must give a class and find more stickers (as
    many, when the array gave no class) at a confidence at least as high.
    """
    from .pipeline import classify_frame

    if not isinstance(color, np.ndarray) or color.ndim != 3 or color.shape[2] != 3:
        return None
    found = result.detections.found  # type: ignore[attr-defined]
    given = result.prediction  # type: ignore[attr-defined]
    if found[list(_YELLOW)].any() or not _swapped_yellow(frame, refs, colours, result, params):
        return None
    swapped = replace(frame, color=np.ascontiguousarray(frame.color[..., ::-1]))
    try:
        again = classify_frame(
            swapped, refs, colours=colours, min_confidence=MIN_CONFIDENCE,
            mirroring=result.mirroring,  # type: ignore[attr-defined]
            params=params,
        )
    except DgliError:
        return None
    more = int(again.detections.found.sum()) - int(found.sum())
    if again.prediction is None or more < (0 if given is None else 1):
        return None
    if given is not None and again.prediction.confidence < given.confidence:
        return None
    return again.prediction


def _swapped_yellow(
    frame: RGBDFrame, refs: ReferenceSet, colours: object, result: object,
    params: PipelineParams,
) -> bool:
    """Whether the frame with red and blue swapped shows a yellow disc (a BGR array's
    cyan ones), from its colour labels alone
    (:func:`~dgli_vision.perception.detect.swapped_discs_seen`): only then is it worth
    classifying swapped (True when the napkin was not kept to tell)."""
    from ..core.layout import layout_of_size
    from ..perception.detect import search_frame, swapped_discs_seen

    napkin = result.observation.napkin  # type: ignore[attr-defined]
    if napkin is None:
        return True
    layout = layout_of_size(refs.napkin_mm)
    search = search_frame(
        frame.color, frame.depth_mm, frame.intrinsics, layout, napkin, params.detector,
        colours=colours,  # type: ignore[arg-type]
    )
    return swapped_discs_seen(search, layout.sticker_disc[_YELLOW[0]])


def _sticker_ids(result: object) -> StickerIds:
    """The stickers found, hidden by cloth and unknown of a classified frame."""
    from ..perception.evidence import HIDDEN

    obs = result.observation  # type: ignore[attr-defined]
    found = tuple(int(i) for i in np.flatnonzero(obs.visible))
    ev = obs.evidence
    if ev is None:
        return StickerIds(found)
    hidden = tuple(int(i) for i in np.flatnonzero(np.asarray(ev.status) == HIDDEN))
    unknown = tuple(int(i) for i in np.flatnonzero(obs.unknown))
    return StickerIds(found, hidden, unknown, tuple(str(ev.reasons[i]) for i in unknown))


def frame_from(
    color: str | Path | NDArray,
    depth: str | Path | NDArray,
    intrinsics: Intrinsics | str | Path | dict | None = None,
) -> RGBDFrame:
    """The frame of a colour and a depth given as files or arrays (as
    :func:`classify_pair` takes them), checked.

    Raises
    ------
    DgliError
        Unreadable or invalid input, one line naming the file or array and the problem.
    """
    _check_source(color, "color")
    _check_source(depth, "depth")
    if intrinsics is not None and not isinstance(intrinsics, (str, Path)):
        intrinsics = check_intrinsics(intrinsics)
    if isinstance(color, (str, Path)) and isinstance(depth, (str, Path)):
        return read_frame(color, depth, intrinsics)
    return _frame_of(color, depth, intrinsics)


def _frame_of(
    color: str | Path | NDArray,
    depth: str | Path | NDArray,
    intrinsics: Intrinsics | str | Path | None,
) -> RGBDFrame:
    """A frame of which at least one image is an array."""
    color_path = str(color) if isinstance(color, (str, Path)) else "<array>"
    depth_path = str(depth) if isinstance(depth, (str, Path)) else "<array>"
    rgb = read_color(color) if isinstance(color, (str, Path)) else _color_array(color)
    mm = read_depth(depth) if isinstance(depth, (str, Path)) else _depth_array(depth)
    if rgb.shape[:2] != mm.shape:
        raise InvalidInputError(
            f"depth {depth_path} is {mm.shape[1]}x{mm.shape[0]} but colour {color_path} is "
            f"{rgb.shape[1]}x{rgb.shape[0]}; expected registered images of the same size"
        )
    source = "given"
    if isinstance(intrinsics, Intrinsics):
        intr = intrinsics
    elif intrinsics is not None:
        intr, source = read_intrinsics(intrinsics), str(intrinsics)
    elif color_path != "<array>" and (Path(color_path).parent / "intrinsics.json").is_file():
        source = str(Path(color_path).parent / "intrinsics.json")
        intr = read_intrinsics(source)
    else:
        intr, source = DEFAULT_INTRINSICS, "default"
    if (intr.width, intr.height) != (mm.shape[1], mm.shape[0]):
        raise CalibrationError(
            f"intrinsics ({source}) are for {intr.width}x{intr.height} images but the pair "
            f"is {mm.shape[1]}x{mm.shape[0]}"
            + ("; give the camera's intrinsics (intrinsics=, an Intrinsics or a file)"
               if source == "default" else "")
        )
    return RGBDFrame(rgb, mm, intr, color_path, depth_path, source)


def reference_set_of(references: object) -> ReferenceSet:
    """The reference set ``references`` names: a :class:`ReferenceSet` itself, a file
    path (loaded once and kept), or None for the shipped set (what :func:`classify_pair`
    and :func:`dgli_vision.plan` take).

    Raises
    ------
    InvalidInputError
        Neither a reference set nor a path.
    """
    if isinstance(references, ReferenceSet):
        return references
    if references is not None and not isinstance(references, (str, Path)):
        raise InvalidInputError(
            f"references must be a ReferenceSet or a file path; got {type(references).__name__}"
        )
    return _references(str(references) if references is not None else None)


def _check_colours(colours: object) -> dict[str, tuple[int, int, int]] | None:
    """Calibrated colours as :func:`~dgli_vision.sources.colours_file.read_colours` gives them."""
    from ..core.layout import default_layout

    if colours is None:
        return None
    names = set(default_layout().colours_srgb)
    if not isinstance(colours, dict) or set(colours) != names:
        raise InvalidInputError(
            f"colours must be a dict of exactly the colours {', '.join(sorted(names))}"
        )
    out = {}
    for name, rgb in colours.items():
        values = tuple(rgb) if isinstance(rgb, (tuple, list, np.ndarray)) else ()
        if len(values) != 3 or not all(
            isinstance(v, (int, np.integer)) and 0 <= v <= 255 for v in values
        ):
            raise InvalidInputError(f"colours: {name!r} must be three integers 0-255")
        out[name] = (int(values[0]), int(values[1]), int(values[2]))
    return out
