"""``dgli_vision.distance``: Spearman and the other distances.

The public import path; the code lives in :mod:`dgli_vision.core.distance`.
"""

from .core.distance import *  # noqa: F403
from .core.distance import __all__  # noqa: F401
