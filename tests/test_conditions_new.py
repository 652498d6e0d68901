"""The renderer's newer capture conditions: each makes what it says (the pipeline's answers
under them are the subject of tests/test_robustness.py)."""

from __future__ import annotations

import json
from functools import lru_cache, partial
from pathlib import Path

import cv2
import numpy as np
from guards import read_only
from numpy.typing import NDArray

from dgli_vision.core.camera import Intrinsics
from dgli_vision.core.colour import srgb_to_linear
from dgli_vision.core.layout import default_layout
from dgli_vision.sim.dataset import render_sample

LAYOUT = default_layout()
#: Half SPEC's camera in each direction: a quarter of the pixels, to keep the tests fast.
SMALL = Intrinsics(640, 360, 302.5, 302.5, 319.5, 179.5)


@lru_cache(maxsize=16)
def render_small(class_id: str, k: int, seed: int, conditions: tuple[str, ...] = ()):
    """Sample ``k`` of a class at a quarter of SPEC's pixels (cached: tests share them;
    read-only)."""
    sample = render_sample(class_id, k, seed, conditions=conditions, intrinsics=SMALL)
    read_only(sample)
    return sample


def disc_ring(result, sid: int, fraction: float = 0.75) -> tuple[NDArray, NDArray]:
    """Pixel columns and rows of 24 points on a ring of a sticker's disc (outside its dot)."""
    px = result.intrinsics.project(result.sticker_points_cam[sid : sid + 1])[0]
    radius = (
        LAYOUT.disc_diameter_mm / 2e3 * result.intrinsics.fx / result.sticker_points_cam[sid, 2]
    )
    ang = np.linspace(0, 2 * np.pi, 24, endpoint=False)
    u = np.rint(px[0] + fraction * radius * np.cos(ang)).astype(int)
    v = np.rint(px[1] + fraction * radius * np.sin(ang)).astype(int)
    return u, v


def hsv_of(rgb: NDArray) -> NDArray:
    """HSV (n, 3) of 8-bit RGB (n, 3): hue in degrees, saturation and value in [0, 1]."""
    hsv = cv2.cvtColor(rgb.reshape(-1, 1, 3).astype(np.uint8), cv2.COLOR_RGB2HSV_FULL)
    return hsv.reshape(-1, 3).astype(float) * np.array([360 / 256, 1 / 255, 1 / 255])


def hue_gap(a: float, b: float) -> float:
    return abs((a - b + 180) % 360 - 180)


# --- sheen: a large light washes a corner's stickers to pastel ---------------------------


def test_sheen_washes_the_mirrored_sticker_to_pastel_keeping_its_hue_and_blows_nothing_out():
    for class_id, k, seed in (("01", 0, 3),):
        s = render_small(class_id, k, seed, ("sheen",))
        plain = render_small(class_id, k, seed)  # the same scene under the usual light
        r = s.result
        sid = r.info["sheen_sticker"]
        u, v = disc_ring(r, sid)
        washed = hsv_of(r.color[v, u])
        before = hsv_of(plain.result.color[v, u])
        assert 0.1 <= np.median(washed[:, 1]) <= 0.3
        assert np.median(before[:, 1]) > 0.6  # the same sticker, saturated without it
        nominal = hsv_of(np.array(LAYOUT.colours_srgb[LAYOUT.sticker_disc[sid]]))[0, 0]
        assert hue_gap(np.median(washed[:, 0]), nominal) < 20
        assert r.color.max() < 250  # nothing blown out: no channel near clipping


def test_sheen_washes_a_whole_corner_and_brightens_the_napkin_around_it():
    s = render_small("01", 0, 3, ("sheen",))
    plain = render_small("01", 0, 3)
    r = s.result
    sid = r.info["sheen_sticker"]
    corner = [i for i in range(16) if (i + 2) % 16 // 4 == (sid + 2) % 16 // 4]
    for i in corner:  # the corner's four stickers (its two segments)
        u, v = disc_ring(r, i)
        assert np.median(hsv_of(r.color[v, u])[:, 1]) < 0.45

    def napkin_beside(result, sticker: int) -> float:
        """Linear brightness of the bare napkin 45 mm inwards from a sticker."""
        uv = LAYOUT.sticker_uv[sticker]
        inward = np.array([LAYOUT.width_mm, LAYOUT.height_mm]) / 2 - uv
        point = s.state.mesh.interpolate((uv + 45 * inward / np.linalg.norm(inward))[None])
        cam = result.pose.world_to_camera(point)
        u, v = np.rint(result.intrinsics.project(cam)[0]).astype(int)
        patch = result.color[v - 2 : v + 3, u - 2 : u + 3].reshape(-1, 3)
        return float(srgb_to_linear(np.median(patch, axis=0) / 255).mean())

    far = (sid + 8) % 16  # the opposite corner's sticker
    lit = napkin_beside(r, sid) / napkin_beside(r, far)
    assert lit > 1.05 * napkin_beside(plain.result, sid) / napkin_beside(plain.result, far)


# --- mirror, backface, depthscale --------------------------------------------------------


def test_mirror_flips_colour_and_depth_together_and_keeps_the_intrinsics():
    plain = render_small("02", 0, 5)
    s = render_small("02", 0, 5, ("mirror",))
    np.testing.assert_array_equal(s.result.color, plain.result.color[:, ::-1])
    np.testing.assert_array_equal(s.result.depth_mm, plain.result.depth_mm[:, ::-1])
    assert s.result.intrinsics == plain.result.intrinsics == SMALL
    assert s.state.class_id == "02"
    # the truth's points project to where the mirrored image shows the stickers
    px = SMALL.project(s.result.sticker_points_cam)
    px0 = SMALL.project(plain.result.sticker_points_cam)
    np.testing.assert_allclose(px[:, 0], SMALL.width - 1 - px0[:, 0], atol=1e-6)
    np.testing.assert_allclose(px[:, 1], px0[:, 1], atol=1e-6)


def test_backface_turns_the_napkin_over_and_draws_the_stickers_on_the_back_face():
    flat = render_small("01", 0, 5, ("backface",))
    r = flat.result
    assert flat.state.params["turned_over_axis_deg"] == flat.conditions.backface_axis_deg
    assert r.visible.all()
    for sid in range(16):  # each sticker shows its printed disc colour on the back face
        u, v = disc_ring(r, sid)
        hue = np.median(hsv_of(r.color[v, u])[:, 0])
        nominal = hsv_of(np.array(LAYOUT.colours_srgb[LAYOUT.sticker_disc[sid]]))[0, 0]
        assert hue_gap(hue, nominal) < 20, sid
    # seen from the back, the corners run the other way round: A -> B -> C is clockwise
    # in the image when front up and counter-clockwise when turned over (or vice versa)
    front = render_small("01", 0, 5).result

    def turn(result) -> float:
        a, b, c = result.intrinsics.project(result.sticker_points_cam[[0, 4, 8]])
        (x0, y0), (x1, y1) = b - a, c - b
        return float(x0 * y1 - y0 * x1)

    assert np.sign(turn(r)) == -np.sign(turn(front))
    # a corner folded over lies under the napkin once it is turned over: the layer
    # order reverses, and the flap's stickers are hidden
    fold = render_small("02", 0, 5)
    over = render_small("02", 0, 5, ("backface",))
    assert over.state.class_id == fold.state.class_id and fold.result.visible.all()
    flap = {"A": [14, 15, 0, 1], "B": [2, 3, 4, 5], "C": [6, 7, 8, 9], "D": [10, 11, 12, 13]}
    hidden = ~over.result.visible
    assert hidden[flap[fold.state.variant]].all() and hidden.sum() == 4
    assert over.state.mesh.xyz[:, 2].min() == fold.state.mesh.xyz[:, 2].min()


def test_depthscale_scales_every_depth_reading_and_leaves_colour_alone():
    plain = render_small("01", 0, 5)
    s = render_small("01", 0, 5, ("depthscale",))
    scale = s.conditions.depth_scale
    assert 0.75 <= scale <= 0.85 or 1.2 <= scale <= 1.3
    np.testing.assert_array_equal(s.result.color, plain.result.color)
    d0, d = plain.result.depth_mm.astype(float), s.result.depth_mm.astype(float)
    np.testing.assert_array_equal(d0 == 0, d == 0)
    assert np.abs(d - d0 * scale)[d0 > 0].max() <= 1.0


# --- lens distortion: OpenCV's model, unknown or written with the intrinsics -------------


def test_distortion_moves_border_stickers_as_opencvs_model_says():
    plain = render_small("01", 1, 9)
    s = render_small("01", 1, 9, ("distortion-known",))
    coeffs = np.array(s.result.intrinsics.distortion)
    k1, k2, p1, p2, k3 = coeffs
    assert 0.06 <= k1 <= 0.12 and -0.06 <= k2 <= 0 and max(abs(p1), abs(p2)) <= 0.002
    assert k3 == 0 and s.result.intrinsics.matrix().tolist() == SMALL.matrix().tolist()
    pts = plain.result.sticker_points_cam
    ideal = SMALL.project(pts)
    seen, _ = cv2.projectPoints(pts / pts[:, 2:], np.zeros(3), np.zeros(3), SMALL.matrix(), coeffs)
    seen = seen.reshape(-1, 2)
    far = int(np.argmax(np.linalg.norm(seen - ideal, axis=1)))  # the most displaced sticker
    radius = LAYOUT.disc_diameter_mm / 2e3 * SMALL.fx / pts[far, 2]

    def centroid(image: NDArray, near: NDArray) -> NDArray:
        """Centre of the saturated (sticker) pixels within 1.4 radii of ``near``."""
        u0, v0 = np.rint(near).astype(int)
        m = int(np.ceil(1.4 * radius))
        window = image[v0 - m : v0 + m + 1, u0 - m : u0 + m + 1]
        sat = hsv_of(window.reshape(-1, 3))[:, 1].reshape(window.shape[:2])
        vv, uu = np.nonzero(sat > 0.45)  # the sticker's disc and dot
        return np.array([uu.mean() + u0 - m, vv.mean() + v0 - m])

    moved = centroid(s.result.color, seen[far]) - centroid(plain.result.color, ideal[far])
    assert np.linalg.norm(seen[far] - ideal[far]) > 1.0
    assert np.linalg.norm(moved - (seen[far] - ideal[far])) < 0.25


def test_lens_distortion_moves_colour_and_depth_as_opencvs_full_model_says():
    from dgli_vision.sim.conditions import apply_lens_distortion

    coeffs = (0.1, -0.05, 0.002, -0.002, 0.0)
    color = np.zeros((SMALL.height, SMALL.width, 3), np.uint8)
    depth = np.zeros((SMALL.height, SMALL.width), np.uint16)
    spots = np.array([[60, 40], [580, 320], [320, 30], [320, 180]])  # corners, edge, centre
    for u, v in spots:  # 7 x 7 squares centred on the spots
        color[v - 3 : v + 4, u - 3 : u + 4] = 255
        depth[v - 3 : v + 4, u - 3 : u + 4] = 600
    norm = np.column_stack([(spots - [SMALL.cx, SMALL.cy]) / SMALL.fx, np.ones(len(spots))])
    full, _ = cv2.projectPoints(norm, np.zeros(3), np.zeros(3), SMALL.matrix(), coeffs)
    radial, _ = cv2.projectPoints(
        norm, np.zeros(3), np.zeros(3), SMALL.matrix(), (coeffs[0], 0, 0, 0)
    )
    full, radial = full.reshape(-1, 2), radial.reshape(-1, 2)
    c, d = apply_lens_distortion(color, depth, SMALL, coeffs)
    for k, (u, v) in enumerate(np.rint(full).astype(int)):
        win_c = c[v - 12 : v + 13, u - 12 : u + 13, 0].astype(float)
        win_d = (d[v - 12 : v + 13, u - 12 : u + 13] > 0).astype(float)
        yy, xx = np.mgrid[v - 12 : v + 13, u - 12 : u + 13]
        for w in (win_c, win_d):  # colour and depth moved alike
            centre = np.array([(w * xx).sum(), (w * yy).sum()]) / w.sum()
            assert np.linalg.norm(centre - full[k]) < 0.3, (k, centre, full[k])
    # the corners move far from where k1 alone would put them: k2 and p count
    assert np.linalg.norm(full[:2] - radial[:2], axis=1).min() > 3


def test_lens_distortion_takes_k1_alone_or_opencvs_coefficient_vector():
    from dgli_vision.sim.conditions import apply_lens_distortion

    r = render_small("01", 1, 9).result
    a = apply_lens_distortion(r.color, r.depth_mm, SMALL, 0.1)
    b = apply_lens_distortion(r.color, r.depth_mm, SMALL, (0.1, 0.0, 0.0, 0.0))
    np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_array_equal(a[1], b[1])


def test_a_known_lens_is_one_for_the_whole_set_and_written_into_intrinsics_json(tmp_path):
    from dgli_vision.sources.labelled import write_labelled_folder

    samples = [render_small(c, 0, 4, ("distortion-known",)) for c in ("01", "02")]
    unknown = render_small("01", 0, 4, ("distortion",))
    assert samples[0].result.intrinsics == samples[1].result.intrinsics
    assert unknown.result.intrinsics == SMALL  # uncorrected and unannounced
    write_labelled_folder(tmp_path / "set", samples, {"command": "test"})
    data = json.loads((tmp_path / "set" / "intrinsics.json").read_text())
    assert data["distortion"] == list(samples[0].result.intrinsics.distortion)
    assert len(data["distortion"]) == 5 and data["distortion"][4] == 0.0



def test_a_set_whose_pairs_come_from_two_cameras_keeps_each_pairs_intrinsics(tmp_path):
    """``combo`` may draw ``distortion-known`` for some pairs only: those pairs go to a
    subfolder with their own intrinsics, and the folder reads back pair by pair."""
    from dgli_vision.sources.labelled import find_labelled_pairs, write_labelled_folder

    plain = render_small("01", 0, 4)
    lens = render_small("02", 0, 4, ("distortion-known",))
    labels = write_labelled_folder(tmp_path / "set", [plain, lens], {"command": "test"})
    pairs, problems = find_labelled_pairs(labels.parent)
    assert not problems
    pairs = sorted(pairs, key=lambda p: p.color)
    assert [Path(p.color).parent.name for p in pairs] == ["set", "camera2"]
    frames = [p.load() for p in pairs]
    assert frames[0].intrinsics == plain.result.intrinsics
    assert frames[1].intrinsics == lens.result.intrinsics

# --- grasp: a gripper holding the corner it folds -----------------------------------------


def tip_pixel_is_dark(sample) -> bool:
    """Whether the held corner's tip is under the gripper's (dark) finger in the image."""
    from dgli_vision.sim.conditions import grasp_frame

    tip, _, _ = grasp_frame(sample.state, sample.state.params["held_corner"])
    r = sample.result
    u, v = np.rint(r.intrinsics.project(r.pose.world_to_camera(tip[None]))[0]).astype(int)
    return bool(np.median(r.color[v - 1 : v + 2, u - 1 : u + 2]) < 90)


def test_the_grasp_gripper_closes_its_fingers_on_the_corner_tip():
    from dgli_vision.sim.conditions import grasp_frame, held_gripper

    s = render_small("02", 0, 5, ("grasp",))
    corner = s.state.params["held_corner"]
    assert corner == s.state.variant  # the folded corner is the one held
    tip, away, normal = grasp_frame(s.state, corner)
    assert np.linalg.norm(tip - s.state.corner_points["ABCD".index(corner)]) < 1e-3
    fingers = held_gripper(tip, away, normal, np.random.default_rng(0)).vertices[:16] - tip
    across, along = fingers @ normal, fingers @ away
    assert (across[:8] > 0).all() and (across[8:] < 0).all()  # one on either side of the cloth
    assert np.abs(across).max() < 0.011 and along.min() < 0 < along.max()  # round the tip
    assert tip_pixel_is_dark(s)


def test_grasp_states_follow_the_90_degree_rule():
    flat = render_small("01", 0, 5, ("grasp",))
    assert flat.state.class_id == "01" and flat.state.params["stage"].startswith("rising")
    assert 20 <= flat.state.params["last_fold_deg"] <= 80
    for k in range(2):  # a fold settling past 90 degrees, or laid flat, keeps the class
        s = render_small("09", k, 5, ("grasp",))
        assert s.state.class_id == "09"
        assert s.conditions.grasp.settle_deg == s.state.params.get("last_fold_deg", 180.0)
        assert s.conditions.grasp.settle_deg > 90
        assert s.state.params["held_corner"] in s.state.variant  # one of the folded side's


def test_a_sequence_rendered_with_the_gripper_holds_the_corner_being_folded():
    from dgli_vision.sim.dataset import render_sequence

    frames = list(
        render_sequence("I", 2, 5, conditions=("grasp",), intrinsics=SMALL, progress=[0.4, 1.6])
    )
    assert [f.state.params["held_corner"] for f in frames] == ["A", "C"]
    assert [(f.state.class_id, f.state.variant) for f in frames] == [("01", None), ("06", "AC")]
    assert all(tip_pixel_is_dark(f) for f in frames)


def test_render_gripper_option_puts_the_grasp_in_a_sequence(tmp_path, monkeypatch):
    from click.testing import CliRunner

    from dgli_vision.cli import main
    from dgli_vision.sim import dataset

    small = partial(dataset.render_sequence, intrinsics=SMALL)  # fewer pixels, same scene
    monkeypatch.setattr(dataset, "render_sequence", small)
    out = tmp_path / "run"
    args = ["render", str(out), "--sequence", "III", "--frames", "2", "--gripper"]
    res = CliRunner().invoke(main, args)
    assert res.exit_code == 0, res.output
    truth = json.loads((out / "truth.json").read_text())
    assert truth["provenance"]["conditions"] == ["grasp"]
    held = [im["state_params"]["held_corner"] for im in truth["images"].values()]
    assert len(held) == 2 and set(held) <= {"A", "B"}


# --- the reliability table ----------------------------------------------------------------


def fake_outcome(args):
    """Outcome of pair ``class i``: best guess of confidence (i - 1) / 12, right for odd
    class numbers, given at 0.25 and above; class 12 has no guess at all."""
    condition, _, k, class_id = args
    i = int(class_id)
    truth = f"{class_id}/x"
    if i == 12:
        return f"{class_id}_{k:03d}", truth, None, None, (condition,), None
    confidence = (i - 1) / 12
    guess = class_id if i % 2 else "99"
    given = guess if confidence >= 0.25 else None
    return f"{class_id}_{k:03d}", truth, given, "x", (condition,), (guess, confidence)


def test_the_reliability_table_counts_right_best_guesses_per_confidence_bin(monkeypatch):
    from dgli_vision.analysis import robustness

    monkeypatch.setattr(robustness, "_one", fake_outcome)
    scores = robustness.score_condition("cast", None, per_class=1, seed=0)
    scores += robustness.score_condition("combo", None, per_class=1, seed=0)
    assert len(scores) == 4  # combo's two parts are not counted again
    rows = robustness.reliability_rows(scores)
    assert [r["confidence"] for r in rows] == [
        "[0, 0.1)",
        "[0.1, 0.25)",
        "[0.25, 0.5)",
        "[0.5, 0.75)",
        "[0.75, 1]",
    ]
    # confidences 0, 1/12 | 2/12 | 3/12, 4/12, 5/12 | 6/12, 7/12, 8/12 | 9/12, 10/12
    assert [r["answers"] for r in rows] == [4, 2, 6, 6, 4]
    assert [r["right"] for r in rows] == [2, 2, 2, 4, 2]
    header, table = robustness.reliability_table(scores)
    assert header == ["confidence", "answers", "right", "right %"]
    assert table[1] == ["[0.1, 0.25)", "2", "2", "100%"]


def test_the_robustness_command_prints_and_writes_the_reliability_table(tmp_path, monkeypatch):
    from click.testing import CliRunner

    from dgli_vision.analysis import robustness
    from dgli_vision.cli import main

    monkeypatch.setattr(robustness, "_one", fake_outcome)
    md = tmp_path / "table.md"
    args = ["robustness", "--per-class", "1", "--conditions", "sheen,mirror", "-j", "1"]
    res = CliRunner().invoke(main, [*args, "--json", "--markdown", str(md)])
    assert res.exit_code == 0, res.output
    data = json.loads(res.output)
    assert [r["condition"] for r in data["rows"]] == ["sheen", "mirror"]
    assert [r["answers"] for r in data["reliability"]] == [4, 2, 6, 6, 4]
    assert "| [0.75, 1] | 4 | 2 | 50% |" in md.read_text()
    res = CliRunner().invoke(main, args)
    assert "| [0.5, 0.75) | 6 | 4 | 67% |" in res.output
