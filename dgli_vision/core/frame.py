"""The RGB-D frame: a registered colour and depth pair with its camera, validated once.

It is the pipeline's input (:func:`dgli_vision.classifier.pipeline.classify_frame`) and
what every source yields (:mod:`dgli_vision.sources`); it lives here, below both, so
that perception and the classifier need not import the sources to name it.
:mod:`dgli_vision.sources.frames` reads and writes its files.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .camera import Intrinsics

__all__ = ["RGBDFrame"]


@dataclass(frozen=True, eq=False)
class RGBDFrame:
    """A registered colour + depth pair, validated.

    Attributes
    ----------
    color : ndarray of uint8, shape (H, W, 3)
        RGB.
    depth_mm : ndarray of uint16, shape (H, W)
        z-depth in mm, 0 = no reading.
    intrinsics : Intrinsics
    color_path, depth_path : str
        Where they came from (for messages and reports).
    intrinsics_source : str
        The intrinsics file, or ``"default"``.
    """

    color: NDArray[np.uint8]
    depth_mm: NDArray[np.uint16]
    intrinsics: Intrinsics
    color_path: str = ""
    depth_path: str = ""
    intrinsics_source: str = "default"
