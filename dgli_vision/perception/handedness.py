"""Which way round the stickers of each corner run: which face each corner shows.

Every sticker is printed on both faces at the same place, so the camera sees the
stickers of a corner whichever face it shows. Seen from the front face, the stickers
around a corner run one way round (as printed); seen from the back face (a corner on a
flap folded over, or the napkin lying back face up) or in a mirrored image, the other
way. Three stickers of one corner in the image tell which, with neither depth nor any
cloth coordinate: the dGLI coordinates need both stickers of two segments, so a corner
half covered by a gripper still says whether it lies folded over.

The turn itself is napkin geometry (:mod:`dgli_vision.core.handedness`): computed from a
simulated state seen from above, it gives each reference's rate of showing the back face
at each corner (``Reference.back_rate``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..core.handedness import back_face_up, corner_turns
from ..core.layout import NapkinLayout

__all__ = ["back_face_up", "corner_turns", "image_turns"]


def image_turns(centroids_px: NDArray[np.float64], layout: NapkinLayout) -> NDArray[np.float64]:
    """:func:`corner_turns` of sticker centres in an image (pixels, x right, y down).

    Parameters
    ----------
    centroids_px : ndarray, shape (16, 2)
        NaN where a sticker was not located.
    layout : NapkinLayout

    Returns
    -------
    ndarray, shape (4,)
        +1 front face towards the camera, -1 back face (or a mirrored image), 0 not told.
    """
    return corner_turns(np.asarray(centroids_px, dtype=float) * np.array([1.0, -1.0]), layout)
