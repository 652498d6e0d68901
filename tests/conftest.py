"""Settings for the whole suite.

One thread per numerical library in each test process. pytest-xdist already runs one
worker per core (``-n 2``); OpenBLAS, OpenMP (Open3D's ray casting) and OpenCV would each
start a thread per core on top, and on two busy cores those threads spin against each
other: a render's 921,600 x 3 matrix product took 10x the CPU time with two OpenBLAS
threads than with one, and a whole render 0.79 s of CPU against 0.45 s. The variables are
read when the libraries load, so they are set here, before any test module imports
numpy, and they pass to the ``dgli`` processes that tests start. A value already set in
the environment is kept.
"""

from __future__ import annotations

import os

for _name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")


def pytest_configure(config) -> None:
    """OpenCV's own thread pool, in this process, to one thread as well."""
    import cv2

    cv2.setNumThreads(1)
