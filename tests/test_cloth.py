"""The cloth simulator: isometric folds, SPEC's hidden stickers per class, determinism."""

from __future__ import annotations

import numpy as np
import pytest

from dgli_vision.core.layout import default_layout
from dgli_vision.sim.cloth import CLASS_IDS, VARIANTS, flat_mesh, sample_state
from dgli_vision.sim.cloth.states import corner_fold_line, side_fold_line

LAYOUT = default_layout()


def edge_lengths(mesh):
    e = mesh.edges()
    return np.linalg.norm(mesh.xyz[e[:, 0]] - mesh.xyz[e[:, 1]], axis=1)


@pytest.mark.parametrize("angle", [np.pi, np.pi / 2, 2.5])
@pytest.mark.parametrize("under", [False, True])
def test_fold_is_isometric_on_a_mesh_that_resolves_the_hinge(angle, under):
    mesh = flat_mesh(LAYOUT, spacing_mm=1.0)
    step = corner_fold_line(LAYOUT, "B", 180.0, 160.0, under=under)
    folded = step.apply(mesh, angle=angle, thickness_m=8e-3)  # hinge radius 4 mm
    ratio = edge_lengths(folded) / edge_lengths(mesh)
    assert np.all(np.abs(ratio - 1) < 0.01), (ratio.min(), ratio.max())
    assert folded.xyz[:, 2].min() >= -1e-12  # rests on the table


def test_fold_moves_the_flap_and_only_the_flap():
    mesh = flat_mesh(LAYOUT)
    folded = side_fold_line(LAYOUT, "AB", 130.0).apply(mesh, thickness_m=1e-3)
    flap = mesh.uv[:, 1] < 129
    rest = mesh.uv[:, 1] > 131
    np.testing.assert_array_equal(folded.xyz[rest], mesh.xyz[rest])
    # Laid flat over the line v = 130: v -> 260 - v, one thickness up.
    np.testing.assert_allclose(folded.xyz[flap, 1], (260 - mesh.uv[flap, 1]) * 1e-3, atol=2e-3)
    np.testing.assert_allclose(folded.xyz[flap, 2], 1e-3, atol=1e-9)


@pytest.mark.parametrize("class_id", CLASS_IDS)
def test_states_never_stretch_the_cloth(class_id):
    flat = flat_mesh(LAYOUT)
    state = sample_state(class_id, rng=3, wrinkles=False)
    ratio = edge_lengths(state.mesh) / edge_lengths(flat)
    assert ratio.max() < 1.01
    assert state.mesh.xyz[:, 2].min() >= -1e-12


def corner_stickers(corner):
    return {
        s for i, c in enumerate(LAYOUT.segment_corners) if c == corner for s in (2 * i, 2 * i + 1)
    }


def hidden_sets(class_id, variant):
    """SPEC section 3's 'stickers hidden' column: (must be hidden, may be either)."""
    none: set[int] = set()
    if class_id in ("01", "02", "04", "06", "07", "08", "09"):
        return none, none
    if class_id == "03":
        return corner_stickers(variant), none
    if class_id == "10":
        return corner_stickers(variant[0]) | corner_stickers(variant[1]), none
    if class_id == "11":
        far = {"AB": "CD", "BC": "DA", "CD": "AB", "DA": "BC"}[variant]
        return corner_stickers(far[0]) | corner_stickers(far[1]), none
    if class_id == "12":
        k = "ABCD".index(variant)
        crease = corner_stickers("ABCD"[(k + 1) % 4]) | corner_stickers("ABCD"[(k - 1) % 4])
        return corner_stickers("ABCD"[(k + 2) % 4]), crease
    if class_id == "05":
        side, top = variant.split("/")
        lower = side.replace(top, "")
        return none, corner_stickers(lower)
    raise AssertionError(class_id)


@pytest.mark.parametrize("class_id", CLASS_IDS)
def test_hidden_stickers_match_spec_for_every_variant(class_id):
    for k, variant in enumerate(VARIANTS[class_id]):
        for seed in range(2):
            state = sample_state(class_id, variant, rng=[seed, k])
            must, may = hidden_sets(class_id, variant)
            hidden = set(np.flatnonzero(~state.visible).tolist())
            assert must <= hidden, (variant, seed, must - hidden)
            assert hidden <= must | may, (variant, seed, hidden - must - may)


def test_sampling_is_deterministic_for_a_seed():
    a = sample_state("05", rng=123)
    b = sample_state("05", rng=123)
    c = sample_state("05", rng=124)
    assert a.variant == b.variant
    np.testing.assert_array_equal(a.mesh.xyz, b.mesh.xyz)
    assert not np.array_equal(a.mesh.xyz, c.mesh.xyz)


def test_crossing_flaps_stack_second_on_top():
    state = sample_state("05", "AB/B", rng=7, wrinkles=False, placement=False)
    order = state.params["order"]
    assert order == ["A", "B"]
    assert state.mesh.xyz[:, 2].max() == pytest.approx(2e-3, abs=1e-6)


def test_state_placement_rotates_about_the_vertical():
    a = sample_state("02", "A", rng=5, wrinkles=False, placement=False)
    b = sample_state("02", "A", rng=5, wrinkles=False, placement=True)
    np.testing.assert_allclose(a.sticker_points[:, 2], b.sticker_points[:, 2], atol=1e-12)
    np.testing.assert_allclose(a.coordinates(), b.coordinates(), rtol=1e-7, atol=1e-9)


def test_unknown_class_or_variant_is_a_value_error():
    with pytest.raises(ValueError, match="unknown class id '13'"):
        sample_state("13")
    with pytest.raises(ValueError, match="has variants"):
        sample_state("02", "AB")
