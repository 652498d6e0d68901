"""The maths core against independent facts: quadrature, linking numbers, symmetries."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import integrate

from dgli_vision.analysis.bench import baseline_gli_pair, baseline_gli_pair_numpy
from dgli_vision.core.dgli import DEFAULT_CLIP, cloth_coordinates, dgli, gli, pair_indices

RNG_SEED = 20261121


def gauss_integral_quadrature(a, b, c, d):
    """The double integral of the GLI's definition by adaptive quadrature."""
    t1, t2 = b - a, d - c
    cross = np.cross(t1, t2)

    def integrand(t, s):
        w = a + s * t1 - (c + t * t2)
        return float(cross @ w) / float(w @ w) ** 1.5

    value, _ = integrate.dblquad(integrand, 0, 1, 0, 1, epsabs=1e-14, epsrel=1e-12)
    return value / (4 * np.pi)


def rotation_about(axis, angle):
    """Rodrigues rotation matrix."""
    k = np.asarray(axis, float) / np.linalg.norm(axis)
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * kx + (1 - np.cos(angle)) * kx @ kx


def polygon_linking_number(p1, p2):
    """Sum of the GLI over all segment pairs of two closed polygons (n, 3) and (k, 3)."""
    a, b = p1, np.roll(p1, -1, axis=0)
    c, d = p2, np.roll(p2, -1, axis=0)
    return float(gli(a[:, None], b[:, None], c[None, :], d[None, :]).sum())


def test_gli_matches_quadrature_of_the_double_integral():
    rng = np.random.default_rng(RNG_SEED)
    for _ in range(6):
        a, b, c, d = rng.normal(size=(4, 3))
        exact = gauss_integral_quadrature(a, b, c, d)
        assert abs(exact) > 1e-4  # non-coplanar, informative pair
        assert gli(a, b, c, d) == pytest.approx(exact, rel=1e-6)


def test_gli_matches_klenin_langowski_arcsin_formula_with_sign():
    rng = np.random.default_rng(RNG_SEED + 1)
    pts = rng.normal(size=(300, 4, 3))
    ours = gli(pts[:, 0], pts[:, 1], pts[:, 2], pts[:, 3])
    theirs = [baseline_gli_pair(*p) for p in pts.tolist()]
    theirs_np = [baseline_gli_pair_numpy(*p) for p in pts[:50]]
    np.testing.assert_allclose(ours, theirs, atol=1e-12)
    np.testing.assert_allclose(ours[:50], theirs_np, atol=1e-12)
    # Without the sign factor the formula is wrong about half the time.
    assert np.mean(np.sign(ours) != np.sign(np.abs(theirs))) > 0.2


def circle(n, radius=1.0, centre=(0, 0, 0), normal=(0, 0, 1)):
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    pts = np.stack([radius * np.cos(t), radius * np.sin(t), np.zeros(n)], axis=1)
    z = np.array([0, 0, 1.0])
    nrm = np.asarray(normal, float) / np.linalg.norm(normal)
    axis = np.cross(z, nrm)
    if np.linalg.norm(axis) > 1e-12:
        pts = pts @ rotation_about(axis, np.arccos(np.clip(z @ nrm, -1, 1))).T
    return pts + np.asarray(centre, float)


def torus_curve(n, phase, p_turns=1, q_turns=2, big=2.0, small=0.7):
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    theta, phi = p_turns * t, q_turns * t + phase
    rr = big + small * np.cos(phi)
    return np.stack([rr * np.cos(theta), rr * np.sin(theta), small * np.sin(phi)], axis=1)


def whitehead_link(n):
    """A figure-eight (Gerono lemniscate) and a circle around its crossing, drawn as the
    alternating five-crossing diagram: the Whitehead link L5a1 (linking number 0)."""
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    eight = np.stack([np.cos(t), np.sin(t) * np.cos(t), 0.1 * np.sin(t)], axis=1)
    ring = np.stack([0.3 * np.cos(t), 0.3 * np.sin(t), 0.3 * np.sin(2 * t)], axis=1)
    return eight, ring


@pytest.mark.parametrize(
    ("name", "curves", "expected"),
    [
        ("Hopf link", (circle(150), circle(150, centre=(1, 0, 0), normal=(0, 1, 0))), 1),
        ("(2,4) torus link", (torus_curve(300, 0.0), torus_curve(300, np.pi)), 2),
        ("Whitehead link", whitehead_link(400), 0),
        ("unlinked rings", (circle(100), circle(100, centre=(3, 0, 0), normal=(0, 1, 0))), 0),
        ("rings side by side", (circle(100), circle(100, centre=(0.5, 0, 0.2))), 0),
    ],
)
def test_linking_numbers_of_closed_polygons(name, curves, expected):
    lk = polygon_linking_number(*curves)
    assert abs(abs(lk) - expected) < 1e-6, f"{name}: {lk}"


def test_linking_number_sign_follows_orientation():
    c1, c2 = circle(80), circle(80, centre=(1, 0, 0), normal=(0, 1, 0))
    lk = polygon_linking_number(c1, c2)
    assert polygon_linking_number(c1[::-1], c2) == pytest.approx(-lk, abs=1e-9)
    assert polygon_linking_number(c2, c1) == pytest.approx(lk, abs=1e-9)


def central_richardson(f, h=1e-3):
    """Derivative at 0 by Richardson-extrapolated central differences (error ~h^6)."""
    d1 = (f(h) - f(-h)) / (2 * h)
    d2 = (f(h / 2) - f(-h / 2)) / h
    d4 = (f(h / 4) - f(-h / 4)) / (h / 2)
    r1 = (4 * d2 - d1) / 3
    r2 = (4 * d4 - d2) / 3
    return (16 * r2 - r1) / 15


def test_dgli_is_the_derivative_of_gli_along_up():
    rng = np.random.default_rng(RNG_SEED + 2)
    for _ in range(20):
        a, b, c, d = rng.normal(size=(4, 3))
        up = rng.normal(size=3)
        u = up / np.linalg.norm(up)
        fd = central_richardson(lambda e, a=a, b=b, c=c, d=d, u=u: gli(a, b + e * u, c, d + e * u))
        assert dgli(a, b, c, d, up) == pytest.approx(fd, rel=1e-7, abs=1e-10)


def test_dgli_of_flat_configurations_is_finite_and_informative():
    a, b, c, d = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 2, 0.0]])
    assert gli(a, b, c, d) == 0.0
    value = dgli(a, b, c, d)
    up = np.array([0, 0, 1.0])
    fd = central_richardson(lambda e: gli(a, b + e * up, c, d + e * up))
    assert value != 0.0
    assert value == pytest.approx(fd, rel=1e-7)


def test_coplanar_gli_is_zero():
    rng = np.random.default_rng(RNG_SEED + 3)
    plane = np.linalg.qr(rng.normal(size=(3, 3)))[0][:, :2]  # two orthonormal columns
    pts = rng.normal(size=(500, 4, 2)) @ plane.T + rng.normal(size=3)
    np.testing.assert_allclose(gli(*pts.transpose(1, 0, 2)), 0.0, atol=1e-12)


def test_collinear_pairs_give_zero():
    a, b, c, d = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0.0]])
    assert gli(a, b, c, d) == 0.0
    assert dgli(a, b, c, d) == 0.0


def test_dgli_is_symmetric():
    rng = np.random.default_rng(RNG_SEED + 4)
    a, b, c, d = rng.normal(size=(4, 1000, 3))
    np.testing.assert_allclose(dgli(a, b, c, d), dgli(c, d, a, b), rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(gli(a, b, c, d), gli(c, d, a, b), rtol=1e-10, atol=1e-14)


def test_invariance_under_rotation_about_up_and_translation():
    rng = np.random.default_rng(RNG_SEED + 5)
    segs = rng.normal(size=(50, 8, 2, 3))
    up = np.array([0.2, -0.3, 1.0])
    ref = cloth_coordinates(segs, up)
    for angle in (0.3, 2.0, -1.1):
        moved = segs @ rotation_about(up, angle).T + rng.normal(size=3) * 10
        np.testing.assert_allclose(cloth_coordinates(moved, up), ref, rtol=1e-9, atol=1e-11)


def test_invariance_under_rotating_points_and_up_together():
    rng = np.random.default_rng(RNG_SEED + 6)
    a, b, c, d = rng.normal(size=(4, 200, 3))
    rot = rotation_about(rng.normal(size=3), 0.9)
    up = np.array([0, 0, 1.0])
    np.testing.assert_allclose(
        dgli(a @ rot.T, b @ rot.T, c @ rot.T, d @ rot.T, rot @ up),
        dgli(a, b, c, d, up),
        rtol=1e-9,
        atol=1e-11,
    )


@pytest.mark.parametrize("lam", [1e-3, 0.5, 7.0, 1e3])
def test_dgli_scales_as_one_over_lambda(lam):
    rng = np.random.default_rng(RNG_SEED + 7)
    segs = rng.normal(size=(20, 8, 2, 3))
    np.testing.assert_allclose(
        cloth_coordinates(lam * segs), cloth_coordinates(segs) / lam, rtol=1e-9
    )
    # GLI is scale-free.
    a, b, c, d = segs[:, :4, 0].transpose(1, 0, 2)
    np.testing.assert_allclose(
        gli(lam * a, lam * b, lam * c, lam * d), gli(a, b, c, d), atol=1e-12
    )


def test_cloth_coordinates_order_and_shape():
    rng = np.random.default_rng(RNG_SEED + 8)
    segs = rng.normal(size=(3, 2, 8, 2, 3))
    out = cloth_coordinates(segs)
    assert out.shape == (3, 2, 28)
    i, j = pair_indices(8)
    assert list(zip(i[:3], j[:3])) == [(0, 1), (0, 2), (0, 3)]
    assert (i[-1], j[-1]) == (6, 7)
    s = segs[1, 1]
    expected = dgli(s[i, 0], s[i, 1], s[j, 0], s[j, 1])
    np.testing.assert_allclose(out[1, 1], expected, rtol=1e-12)


def test_cloth_coordinates_large_batch_spans_blocks():
    rng = np.random.default_rng(RNG_SEED + 9)
    segs = rng.normal(size=(1000, 8, 2, 3))
    out = cloth_coordinates(segs)
    i, j = pair_indices(8)
    s = segs[-1]
    np.testing.assert_allclose(out[-1], dgli(s[i, 0], s[i, 1], s[j, 0], s[j, 1]), rtol=1e-12)


def test_one_state_gets_bit_for_bit_the_coordinates_of_a_batch():
    # a frame alone goes through the stacked kernel for few pairs, the references were
    # built in batches by the blocked one: the two must agree to the last bit, also on
    # touching, zero-length, coplanar and missing segments
    rng = np.random.default_rng(RNG_SEED + 17)
    segs = rng.normal(size=(40, 8, 2, 3))
    segs[1, 1, 0] = segs[1, 0, 1]  # touching at an end
    segs[2, ..., 2] = 0.0  # all coplanar
    segs[3, 2, 1] = segs[3, 2, 0]  # zero length
    segs[4, 5] = np.nan  # missing
    segs[5] = np.round(segs[5], 0)  # crossings on a grid
    segs[6, :, :, 2] = 0.0
    segs[6, 0] = [[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0]]
    segs[6, 1] = [[0.0, -1.0, 0.0], [0.0, 1.0, 0.0]]  # crossing interiors
    up = np.array([0.1, -0.2, 0.97])
    batch = cloth_coordinates(np.repeat(segs, 50, axis=0), up)[::50]
    for k, s in enumerate(segs):
        alone = cloth_coordinates(s, up)
        assert np.array_equal(alone, batch[k], equal_nan=True), k
        assert np.array_equal(np.signbit(alone), np.signbit(batch[k])), k
    assert (cloth_coordinates(segs[6], up)[0] == 0.0) and np.isnan(batch[4]).any()


def test_missing_segment_gives_nan_only_for_its_pairs():
    rng = np.random.default_rng(RNG_SEED + 10)
    segs = rng.normal(size=(8, 2, 3))
    segs[3, 1] = np.nan
    out = cloth_coordinates(segs)
    i, j = pair_indices(8)
    involved = (i == 3) | (j == 3)
    assert np.isnan(out[involved]).all()
    assert np.isfinite(out[~involved]).all()
    assert np.isnan(dgli([0, 0, np.nan], [1, 0, 0], [0, 1, 1], [1, 1, 1]))
    assert np.isnan(gli([0, 0, np.nan], [1, 0, 0], [0, 1, 1], [1, 1, 1]))


def test_near_touching_pair_is_clipped_scale_aware_keeping_sign():
    # The end of a -> b nearly touches the start of c -> d: moving b and d up separates
    # them, and the exact dGLI grows like 1 / gap.
    for lam in (1.0, 1e-3):
        for mirror in (1.0, -1.0):
            a, b = np.array([-1, 0, 0.0]) * lam, np.array([0, 0, 0.0]) * lam
            c, d = np.array([1e-7, 0, 0]) * lam, np.array([0.3, mirror, 0.2]) * lam
            value = dgli(a, b, c, d)
            bound = DEFAULT_CLIP / (0.5 * (np.linalg.norm(b - a) + np.linalg.norm(d - c)))
            unclipped = dgli(a, b, c, d, clip=np.inf)
            assert abs(unclipped) > 1e3 * bound
            assert abs(value) == pytest.approx(bound)
            assert np.sign(value) == np.sign(unclipped) == mirror
    # Far from touching, nothing is clipped.
    c = np.array([0.5, 0, 0])
    assert dgli(a, b, c, d) == dgli(a, b, c, d, clip=np.inf)


def test_dgli_stays_bounded_near_a_crossing():
    # Near a crossing the GLI jumps by 1 across the gap, but each one-sided derivative is
    # finite: the exact dGLI does not blow up there (a forward difference would).
    a, b = np.array([-1, 0, 0.0]), np.array([3, 0, 0.0])
    values = [dgli(a, b, [0, -3, g], [0, 1, g]) for g in (1e-2, 1e-4, 1e-6)]
    np.testing.assert_allclose(values, values[-1], rtol=1e-2)
    above, below = gli(a, b, [0, -3, 1e-6], [0, 1, 1e-6]), gli(a, b, [0, -3, -1e-6], [0, 1, -1e-6])
    assert above == pytest.approx(-0.5, abs=1e-5) and below == pytest.approx(0.5, abs=1e-5)


@pytest.mark.parametrize(
    ("gap", "c", "d"),
    [
        # c -> d passes over the interior of a -> b: the GLI tends to -+1/2 as gap -> 0
        (1e-3, [0.2, -1, 1], [0.1, 1, 1]),
        # c lies just off the interior of a -> b (a T): it tends to -+1/4 and more
        (1e-2, [0.3, 0, 1], [0.1, 1, 0.5]),
        # c lies just off b, the end of a -> b
        (1e-2, [1, 0, 1], [1.5, 1, -0.5]),
    ],
    ids=["cross", "on-segment", "touch"],
)
def test_near_degenerate_gli_matches_quadrature_of_the_double_integral(gap, c, d):
    # the near-degenerate kinds of the property test above, at gaps quadrature resolves
    a, b = np.array([-1, 0, 0.0]), np.array([1, 0, 0.0])
    c, d = np.array(c, float), np.array(d, float)
    c[2] *= gap
    exact = gauss_integral_quadrature(a, b, c, d)
    assert abs(exact) > 0.1
    assert gli(a, b, c, d) == pytest.approx(exact, abs=1e-12)
    _, raw = unclipped_gli(a, b, c, d)
    assert raw == pytest.approx(exact, abs=1e-12)


def test_degenerate_inputs_have_defined_values():
    a, b, c, d = (np.array(p, float) for p in ([0, 0, 0], [1, 0, 0], [1, 0, 0], [1, 1, 0.3]))
    # Touching (b == c): GLI exactly 0, dGLI defined as 0.
    assert gli(a, b, c, d) == 0.0
    assert dgli(a, b, c, d) == 0.0
    # Shared start point.
    assert dgli(a, b, a, d) == 0.0
    # Zero-length segment: finite; both zero-length: 0.
    assert np.isfinite(dgli(a, a, c, d))
    assert gli(a, a, c, d) == 0.0
    assert dgli(a, a, d, d) == 0.0
    # All four points equal.
    assert dgli(a, a, a, a) == 0.0 and gli(a, a, a, a) == 0.0
    # Crossing interiors (coplanar X).
    assert dgli([-1, 0, 0], [1, 0, 0], [0, -1, 0], [0, 1, 0]) == 0.0


def test_invalid_arguments_raise_value_errors():
    with pytest.raises(ValueError, match="segments must have shape"):
        cloth_coordinates(np.zeros((8, 3)))
    with pytest.raises(ValueError, match="up must be a finite non-zero"):
        cloth_coordinates(np.zeros((8, 2, 3)), up=(0, 0, 0))
    with pytest.raises(ValueError, match="a must have shape"):
        dgli(np.zeros(2), np.zeros(3), np.zeros(3), np.zeros(3))


coord = st.floats(-10.0, 10.0, allow_nan=False, allow_infinity=False)
point = st.tuples(coord, coord, coord).map(np.array)
tiny = st.floats(-1e-9, 1e-9, allow_nan=False).map(abs) | st.sampled_from([0.0, 1e-300, 1e-15])


@st.composite
def near_degenerate_pair(draw):
    a, b, c, d = draw(point), draw(point), draw(point), draw(point)
    kind = draw(st.sampled_from(["touch", "on-segment", "coplanar", "zero-length", "cross"]))
    eps = draw(tiny)
    jitter = np.array([eps, -eps, eps])
    if kind == "touch":
        c = b + jitter
    elif kind == "on-segment":
        s = draw(st.floats(0, 1))
        c = a + s * (b - a) + jitter
    elif kind == "coplanar":
        a[2] = b[2] = c[2] = d[2] = eps
    elif kind == "zero-length":
        b = a + jitter
    else:  # interiors crossing at a tiny height difference
        mid = 0.5 * (a + b)
        c, d = mid - (d - c) / 2 + jitter, mid + (d - c) / 2 + jitter
    return a, b, c, d


def unclipped_gli(a, b, c, d):
    """``gli(a, b, c, d)`` and the value it had before its final clip to [-1/2, 1/2]
    (``gli`` clips, so a check of its result against the bound cannot fail)."""
    real_clip = np.clip
    seen = []

    def spy(x, lo, hi, *args, **kwargs):
        if (lo, hi) == (-0.5, 0.5):
            seen.append(np.array(x, dtype=float, copy=True))
        return real_clip(x, lo, hi, *args, **kwargs)

    with pytest.MonkeyPatch.context() as m:
        m.setattr(np, "clip", spy)
        g = gli(a, b, c, d)
    assert len(seen) == 1, "gli no longer clips with np.clip(..., -0.5, 0.5)"
    return g, seen[0]


def rounding_allowance(a, b, c, d):
    """How far rounding may take the unclipped GLI past 1/2: about 1e-16 L / gap near a
    crossing (L: the segments' lengths, gap: the distance of their lines; unbounded when
    the lines are parallel or meet)."""
    t1, t2 = b - a, d - c
    normal = np.cross(t1, t2)
    size = np.linalg.norm(normal)
    gap = abs(float((c - a) @ normal)) / size if size > 0 else 0.0
    length = np.linalg.norm(t1) + np.linalg.norm(t2)
    return 1e-12 + (np.inf if gap == 0 else 1e-14 * length / gap)


@settings(max_examples=400, deadline=None)
@given(near_degenerate_pair(), st.sampled_from([(0, 0, 1.0), (0.3, -0.2, 0.9)]))
def test_near_degenerate_inputs_never_give_nan_or_inf(pair, up):
    a, b, c, d = pair
    g, raw = unclipped_gli(a, b, c, d)
    dg = dgli(a, b, c, d, up)
    assert np.isfinite(g)
    # where the pair is not set to 0 as touching or coplanar, the clip only takes off
    # rounding: the solid-angle formula itself stays within |GLI| < 1/2
    assert g == 0.0 or abs(raw) <= 0.5 + rounding_allowance(a, b, c, d), (g, raw)
    if a[2] == b[2] == c[2] == d[2]:  # the four points in one plane z = eps, exactly
        assert g == 0.0
    assert np.isfinite(dg)
    coords = cloth_coordinates(np.stack([np.stack([a, b]), np.stack([c, d])]), up)
    assert np.isfinite(coords).all()
