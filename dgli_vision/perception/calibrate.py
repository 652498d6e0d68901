"""Sticker colour calibration from one image of the flat napkin with all 16 stickers seen.

Printers and inks differ: a user's "blue" may print nearer cyan. The detector names a
pixel's colour by the nearest hue, so measuring each printed colour once, as the camera
sees it after balancing to the napkin's white, keeps that robust. The result maps each
colour name to an sRGB triple in the balanced image (what :func:`detect_stickers`
thresholds); it is used with ``--colours`` and never needed for stickers printed close
to the nominal colours.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..core.camera import Intrinsics
from ..core.layout import NapkinLayout
from .detect import DetectorParams, detect_all_stickers
from .params import disc_bands

__all__ = ["calibrate_colours", "calibrate_handedness"]


def calibrate_colours(
    color: NDArray[np.uint8],
    depth_mm: NDArray[np.uint16],
    intrinsics: Intrinsics,
    layout: NapkinLayout,
    *,
    params: DetectorParams | None = None,
    source: str = "image",
) -> dict[str, tuple[int, int, int]]:
    """Measure the printed colours of the four sticker colours.

    Parameters
    ----------
    color : ndarray of uint8, shape (H, W, 3)
        RGB image of the flat napkin, all 16 stickers in view.
    depth_mm : ndarray of uint16, shape (H, W)
    intrinsics : Intrinsics
    layout : NapkinLayout
    params : DetectorParams, keyword-only, optional
        A wider ``max_hue_distance`` is used to find stickers printed off-nominal.
    source : str, keyword-only
        Name of the image, for messages.

    Returns
    -------
    dict
        Colour name -> (r, g, b), 0-255, as seen once balanced to the napkin's white.

    Raises
    ------
    CalibrationError
        Fewer than 16 stickers found.
    """
    import cv2

    params = params or DetectorParams(max_hue_distance=40)
    det, napkin = detect_all_stickers(
        color, depth_mm, intrinsics, layout, params, source=source, purpose="calibration"
    )
    norm = cv2.LUT(color, napkin.lut)
    bands = disc_bands(layout)  # (where the detector reads the disc and the dot)
    band = bands.band
    samples: dict[str, list[NDArray]] = {name: [] for name in layout.colours_srgb}
    yy, xx = np.mgrid[0 : color.shape[0], 0 : color.shape[1]]
    for sid in range(layout.n_stickers):
        cu, cv = det.centroids[sid]
        radius = np.sqrt(det.areas[sid] / np.pi)
        x0, x1 = int(max(cu - radius - 2, 0)), int(min(cu + radius + 3, color.shape[1]))
        y0, y1 = int(max(cv - radius - 2, 0)), int(min(cv + radius + 3, color.shape[0]))
        r = np.hypot(xx[y0:y1, x0:x1] - cu, yy[y0:y1, x0:x1] - cv) / radius
        win = norm[y0:y1, x0:x1]
        samples[layout.sticker_disc[sid]].append(win[(r > band[0]) & (r < band[1])])
        samples[layout.sticker_dot[sid]].append(win[r < bands.dot])
    out = {}
    for name, parts in samples.items():
        px = np.concatenate(parts).astype(np.float64)
        out[name] = tuple(int(v) for v in np.rint(np.median(px, axis=0)))
    return out


def calibrate_handedness(
    color: NDArray[np.uint8],
    depth_mm: NDArray[np.uint16],
    intrinsics: Intrinsics,
    layout: NapkinLayout,
    *,
    params: DetectorParams | None = None,
    source: str = "image",
) -> bool:
    """Whether the camera mirrors its image, from one image of the flat napkin lying front
    face up (all 16 stickers in view).

    Seen from the front, the stickers around every corner run as printed
    (:func:`~dgli_vision.perception.handedness.image_turns`): a camera that mirrors its
    image shows all four corners the other way round. A perspective view of the flat
    napkin keeps the turn, whatever the camera's tilt.

    Parameters
    ----------
    color : ndarray of uint8, shape (H, W, 3)
    depth_mm : ndarray of uint16, shape (H, W)
    intrinsics : Intrinsics
    layout : NapkinLayout
    params : DetectorParams, keyword-only, optional
        Default: as :func:`calibrate_colours` finds the stickers.
    source : str, keyword-only
        Name of the image, for messages.

    Returns
    -------
    bool
        True: the camera mirrors its image (or the napkin lies back face up: the image
        alone cannot tell those apart, so lay it front face up).

    Raises
    ------
    CalibrationError
        Fewer than 16 stickers found, or corners that do not all turn one way (the napkin
        not flat, or stickers misplaced).
    """
    from ..core.errors import CalibrationError
    from .handedness import image_turns

    params = params or DetectorParams(max_hue_distance=40)
    det, _ = detect_all_stickers(
        color, depth_mm, intrinsics, layout, params, source=source, purpose="calibration"
    )
    turns = image_turns(det.centroids, layout)
    if (turns == 1).all():
        return False
    if (turns == -1).all():
        return True
    ways = {1: "as printed", -1: "the other way", 0: "neither way clearly"}
    told = ", ".join(f"{c} {ways[int(t)]}" for c, t in zip("ABCD", turns))
    raise CalibrationError(
        f"'{source}': the stickers of the corners do not all run one way round ({told}): "
        "lay the napkin flat, unfolded, front face up"
    )
