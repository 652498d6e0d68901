"""A half fold's, a diagonal fold's and a flap under's crease from the napkin's outline
(classifier/fold_outline.py), where the stickers seen do not fix it, and `verify` on
them: synthetic images with known creases, then renders against the simulator's
truth."""

from __future__ import annotations

import math

import numpy as np
import pytest
from render_cache import rendered

from dgli_vision.classifier.fold_geometry import PRIOR_DOF, STICKER_SD_MM, plane_basis
from dgli_vision.classifier.fold_outline import (
    OutlineView,
    PartMap,
    crease_from_edges,
    edge_profiles,
    fit_part_map,
)
from dgli_vision.core.camera import Intrinsics
from dgli_vision.core.classes import VARIANTS
from dgli_vision.core.fold_lines import nominal_folds
from dgli_vision.core.fold_measure import Crease, fold_measures, planned_crease
from dgli_vision.core.layout import default_layout

LAYOUT = default_layout()
SMALL = Intrinsics(640, 360, 302.5, 302.5, 319.5, 179.5)
#: The renders' seed (held out: no constant of the fit was set on it).
SEED = 5207


def _draw(polys_px: list[np.ndarray], shape: tuple[int, int], k: int = 8) -> np.ndarray:
    """White polygons on a grey table, their edges anti-aliased as a camera sees them
    (drawn k times finer, then averaged), under light falling off across the image and
    a soft shadow; RGB uint8."""
    import cv2

    h, w = shape
    big = np.full((h * k, w * k), 110, np.uint8)
    for poly in polys_px:
        # pixel centres at integer coordinates: pixel (x, y)'s centre is k x + (k - 1) / 2
        fine = np.round((poly * k + (k - 1) / 2.0) * 16).astype(np.int32)
        cv2.fillPoly(big, [fine], 225, lineType=cv2.LINE_8, shift=4)
    small = cv2.resize(big, (w, h), interpolation=cv2.INTER_AREA).astype(float)
    small *= np.linspace(1.0, 0.7, w)[None, :]  # a lamp's fall-off
    # an arm's soft shadow: a band across the image at 45 degrees, half the light,
    # its edges soft over 20 pixels
    y, x = np.mgrid[0:h, 0:w]
    across = (x - y - 150.0) / math.sqrt(2.0)
    small *= 1.0 - 0.5 * np.clip(np.minimum(across + 40, 40 - across) / 20.0 + 0.5, 0, 1)
    return np.repeat(np.round(small).astype(np.uint8)[..., None], 3, axis=2)


def _clip(poly: np.ndarray, crease: Crease, keep_side: np.ndarray) -> np.ndarray:
    """The polygon's part on the side of ``crease`` where ``keep_side`` lies."""
    p, t = np.asarray(crease.point), np.asarray(crease.direction)
    n = np.array([-t[1], t[0]])
    sign = np.sign((keep_side - p) @ n)
    out = []
    for a, b in zip(poly, np.roll(poly, -1, axis=0)):
        da, db = sign * (a - p) @ n, sign * (b - p) @ n
        if da >= 0:
            out.append(a)
        if da * db < 0:
            out.append(a + (b - a) * da / (da - db))
    return np.asarray(out)


def _table(part: PartMap, m: np.ndarray) -> np.ndarray:
    q = np.array(m, dtype=float)
    if part.mirror:
        q[:, 1] = -q[:, 1]
    c, s = math.cos(part.theta), math.sin(part.theta)
    return q @ np.array([[c, -s], [s, c]]).T + part.tau


CASES = {
    "AB half": ("11", "AB", {"inset_mm": 214.0, "skew_deg": 1.5}),
    "B diagonal": ("12", "B", {"offset_mm": -6.0, "turn_deg": -1.0}),
    "CD strip under": ("10", "CD", {"inset_mm": 131.0, "skew_deg": -1.0}),
}


@pytest.mark.parametrize("case", list(CASES))
def test_crease_is_where_the_cloth_ends(case):
    # a folded napkin seen straight down from 500 mm: the part seen (the flap, mirrored,
    # for a fold over; the napkin that stays over a flap under) is the napkin clipped at
    # the true crease, placed on the table by a known map; a white box touches the
    # folded edge over 30 mm, the light falls off across the image, and a soft shadow
    # crosses it
    cid, variant, sizes = CASES[case]
    (fold,) = nominal_folds(cid, variant, LAYOUT)
    true = planned_crease(fold.word, LAYOUT, **sizes)
    square = np.asarray(LAYOUT.corner_uv, dtype=float)
    flap = np.asarray(fold.flap, dtype=float)
    stays = 400.0 - flap if cid != "12" else np.array([0.0, 400.0])
    seen = _clip(square, true, stays if fold.under else flap)
    up = np.array([0.0, 0.0, -1.0])
    view = OutlineView(np.zeros((360, 640, 3), np.uint8), SMALL, up, -0.5, plane_basis(up))
    centre = (np.array([0.0, 0.0, 0.5]) @ view.basis.T) * 1e3  # under the image's centre
    part = PartMap(0.3, np.zeros(2), not fold.under, np.diag([1e-6, 0.5, 0.5]), 1.0, 8)
    part = PartMap(0.3, centre - _table(part, seen.mean(axis=0)[None])[0], part.mirror,
                   part.cov, 1.0, 8)
    t = np.asarray(true.direction)
    n = np.array([-t[1], t[0]])
    n = n if (np.asarray(true.point) - seen.mean(axis=0)) @ n > 0 else -n
    mid = np.asarray(true.point) + (seen.mean(axis=0) - true.point) @ t * t
    box = np.array([mid - 15 * t - 10 * n, mid + 15 * t - 10 * n, mid + 15 * t + 12 * n,
                    mid - 15 * t + 12 * n])
    polys = [view.to_pixels(_table(part, poly), 1.5) for poly in (seen, box)]
    view = OutlineView(_draw(polys, (360, 640)), SMALL, up, -0.5, view.basis)
    along, past = edge_profiles(view, part, fold, LAYOUT)
    assert np.count_nonzero(np.isfinite(past)) > 0.9 * len(along)
    got = crease_from_edges(along, past, part, fold, LAYOUT)
    assert not isinstance(got, str), got
    crease, cov, edges, rms = got
    m = fold_measures(fold.word, crease, LAYOUT)
    for key, want in sizes.items():
        assert m[key] == pytest.approx(want, abs=0.5 if key.endswith("_mm") else 0.2), key
    assert edges >= 0.8 * len(along) and rms < 1.0  # the box's profiles left out
    assert 1.0 < math.sqrt(cov[1, 1]) < 3.0  # the edge's own uncertainty (1.5 mm) counted


def test_no_crease_where_the_edge_is_not_seen():
    # a profile of bare table (no cloth) and a flat napkin's interior give no edge; too
    # few edges give no crease, with why
    (fold,) = nominal_folds("11", "AB", LAYOUT)
    up = np.array([0.0, 0.0, -1.0])
    flat = np.full((360, 640, 3), 120, np.uint8)
    part = PartMap(0.0, np.zeros(2), True, np.eye(3) * 1e-6, 0.0, 8)
    view = OutlineView(flat, SMALL, up, -0.5, plane_basis(up))
    along, past = edge_profiles(view, part, fold, LAYOUT)
    assert len(along) > 50 and not np.isfinite(past).any()
    why = crease_from_edges(along, past, part, fold, LAYOUT)
    assert isinstance(why, str) and "outline" in why


def test_the_part_map_and_its_uncertainty():
    rng = np.random.default_rng(3)
    m = np.asarray(LAYOUT.sticker_uv, dtype=float)[:8]
    true = PartMap(-0.4, np.array([10.0, 30.0]), True, np.zeros((3, 3)), 0.0, 8)
    p = _table(true, m) + rng.normal(0, 1.0, (8, 2))
    fit = fit_part_map(m, p, mirror=True, sticker_sd_mm=STICKER_SD_MM, prior_dof=PRIOR_DOF)
    assert fit.theta == pytest.approx(-0.4, abs=0.02)
    back = fit.to_material(p)
    assert np.sqrt(np.mean(np.sum((back - m) ** 2, axis=1))) < 2.0
    assert np.all(np.sqrt(np.diag(fit.cov))[1:] < 3.0)
    assert fit_part_map(m[:1], p[:1], mirror=True, sticker_sd_mm=2.0, prior_dof=4.0) is None


def _truth(class_id: str, k: int, seed: int) -> tuple[str, dict]:
    """The rendered state's variant and true creases, drawn as render_sample draws
    them (the state comes first from its generator)."""
    from dgli_vision.sim.cloth.states import sample_state

    rng = np.random.default_rng([seed, int(class_id), k, 7])
    variant = VARIANTS[class_id][(k + seed) % len(VARIANTS[class_id])]
    state = sample_state(class_id, variant, rng, layout=LAYOUT)
    return variant, state.params["creases_mm"]


@pytest.fixture(scope="module")
def seen(request):
    """Two half folds and two diagonal folds, rendered (1280 x 720) and classified."""
    from dgli_vision.classifier.pipeline import classify_frame
    from dgli_vision.classifier.references import load_references

    refs = load_references(None)
    out = {}
    for cid, k, conditions in (("11", 0, ()), ("11", 1, ("shadow",)), ("12", 0, ()),
                               ("12", 3, ("jpeg",))):
        frame = rendered(request.config, cid, k, SEED, conditions)
        out[(cid, k)] = (classify_frame(frame, refs, layout=LAYOUT), *_truth(cid, k, SEED))
    return out


def test_half_and_diagonal_folds_measured_from_the_outline(seen):
    for (cid, k), (result, variant, creases) in seen.items():
        p = result.prediction
        assert p is not None and (p.class_id, p.variant) == (cid, variant), (cid, k)
        (f,) = p.folds
        g = f.geometry
        assert g.why is None and g.source == "outline", (cid, k, g.why)
        key = "inset_mm" if cid == "11" else "offset_mm"
        want = fold_measures(f.fold, Crease.through(*creases[f.fold]), LAYOUT)[key]
        sd = g.sd[key.replace("_mm", "_sd_mm")]
        assert abs(g.values[key] - want) <= 5.0, (cid, k, g.values[key], want)
        assert abs(g.values[key] - want) <= 2.0 * sd, (cid, k, sd)
        js = g.to_json()
        assert js["geometry_from"] == "outline" and js[key] is not None
        assert js["geometry_stickers"] >= 2 and len(js["crease_mm"]) == 2


def test_verify_judges_half_and_diagonal_folds(seen):
    from dgli_vision.planning.verify import verify_fold

    for (cid, k), (result, variant, creases) in seen.items():
        word = f"{variant} half" if cid == "11" else f"{variant} diagonal"
        true = fold_measures(word, Crease.through(*creases[word]), LAYOUT)
        for off in (0.0, 30.0, -30.0):
            if cid == "11":
                check = verify_fold(result, (cid, variant), LAYOUT,
                                    inset_mm=true["inset_mm"] + off)
            elif off >= 0.0:  # the planned offset (`dgli verify --offset`)
                check = verify_fold(result, (cid, variant), LAYOUT,
                                    offset_mm=true["offset_mm"] + off)
            else:  # the planned crease (a plan's step)
                plan = planned_crease(word, LAYOUT, offset_mm=true["offset_mm"] + off,
                                      turn_deg=true["turn_deg"])
                check = verify_fold(result, (cid, variant), LAYOUT, fold=word, crease=plan)
            if off == 0.0:
                assert check.success is True, (cid, k, check.line())
            else:
                assert check.success is False, (cid, k, off, check.line())
                key = "inset_mm" if cid == "11" else "offset_mm"
                assert check.errors[key] == pytest.approx(-off, abs=5.0)


def test_verify_command_on_a_half_fold(request, tmp_path):
    # the command a user runs: `dgli verify --inset` passes the half fold made and
    # fails one planned 30 mm deeper; its JSON gives the inset measured, from the
    # outline
    import json

    from click.testing import CliRunner

    from dgli_vision.cli.main import main
    from dgli_vision.sources.frames import write_color, write_depth

    frame = rendered(request.config, "11", 0, SEED, ())
    variant, creases = _truth("11", 0, SEED)
    word = f"{variant} half"
    inset = fold_measures(word, Crease.through(*creases[word]), LAYOUT)["inset_mm"]
    color, depth = tmp_path / "a_color.png", tmp_path / "a_depth.png"
    write_color(color, frame.color)
    write_depth(depth, frame.depth_mm)
    (tmp_path / "intrinsics.json").write_text(json.dumps(frame.intrinsics.to_open3d_dict()))
    run = CliRunner().invoke
    args = ["verify", str(color), str(depth), "--expect", f"11/{variant}"]
    good = run(main, [*args, "--inset", f"{inset:.0f}"])
    assert good.exit_code == 0 and good.output.startswith(f"success: 11/{variant}"), good.output
    bad = run(main, [*args, "--inset", f"{inset + 30:.0f}", "--json"])
    assert bad.exit_code == 1, bad.output
    out = json.loads(bad.output)
    assert out["outcome"] == "failed" and out["errors"]["inset_mm"] == pytest.approx(-30, abs=5)
    # an offset is a diagonal fold's: asked of a half fold, refused before looking
    wrong = run(main, [*args, "--offset", "0"])
    assert wrong.exit_code == 2 and "has no diagonal fold" in wrong.output, wrong.output
    measured = out["measured"]  # the fold as `dgli classify --json` gives it
    assert measured["geometry_from"] == "outline" and measured["why"] is None
    assert measured["inset_mm"] == pytest.approx(inset, abs=5.0)
    assert measured["inset_sd_mm"] > 0


def test_a_misread_sticker_is_left_out_of_the_map():
    from dgli_vision.classifier.fold_outline import _part_map

    m = np.asarray(LAYOUT.sticker_uv, dtype=float)[:8]
    true = PartMap(0.2, np.array([-50.0, 80.0]), True, np.zeros((3, 3)), 0.0, 8)
    p = _table(true, m)
    p[3] += np.array([25.0, -10.0])  # read 27 mm off
    fit = _part_map(m, p, True, STICKER_SD_MM, PRIOR_DOF, 12.0)
    assert fit.stickers == 7 and fit.rms_mm < 0.01
    assert np.allclose(fit.to_material(_table(true, m)), m, atol=0.01)
