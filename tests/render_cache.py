"""Rendered frames kept on disk between test runs (and shared between test modules).

A render costs a few tenths of a second; the same few dozen frames are rendered by
several modules. :func:`rendered` keeps each under pytest's cache folder
(``.pytest_cache/d/renders``), keyed by its arguments and by a digest of the renderer's
sources (``dgli_vision/sim``), so a change to the renderer renders afresh. Under xdist
every worker reads the same files; a file is written whole (to a temporary name, then
renamed), so a worker never reads half of one.
"""

from __future__ import annotations

import hashlib
import os
from functools import lru_cache
from pathlib import Path

import numpy as np
import pytest

from dgli_vision.core.camera import Intrinsics
from dgli_vision.sources.frames import RGBDFrame

SIM = Path(__file__).resolve().parents[1] / "dgli_vision" / "sim"


@lru_cache(maxsize=1)
def _sim_digest() -> str:
    h = hashlib.sha256()
    for p in sorted(SIM.rglob("*.py")):
        h.update(p.relative_to(SIM).as_posix().encode())
        h.update(p.read_bytes())
    return h.hexdigest()[:16]


def _folder(config: pytest.Config | None) -> Path | None:
    if config is None or getattr(config, "cache", None) is None:
        return None
    return Path(config.cache.mkdir("renders"))


def rendered(
    config: pytest.Config | None,
    class_id: str,
    k: int,
    seed: int,
    conditions: tuple[str, ...] = (),
    **kwargs: object,
) -> RGBDFrame:
    """:func:`~dgli_vision.sim.dataset.render_sample`'s frame, from the disk cache when
    it was rendered before by this renderer. ``kwargs`` must be plain values (bool,
    int, str); the frame is named ``"{class}_{k:03d}"``."""
    key = repr((class_id, k, seed, tuple(conditions), sorted(kwargs.items()), _sim_digest()))
    name = f"{class_id}_{k:03d}"
    folder = _folder(config)
    path = folder / f"{hashlib.sha256(key.encode()).hexdigest()[:24]}.npz" if folder else None
    if path is not None and path.is_file():
        z = np.load(path)
        w, h, fx, fy, cx, cy = z["intrinsics"].tolist()
        intr = Intrinsics(int(w), int(h), fx, fy, cx, cy, tuple(z["distortion"].tolist()))
        return RGBDFrame(z["color"], z["depth"], intr, name, name)
    from dgli_vision.sim.dataset import render_sample

    r = render_sample(class_id, k, seed, conditions=tuple(conditions), **kwargs).result
    if path is not None:
        i = r.intrinsics
        tmp = path.with_suffix(f".{os.getpid()}.tmp.npz")
        np.savez(
            tmp,
            color=r.color,
            depth=r.depth_mm,
            intrinsics=np.array([i.width, i.height, i.fx, i.fy, i.cx, i.cy], dtype=np.float64),
            distortion=np.array(i.distortion, dtype=np.float64),
        )
        os.replace(tmp, path)
    return RGBDFrame(r.color, r.depth_mm, r.intrinsics, name, name)
