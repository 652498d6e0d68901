"""``dgli_vision.camera``: camera intrinsics and lens distortion.

The public import path; the code lives in :mod:`dgli_vision.core.camera`.
"""

from .core.camera import *  # noqa: F403
from .core.camera import __all__  # noqa: F401
