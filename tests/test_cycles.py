"""The path-traced render path (``dgli render --engine cycles``): its camera pipeline and
depth model (plain numpy, always run), the one-line error without Blender, and a small
Cycles render whose sticker pixels and depth must agree with the simulator's geometry
through intrinsics.json (run where ``bpy`` is: in this Python, or in the
``.venv-photoreal/`` that scripts/setup.sh --test makes, since bpy needs numpy < 2)."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
from click.testing import CliRunner

from dgli_vision.cli import main
from dgli_vision.sim.camera_pipeline import (
    CameraModel,
    ToFModel,
    bayer_mosaic,
    blackbody_rgb,
    colour_camera,
    demosaic,
    tof_depth,
)

REPO = Path(__file__).resolve().parents[1]


def test_blackbody_colours_run_from_warm_to_neutral():
    warm, neutral = blackbody_rgb(2700), blackbody_rgb(6500)
    assert warm[0] > 1.5 * warm[2]  # tungsten: much more red than blue
    assert max(neutral) / min(neutral) < 1.15  # D65-like: about white


def test_demosaic_keeps_a_flat_colour():
    """The RGGB mosaic and OpenCV's demosaicing agree on which pixel is which colour."""
    rgb = np.zeros((8, 10, 3))
    rgb[...] = (0.8, 0.3, 0.1)
    raw = (bayer_mosaic(rgb) * 65535).astype(np.uint16)
    out = demosaic(raw)[2:-2, 2:-2].reshape(-1, 3).mean(axis=0) / 65535
    assert np.allclose(out, (0.8, 0.3, 0.1), atol=0.01)


def test_colour_camera_is_seeded_and_noisy():
    lin = np.full((60, 80, 3), 0.3)
    lin[20:40, 30:50] = (0.5, 0.05, 0.05)
    a, info = colour_camera(lin, CameraModel(), np.random.default_rng(1))
    b, _ = colour_camera(lin, CameraModel(), np.random.default_rng(1))
    c, _ = colour_camera(lin, CameraModel(), np.random.default_rng(2))
    assert a.dtype == np.uint8 and np.array_equal(a, b) and not np.array_equal(a, c)
    assert a[5:15, 5:15].std() > 0.5  # sensor noise
    assert a[30, 40, 0] > 2 * a[30, 40, 1]  # the red patch stays red
    assert set(info) >= {"exposure", "vignetting", "wb_gains"}


def test_tof_holes_on_glossy_facing_the_camera_and_flying_pixels_at_edges():
    z = np.full((40, 40), 600.0)
    z[:, 20:] = 500.0  # a step of 100 mm
    cos = np.full(z.shape, 0.9)
    cos[5:10, 5:10] = 0.999  # facing the camera
    glossy = np.zeros(z.shape, bool)
    glossy[5:10, 5:10] = True
    glossy[25:30, 5:10] = True  # glossy but at an angle: read
    d = tof_depth(z, cos, glossy, ToFModel(random_dropout=0.0), np.random.default_rng(0))
    assert (d[5:10, 5:10] == 0).all()
    assert (d[25:30, 5:10] > 0).all()
    edge = d[:, 19:21].astype(float)
    mixed = (edge > 510) & (edge < 590)
    assert mixed.any() and (d[:, 19:21] == 0).any()
    assert abs(np.median(d[:, :15]) - 600) <= 1


def test_cycles_without_blender_is_one_line_exit_2(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "bpy", None)  # import bpy raises ImportError
    out = tmp_path / "set"
    res = CliRunner().invoke(main, ["render", str(out), "--engine", "cycles"])
    assert res.exit_code == 2
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and "pip install dgli_vision[photoreal]" in lines[0]
    assert not out.exists() or not any(out.iterdir())


def test_cycles_refuses_conditions(tmp_path):
    res = CliRunner().invoke(
        main, ["render", str(tmp_path / "s"), "--engine", "cycles", "--conditions", "jpeg"]
    )
    assert res.exit_code == 2 and "--conditions" in res.output


def _bpy_python() -> str | None:
    """A Python that has bpy: this one, or .venv-photoreal's."""
    if importlib.util.find_spec("bpy") is not None:
        return sys.executable
    other = REPO / ".venv-photoreal" / "bin" / "python"
    return str(other) if other.is_file() else None


_RENDER = r"""
import sys
import numpy as np
from dgli_vision.core.camera import Intrinsics, look_at_table
from dgli_vision.sim.cloth.states import sample_state
from dgli_vision.sim.render_scene import Lighting
from dgli_vision.sim.cycles_scene import draw_look, render_cycles

rng = np.random.default_rng(5)
state = sample_state("01", None, rng)
# an off-centre principal point checks Blender's lens shift against ours
intr = Intrinsics(320, 180, 151.25, 151.25, 171.5, 82.5)
centre = np.append(state.mesh.xyz[:, :2].mean(axis=0), 0.0)
pose = look_at_table(0.45, tilt_rad=np.radians(8), tilt_direction_rad=0.7, yaw_rad=0.4,
                     target=centre)
look = draw_look(state, pose, Lighting(), rng)
res = render_cycles(state, pose, intr, look, rng, samples=8, seed=1, threads=2, clean=True)
# --scene varied's Blender parts (a wooden table, lamps turned about their axis) build
import bpy
from dgli_vision.sim.cycles_scene import _add_lights, _wood_material
from dgli_vision.sim.photo_variety import draw_varied_look, draw_wood
wood_mat = _wood_material(bpy, draw_wood(np.random.default_rng(2)))
base = wood_mat.node_tree.nodes["Principled BSDF"].inputs["Base Color"]
varied = draw_varied_look(state, pose, Lighting(), np.random.default_rng(3))
_add_lights(bpy, varied)
rolls = [o.rotation_euler.to_quaternion() for o in bpy.data.objects if o.type == "LIGHT"]
np.savez(sys.argv[1], color=res.color, depth=res.depth_mm, points=res.sticker_points_cam,
         visible=res.visible, K=intr.matrix(), wood_linked=base.is_linked,
         lights=len(rolls), looks=len(varied.lights))
"""


@pytest.fixture(scope="module")
def small_render(tmp_path_factory):
    python = _bpy_python()
    if python is None:
        pytest.skip(
            "bpy (Blender as a Python module) is not installed: pip install "
            "dgli_vision[photoreal] (scripts/setup.sh --test makes .venv-photoreal/ with it)"
        )
    out = tmp_path_factory.mktemp("cycles") / "render.npz"
    run = subprocess.run(
        [python, "-c", _RENDER, str(out)], capture_output=True, text=True, timeout=300,
        cwd=REPO,
    )
    assert run.returncode == 0, run.stderr[-2000:]
    return dict(np.load(out))


def test_cycles_stickers_are_where_the_intrinsics_project_them(small_render):
    """Each sticker's disc, found by its colour in the path-traced image, is centred
    within half a pixel of the projection of the simulator's sticker through the intrinsics."""
    color, points, k = small_render["color"], small_render["points"], small_render["K"]
    px = (k @ (points / points[:, 2:]).T).T[:, :2]
    hsv = cv2.cvtColor(color, cv2.COLOR_RGB2HSV).astype(float)
    coloured = (hsv[..., 1] > 110) & (hsv[..., 2] > 60)
    errors = []
    for (u, v), seen in zip(px, small_render["visible"]):
        assert seen
        y, x = np.mgrid[0 : color.shape[0], 0 : color.shape[1]]
        near = coloured & ((x - u) ** 2 + (y - v) ** 2 < 9**2)
        assert near.sum() > 20
        errors.append(np.hypot(x[near].mean() - u, y[near].mean() - v))
    assert max(errors) < 0.5, errors


def test_cycles_depth_deprojects_to_the_sticker_points(small_render):
    depth, points, k = small_render["depth"], small_render["points"], small_render["K"]
    px = (k @ (points / points[:, 2:]).T).T[:, :2]
    kinv = np.linalg.inv(k)
    for (u, v), truth in zip(px, points):
        z = np.median(depth[round(v) - 1 : round(v) + 2, round(u) - 1 : round(u) + 2]) / 1000
        got = kinv @ np.array([u, v, 1.0]) * z
        assert np.linalg.norm(got - truth) < 0.002, (got, truth)


def test_envelopes_cover_every_class_and_keep_their_ranges():
    from dgli_vision.core.camera import DEFAULT_INTRINSICS
    from dgli_vision.sim.cloth.states import sample_state
    from dgli_vision.sim.dataset import _fits, render_plan
    from dgli_vision.sim.photoreal import ENVELOPES, envelope_of, photo_camera

    for c in ("01", "05", "12"):
        assert {envelope_of("all", c, k) for k in range(3)} == set(ENVELOPES)
    names, _ = render_plan(2, None, 25, by_number=True)
    assert names[:3] == ["01_000", "02_000", "03_000"] and names[12] == "01_001"
    rng = np.random.default_rng(3)
    state = sample_state("06", "AC", rng)
    for env, ((lo, hi), tilt) in ENVELOPES.items():
        pose, info = photo_camera(state, rng, env)
        assert lo <= info["distance_m"] <= hi and info["tilt_deg"] <= tilt
        assert _fits(state, pose, DEFAULT_INTRINSICS, 20.0)
        axis = pose.rotation[:, 2]
        assert np.degrees(np.arccos(-axis[2])) == pytest.approx(info["tilt_deg"], abs=1e-3)


def test_varied_scene_builds_in_blender(small_render):
    """--scene varied's wooden table is a texture feeding the table's colour, and every
    drawn lamp is in the scene."""
    assert bool(small_render["wood_linked"])
    assert int(small_render["lights"]) == int(small_render["looks"]) >= 1
