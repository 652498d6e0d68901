"""``dgli_vision.dgli``: GLI, dGLI and the cloth coordinates.

The public import path; the code lives in :mod:`dgli_vision.core.dgli`.
"""

from .core.dgli import *  # noqa: F403
from .core.dgli import __all__  # noqa: F401
