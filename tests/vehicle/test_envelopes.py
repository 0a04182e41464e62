"""Torque and momentum envelopes (allsky.vehicle.envelopes) against brute force and closed forms.

Truth:
- brute force: the envelope is the convex hull of the 2^n corners
  ``sum_i c_i L_i g_i``, ``c_i = +-1`` (Reynolds & Markley, *Maximum torque
  and momentum envelopes for reaction wheel arrays*, NASA GSFC); Qhull
  (``scipy.spatial.ConvexHull``) gives its facet planes independently;
- closed forms for the four-wheel pyramid and the jet box, derived in the
  docstrings below;
- the dither example of the first source document: inertia 16000 kg m^2,
  amplitude 100 microrad, period 51.2 s, peak feed-forward torque
  ``J A w^2`` (SPEC sec. 5-6);
- the default jets: thrust F = [0.25, 0.5, 0.5] N, arm r = [0.5, 1.25, 1.25] m
  (src/allsky/scenarios/default.toml), couple torque 2 F r.
"""

import itertools
import json

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from scipy.spatial import ConvexHull

from allsky.hardware.jets import make_params as jet_params
from allsky.sequencer.dither import feedforward_torque_n_m
from allsky.vehicle.envelopes import (
    BODY_AXES,
    ProfileCheck,
    check_profile,
    envelope_summary,
    jet_envelope,
    make_envelope,
    pyramid_axes,
    single_failures,
    worst_failure,
)

ISOTROPIC_BETA_DEG = float(np.degrees(np.arctan(np.sqrt(2.0))))  # cos^2 beta = 1/3
BETAS_DEG = [20.0, 45.0, ISOTROPIC_BETA_DEG, 60.0, 75.0]
JET_THRUST_N = [0.25, 0.5, 0.5]  # default.toml [jets]
JET_ARM_M = [0.5, 1.25, 1.25]
JET_ISP_S = 65.0


# ---------------------------------------------------------------------------
# Brute force: the hull of the 2^n corners
# ---------------------------------------------------------------------------

def corners(axes, limits):
    """All 2^n points sum_i c_i L_i g_i with c_i = +-1."""
    signs = np.array(list(itertools.product((-1.0, 1.0), repeat=len(limits))))
    return signs @ (np.asarray(limits)[:, None] * np.asarray(axes))


def hull_planes(axes, limits):
    """Distinct (unit normal, offset) planes of the corners' hull, from Qhull."""
    hull = ConvexHull(corners(axes, limits))
    normals, offsets = [], []
    for eq in hull.equations:  # n . x + d <= 0 inside, |n| = 1
        if not any(np.dot(eq[:3], m) > 1.0 - 1e-9 for m in normals):
            normals.append(eq[:3])
            offsets.append(-eq[3])
    return np.array(normals), np.array(offsets)


def hull_max_along(normals, offsets, u):
    u = np.asarray(u, dtype=float) / np.linalg.norm(u)
    cos = normals @ u
    return np.min(offsets[cos > 1e-12] / cos[cos > 1e-12])


def random_array(seed, n):
    rng = np.random.default_rng(seed)
    g = rng.normal(size=(n, 3))
    return g / np.linalg.norm(g, axis=1)[:, None], rng.uniform(0.2, 3.0, n)


def special_arrays():
    """Arrays with coplanar triples, parallel and antiparallel axes."""
    s2 = np.sqrt(0.5)
    x, y, z = np.eye(3)
    return {
        "pyramid-60": (pyramid_axes(60.0), np.array([0.1, 0.2, 0.3, 0.4])),
        "coplanar-triple": (np.array([x, y, [s2, s2, 0.0], z]), np.array([1.0, 2.0, 0.5, 1.5])),
        "parallel-pair": (np.array([x, x, y, z, [0.0, s2, s2]]), np.array([1.0, 2.0, 1.0, 1.0, 0.7])),
        "antiparallel": (np.array([x, -x, y, z]), np.array([1.0, 0.5, 2.0, 1.0])),
        "six-wheel": (np.array([[np.cos(a) * np.sin(b), np.sin(a) * np.sin(b), np.cos(b)]
                                for a, b in zip(np.radians(np.arange(0, 360, 60)),
                                                np.radians([30, 60] * 3))]),
                      np.ones(6)),
    }


ARRAYS = {f"random-{n}-{seed}": random_array(seed, n)
          for n in range(3, 9) for seed in range(3)} | special_arrays()


@pytest.mark.parametrize("name", sorted(ARRAYS))
def test_facets_are_the_hull_planes(name):
    axes, limits = ARRAYS[name]
    env = make_envelope(axes, limits)
    normals, offsets = hull_planes(axes, limits)
    assert len(env.normals) == len(normals)
    for n, h in zip(env.normals, env.offsets):
        match = np.flatnonzero(normals @ n > 1.0 - 1e-9)
        assert len(match) == 1, n
        assert offsets[match[0]] == pytest.approx(h, rel=0, abs=1e-9)
    # Every facet is spanned by two non-parallel axes perpendicular to it.
    for n, spanned in zip(env.normals, env.facet_axes):
        assert np.linalg.matrix_rank(env.axes[list(spanned)], tol=1e-9) == 2
        assert np.all(np.abs(env.axes[list(spanned)] @ n) <= 1e-9)


@pytest.mark.parametrize("name", sorted(ARRAYS))
def test_support_and_reach_match_brute_force(name):
    axes, limits = ARRAYS[name]
    env = make_envelope(axes, limits)
    pts = corners(axes, limits)
    normals, offsets = hull_planes(axes, limits)
    rng = np.random.default_rng(99)
    dirs = rng.normal(size=(200, 3))
    assert np.allclose(env.support(dirs), np.max(dirs @ pts.T, axis=1), rtol=0, atol=1e-9)
    reach = env.max_along(dirs)
    truth = [hull_max_along(normals, offsets, u) for u in dirs]
    assert np.allclose(reach, truth, rtol=0, atol=1e-9)
    assert np.allclose(env.max_along_body_axes(),
                       [hull_max_along(normals, offsets, e) for e in BODY_AXES], rtol=0, atol=1e-9)
    assert env.min_radius == pytest.approx(np.min(offsets), abs=1e-9)


def test_parallel_axes_add_up_to_one_generator():
    """Wheels on one line act as one wheel with the summed limit (|c_1 L_1 + c_2 L_2| <= L_1 + L_2)."""
    x, y, z = np.eye(3)
    box = make_envelope(BODY_AXES, [3.0, 1.0, 2.0])
    for axes, limits in [([x, x, y, z], [1.0, 2.0, 1.0, 2.0]),
                         ([x, -x, y, z], [2.5, 0.5, 1.0, 2.0]),
                         ([y, x, z, -x], [1.0, 1.0, 2.0, 2.0])]:
        env = make_envelope(np.array(axes), limits)
        assert len(env.normals) == 6
        assert np.allclose(env.max_along_body_axes(), [3.0, 1.0, 2.0], rtol=1e-15)
        assert env.min_radius == 1.0
        dirs = np.random.default_rng(1).normal(size=(50, 3))
        assert np.allclose(env.max_along(dirs), box.max_along(dirs), rtol=1e-14)


# ---------------------------------------------------------------------------
# Closed forms: the four-wheel pyramid
# ---------------------------------------------------------------------------

@pytest.mark.parametrize("beta_deg", BETAS_DEG)
def test_pyramid_closed_forms(beta_deg):
    """Four equal wheels (limit tau) in a pyramid about +x, inclined at beta.

    Axes (``pyramid_axes``), c = cos beta, s = sin beta:
    g0 = (c, s, 0), g1 = (c, 0, s), g2 = (c, -s, 0), g3 = (c, 0, -s).

    Lemma: if a corner combination p = tau sum c_i g_i (|c_i| <= 1) is
    parallel to a unit u and u . p = h(u), then |p| is the largest reach
    along u: any t u in the envelope has t = u . (t u) <= h(u) = |p|.

    * Along the pyramid axis x: h(x) = tau sum |g_i . x| = 4 tau c, and
      c_i = +1 for all gives p = tau (4c, 0, 0). Reach 4 tau cos(beta).
    * Along y (between wheels 0 and 2, opposite): h(y) = tau (s + 0 + s + 0)
      = 2 tau s, and c = (+1, 0, -1, 0) gives p = tau (0, 2s, 0) (wheels 1, 3
      are perpendicular to y and idle). Reach 2 tau sin(beta) exactly; z
      likewise with wheels 1 and 3.
    * Along (0, 1, 1)/sqrt2 (between adjacent wheels 0 and 1):
      h = tau s (1 + 1 + 1 + 1)/sqrt2 = 2 sqrt2 tau s, and c = (+1, +1, -1, -1)
      gives p = tau (0, 2s, 2s). Reach 2 sqrt2 tau sin(beta).
    * Facets: opposite pairs (0, 2) and (1, 3) give normals +-z and +-y with
      offset h = 2 tau s. Adjacent pairs, e.g. g0 x g1 = (s^2, -cs, -cs), unit
      n = (s, -c, -c)/N with N = sqrt(s^2 + 2c^2): n . g0 = n . g1 = 0 and
      n . g2 = n . g3 = 2sc/N, offset 4 tau s c / N; four adjacent pairs.
      2 + 2 + 8 = 12 facets = 2 C(4, 2) (no three axes coplanar).
    * Inscribed radius: min(2 tau s, 4 tau s c / N); the two are equal when
      4c^2 = s^2 + 2c^2, i.e. tan^2 beta = 2 (beta = 54.74 deg, cos^2 = 1/3);
      below that 2 tau s is smaller, above it 4 tau s c / N.
    """
    tau = 0.2  # [N m]
    b = np.radians(beta_deg)
    c, s = np.cos(b), np.sin(b)
    big_n = np.sqrt(s**2 + 2 * c**2)
    env = make_envelope(pyramid_axes(beta_deg), tau)
    assert len(env.normals) == 12
    assert np.allclose(env.max_along_body_axes(), [4 * tau * c, 2 * tau * s, 2 * tau * s],
                       rtol=1e-14, atol=0)
    assert env.max_along([0.0, 1.0, 1.0]) == pytest.approx(2 * np.sqrt(2) * tau * s, rel=1e-14)
    assert env.max_along([0.0, -1.0, 1.0]) == pytest.approx(2 * np.sqrt(2) * tau * s, rel=1e-14)
    assert sorted(env.offsets) == pytest.approx(
        sorted([2 * tau * s] * 4 + [4 * tau * s * c / big_n] * 8), rel=1e-14)
    assert env.min_radius == pytest.approx(min(2 * tau * s, 4 * tau * s * c / big_n), rel=1e-14)


def test_pyramid_isotropic_angle_equalises_the_facets():
    """At tan^2 beta = 2 all 12 facets are at 2 tau sin beta = 2 tau sqrt(2/3) (rhombic dodecahedron)."""
    env = make_envelope(pyramid_axes(ISOTROPIC_BETA_DEG), 1.0)
    assert np.allclose(env.offsets, 2 * np.sqrt(2 / 3), rtol=1e-14)


@pytest.mark.parametrize("beta_deg", BETAS_DEG)
def test_pyramid_one_wheel_failed(beta_deg):
    """The pyramid with one wheel failed (c = cos beta, s = sin beta, N = sqrt(s^2 + 2c^2)).

    Wheel 3, g3 = (c, 0, -s), failed; g0, g1, g2 remain (independent: a
    parallelepiped, 6 facets):
    * pair (0, 2) -> normal +-z, offset h(z) = tau (0 + s + 0) = tau s;
    * pair (0, 1) -> n = (s, -c, -c)/N, n . g2 = 2sc/N, offset 2 tau s c / N;
    * pair (1, 2) -> g1 x g2 = (s^2, sc, -cs), n = (s, c, -c)/N,
      n . g0 = 2sc/N, offset 2 tau s c / N.
    Every offset is half the full array's, so the inscribed radius halves:
    min(tau s, 2 tau s c / N).
    Reach, by the lemma of :func:`test_pyramid_closed_forms`:
    * x: c = (1, 0, 1) gives tau (2c, 0, 0); the facet n = (s, c, -c)/N has
      n . x = s/N and offset 2 tau s c/N, ratio 2 tau c, so reach 2 tau cos beta;
    * y: c = (1, 0, -1) gives tau (0, 2s, 0) and h(y) = 2 tau s: reach
      2 tau sin beta (both y wheels still there);
    * z: c = (-1/2, 1, -1/2) gives tau (0, 0, s) and h(z) = tau s: reach
      tau sin beta (wheel 1 alone has a z component).
    By symmetry wheel 1 failed gives the same, and wheels 0 or 2 failed swap
    y and z.
    """
    tau = 0.2
    b = np.radians(beta_deg)
    c, s = np.cos(b), np.sin(b)
    big_n = np.sqrt(s**2 + 2 * c**2)
    env = make_envelope(pyramid_axes(beta_deg), tau)
    failed = single_failures(env)
    assert len(failed) == 4
    for k, f in enumerate(failed):
        assert len(f.normals) == 6
        assert f.min_radius == pytest.approx(min(tau * s, 2 * tau * s * c / big_n), rel=1e-14)
        assert f.min_radius == pytest.approx(env.min_radius / 2, rel=1e-14)
        y_lost = k in (0, 2)
        expected = [2 * tau * c, tau * s if y_lost else 2 * tau * s, 2 * tau * s if y_lost
                    else tau * s]
        assert np.allclose(f.max_along_body_axes(), expected, rtol=1e-14, atol=0)
    # All four are equally bad; the tie goes to the lowest index.
    assert worst_failure(env, make_envelope(pyramid_axes(beta_deg), 3.0)) == 0


def test_worst_failure_ranks_by_torque_then_momentum_then_index():
    """Wheels on x, y, z and one on (1, 1, 0)/sqrt2: losing z leaves all axes in the x-y plane.

    That failure leaves no torque along z (radius 0), any other leaves a solid
    envelope, so it is the worst whatever the limits. For the equal pyramid
    every failure halves the torque radius (a tie); unequal momentum limits
    [1, 2, 3, 4] N m s then rank them, and wheels 1 and 3 tie again (both
    leave 0.7746 N m s), so the lower index is reported.
    """
    s2 = np.sqrt(0.5)
    axes = np.array([[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0], [s2, s2, 0]])
    torque = make_envelope(axes, [0.1, 0.2, 0.3, 0.4])
    radii = [f.min_radius for f in single_failures(torque)]
    assert radii[2] == 0.0 and min(radii[:2] + radii[3:]) > 0.0
    assert worst_failure(torque, make_envelope(axes, 1.0)) == 2
    pyramid = pyramid_axes(60.0)
    momentum = make_envelope(pyramid, [1.0, 2.0, 3.0, 4.0])
    m_radii = [f.min_radius for f in single_failures(momentum)]
    assert m_radii[1] == pytest.approx(m_radii[3], rel=1e-14) and m_radii[1] < min(m_radii[0],
                                                                                    m_radii[2])
    assert worst_failure(make_envelope(pyramid, 0.1), momentum) == 1


# ---------------------------------------------------------------------------
# Jets: one couple per body axis -> a box
# ---------------------------------------------------------------------------

def test_jet_box_from_the_default_couples():
    """Couples 2 F r = [0.25, 1.25, 1.25] N m along x, y, z: the box |T_i| <= 2 F_i r_i.

    Its facets are the six faces (offsets the couple torques), the inscribed
    radius is the smallest couple, the reach along each axis is its couple,
    and along (1, 1, 1)/sqrt3 the ray leaves through the smallest face:
    0.25 sqrt3 N m.
    """
    couple_n_m = jet_params(JET_THRUST_N, JET_ARM_M, JET_ISP_S).torque_n_m
    env = jet_envelope(couple_n_m)
    assert len(env.normals) == 6
    assert sorted(env.offsets) == pytest.approx([0.25, 0.25, 1.25, 1.25, 1.25, 1.25], rel=1e-15)
    assert env.min_radius == pytest.approx(0.25, rel=1e-15)
    assert np.allclose(env.max_along_body_axes(), [0.25, 1.25, 1.25], rtol=1e-15, atol=0)
    assert env.max_along([1.0, 1.0, 1.0]) == pytest.approx(0.25 * np.sqrt(3), rel=1e-15)
    # The eight combinations with every couple firing are the box's corners.
    box = corners(BODY_AXES, couple_n_m)
    assert np.allclose(np.max(np.abs(box), axis=0), couple_n_m)
    with pytest.raises(ValueError, match="couple_torque_n_m"):
        jet_envelope([0.25, 1.25])


# ---------------------------------------------------------------------------
# Summary: the JSON layout users rely on
# ---------------------------------------------------------------------------

def test_summary_layout_and_values():
    beta_deg, tau, h = 60.0, 0.1, 4.0
    c, s = np.cos(np.radians(beta_deg)), np.sin(np.radians(beta_deg))
    couples = [0.25, 1.25, 1.25]
    out = envelope_summary(pyramid_axes(beta_deg), tau, [h] * 4, couples)
    assert json.loads(json.dumps(out)) == out  # plain JSON types only
    reach = {"min_radius_n_m", "max_n_m"}
    reach_s = {"min_radius_n_m_s", "max_n_m_s"}
    assert set(out) == {"wheels", "jets"}
    assert set(out["wheels"]) == {"torque", "momentum", "one_failed"}
    assert set(out["wheels"]["torque"]) == reach
    assert set(out["wheels"]["momentum"]) == reach_s
    assert set(out["wheels"]["one_failed"]) == {"wheel", "torque", "momentum"}
    assert set(out["wheels"]["one_failed"]["torque"]) == reach
    assert set(out["wheels"]["one_failed"]["momentum"]) == reach_s
    assert set(out["jets"]) == {"torque"} and set(out["jets"]["torque"]) == reach
    assert isinstance(out["wheels"]["one_failed"]["wheel"], int)

    big_n = np.sqrt(s**2 + 2 * c**2)
    w = out["wheels"]
    assert w["torque"]["max_n_m"] == pytest.approx([4 * tau * c, 2 * tau * s, 2 * tau * s],
                                                   rel=1e-14)
    assert w["torque"]["min_radius_n_m"] == pytest.approx(4 * tau * s * c / big_n, rel=1e-14)
    assert w["momentum"]["max_n_m_s"] == pytest.approx([4 * h * c, 2 * h * s, 2 * h * s],
                                                       rel=1e-14)
    assert w["one_failed"]["wheel"] == 0
    assert w["one_failed"]["torque"]["max_n_m"] == pytest.approx(
        [2 * tau * c, tau * s, 2 * tau * s], rel=1e-14)
    assert w["one_failed"]["momentum"]["min_radius_n_m_s"] == pytest.approx(
        2 * h * s * c / big_n, rel=1e-14)
    assert out["jets"]["torque"] == {"min_radius_n_m": 0.25, "max_n_m": couples}


def test_summary_refuses_a_flat_array():
    x, y = np.eye(3)[:2]
    with pytest.raises(ValueError, match="one plane"):
        envelope_summary([x, y, [np.sqrt(0.5), np.sqrt(0.5), 0.0]], 0.1, 1.0, [1.0, 1.0, 1.0])


def test_three_orthogonal_wheels_one_failed_is_flat():
    """Three wheels on x, y, z: any failure leaves a rectangle and nothing across it.

    All three failures tie at radius 0, so wheel 0 (x) is reported: the
    rectangle |T_y| <= 0.2, |T_z| <= 0.3 N m in the y-z plane.
    """
    out = envelope_summary(BODY_AXES, [0.1, 0.2, 0.3], 1.0, [1.0, 1.0, 1.0])
    failed = out["wheels"]["one_failed"]
    assert failed["wheel"] == 0
    assert failed["torque"] == {"min_radius_n_m": 0.0, "max_n_m": [0.0, 0.2, 0.3]}
    flat = make_envelope(BODY_AXES[:2], [0.1, 0.2])
    assert flat.rank == 2 and flat.min_radius == 0.0
    assert np.array_equal(flat.max_along_body_axes(), [0.1, 0.2, 0.0])
    # In the plane it is the rectangle: the ray along (1, 1) leaves through x = 0.1.
    assert flat.max_along([1.0, 1.0, 0.0]) == pytest.approx(0.1 * np.sqrt(2), rel=1e-15)
    assert flat.max_along([1.0, 1.0, 1e-3]) == 0.0


def test_flat_envelope_matches_the_planar_hull():
    rng = np.random.default_rng(5)
    p = np.array([1.0, 2.0, 2.0]) / 3.0
    basis = np.linalg.svd(p[None, :])[2][1:]  # two unit vectors spanning the plane
    ang = rng.uniform(0, 2 * np.pi, 5)
    axes = np.column_stack([np.cos(ang), np.sin(ang)]) @ basis
    limits = rng.uniform(0.5, 2.0, 5)
    env = make_envelope(axes, limits)
    assert env.rank == 2 and env.min_radius == 0.0
    hull = ConvexHull(corners(axes, limits) @ basis.T)
    normals = hull.equations[:, :2]
    offsets = -hull.equations[:, 2]
    for a in rng.uniform(0, 2 * np.pi, 50):
        u2 = np.array([np.cos(a), np.sin(a)])
        cos = normals @ u2
        truth = np.min(offsets[cos > 1e-12] / cos[cos > 1e-12])
        assert env.max_along(u2 @ basis) == pytest.approx(truth, abs=1e-12)


# ---------------------------------------------------------------------------
# Bad input
# ---------------------------------------------------------------------------

def test_parallel_only_axes_are_refused():
    x = np.array([1.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="parallel"):
        make_envelope([x, -x, x], 1.0)
    with pytest.raises(ValueError, match="parallel"):
        make_envelope([x], 1.0)


@pytest.mark.parametrize("axes, limit, match", [
    ([[1.0, 0, 0], [0, 1.0, 0], [0, 0, 2.0]], 1.0, "unit"),
    ([[1.0, 0, 0], [0, 1.0, 0], [0, 0, 0]], 1.0, "unit"),
    ([[1.0, 0, 0], [0, 1.0, 0], [0, 0, np.nan]], 1.0, "finite"),
    ([1.0, 0.0, 0.0], 1.0, r"\(n, 3\)"),
    (np.eye(3), [1.0, 2.0], "one per actuator"),
    (np.eye(3), [1.0, 0.0, 1.0], "> 0"),
    (np.eye(3), -1.0, "> 0"),
    (np.eye(3), np.inf, "finite"),
])
def test_bad_arrays_are_refused(axes, limit, match):
    with pytest.raises(ValueError, match=match):
        make_envelope(axes, limit)


@pytest.mark.parametrize("beta_deg", [0.0, 90.0, -10.0, 120.0, np.nan])
def test_pyramid_angle_out_of_range(beta_deg):
    with pytest.raises(ValueError, match="beta_deg"):
        pyramid_axes(beta_deg)


def test_bad_directions_and_failures():
    env = make_envelope(np.eye(3), 1.0)
    with pytest.raises(ValueError, match="non-zero"):
        env.max_along([0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="3 components"):
        env.max_along([1.0, 0.0])
    with pytest.raises(IndexError):
        env.without(3)
    with pytest.raises(ValueError, match="different arrays"):
        worst_failure(env, make_envelope(pyramid_axes(45.0), 1.0))


@given(st.lists(st.floats(-10.0, 0.0), min_size=4, max_size=4))
def test_non_positive_limits_are_refused(limits):
    with pytest.raises(ValueError, match="> 0"):
        make_envelope(pyramid_axes(50.0), limits)


# ---------------------------------------------------------------------------
# Invariants
# ---------------------------------------------------------------------------

unit_vector = st.tuples(*[st.floats(-1.0, 1.0)] * 3).map(np.array).filter(
    lambda v: np.linalg.norm(v) > 0.1).map(lambda v: v / np.linalg.norm(v))
direction = st.tuples(*[st.floats(-1e3, 1e3)] * 3).map(np.array).filter(
    lambda v: np.linalg.norm(v) > 1e-3)


@st.composite
def arrays(draw):
    n = draw(st.integers(3, 6))
    axes = np.array([draw(unit_vector) for _ in range(n)])
    assume(np.linalg.svd(axes, compute_uv=False)[2] > 1e-3)  # well spread: rank 3
    limits = np.array(draw(st.lists(st.floats(0.1, 10.0), min_size=n, max_size=n)))
    return make_envelope(axes, limits)


@settings(max_examples=200, deadline=None)
@given(arrays(), direction, direction, st.floats(0.0, 100.0))
def test_support_is_convex_and_positively_homogeneous(env, a, b, lam):
    scale = np.sum(env.limits) * (np.linalg.norm(a) + np.linalg.norm(b))
    assert env.support(lam * a) == pytest.approx(lam * env.support(a), rel=1e-12, abs=1e-300)
    assert env.support(a + b) <= env.support(a) + env.support(b) + 1e-12 * scale
    assert np.allclose(env.support(env.normals), env.offsets, rtol=1e-12)


@settings(max_examples=200, deadline=None)
@given(arrays(), direction)
def test_reach_lands_on_the_boundary(env, u):
    point, k = env.boundary_point(u)
    tol = 1e-10 * np.sum(env.limits)
    # On its facet's plane: support along the facet normal equals the offset.
    assert env.normals[k] @ point == pytest.approx(env.offsets[k], abs=tol)
    assert env.support(env.normals[k]) == pytest.approx(env.offsets[k], rel=1e-12)
    # And inside every other facet's half-space.
    assert np.all(env.normals @ point <= env.offsets + tol)
    t = env.max_along(u)
    assert np.allclose(point, t * u / np.linalg.norm(u), rtol=0, atol=tol)
    # Symmetric about the origin, between the inscribed sphere and h(u).
    assert env.max_along(-u) == pytest.approx(t, rel=1e-12)
    assert env.min_radius - tol <= t <= env.support(u / np.linalg.norm(u)) + tol


# ---------------------------------------------------------------------------
# Profiles: the dither feed-forward torque
# ---------------------------------------------------------------------------

DITHER_INERTIA_KG_M2 = 16000.0  # SPEC sec. 6: the dither document's example
DITHER_AMPLITUDE_RAD = 100e-6
DITHER_PERIOD_S = 51.2
DITHER_SAMPLE_S = 0.1


def dither_torque(amplitude_rad, period_s):
    """Feed-forward torque J a(t) [N m] at 0.1 s over one 51.2 s period, body axes."""
    omega = np.array([2 * np.pi / p if p else 0.0 for p in period_s])
    t_s = np.arange(512) * DITHER_SAMPLE_S
    j = DITHER_INERTIA_KG_M2 * np.eye(3)
    return np.array([feedforward_torque_n_m(j, amplitude_rad, omega, t) for t in t_s])


def test_dither_feedforward_peak_is_j_a_w2():
    profile = dither_torque([DITHER_AMPLITUDE_RAD, 0.0, 0.0], [DITHER_PERIOD_S, 0.0, 0.0])
    peak = DITHER_INERTIA_KG_M2 * DITHER_AMPLITUDE_RAD * (2 * np.pi / DITHER_PERIOD_S) ** 2
    assert peak == pytest.approx(0.0240957, rel=1e-6)  # 1.6 kg m^2 rad x (0.12272 rad/s)^2
    # 51.2 s = 512 samples: the quarter periods (samples 128, 384) are the peaks.
    assert np.max(np.abs(profile[:, 0])) == pytest.approx(peak, rel=1e-15)


@pytest.mark.parametrize("beta_deg", BETAS_DEG)
def test_roll_dither_inside_the_pyramid(beta_deg):
    """Roll dither along the pyramid axis: margin = 4 tau cos(beta) / (J A w^2)."""
    profile = dither_torque([DITHER_AMPLITUDE_RAD, 0.0, 0.0], [DITHER_PERIOD_S, 0.0, 0.0])
    peak = DITHER_INERTIA_KG_M2 * DITHER_AMPLITUDE_RAD * (2 * np.pi / DITHER_PERIOD_S) ** 2
    cos_b = np.cos(np.radians(beta_deg))
    tau = 0.05  # [N m] per wheel
    check = check_profile(make_envelope(pyramid_axes(beta_deg), tau), profile)
    assert isinstance(check, ProfileCheck)
    assert check.inside
    assert check.margin == pytest.approx(4 * tau * cos_b / peak, rel=1e-12)
    assert check.worst_sample in (128, 384)
    # The wheel torque that just meets the peak, and 1e-9 either side of it.
    tau_min = peak / (4 * cos_b)
    assert check_profile(make_envelope(pyramid_axes(beta_deg), tau_min * (1 + 1e-9)),
                         profile).inside
    below = check_profile(make_envelope(pyramid_axes(beta_deg), tau_min * (1 - 1e-9)), profile)
    assert not below.inside and below.margin == pytest.approx(1 - 1e-9, rel=1e-12)


def test_roll_and_yaw_dither_margin_matches_brute_force():
    """Roll 51.2 s and yaw 25.6 s together (the default plan): margin from the corners' hull."""
    profile = dither_torque([DITHER_AMPLITUDE_RAD, 0.0, DITHER_AMPLITUDE_RAD],
                            [DITHER_PERIOD_S, 0.0, DITHER_PERIOD_S / 2])
    axes, limits = pyramid_axes(60.0), np.full(4, 0.02)
    check = check_profile(make_envelope(axes, limits), profile)
    normals, offsets = hull_planes(axes, limits)
    live = np.linalg.norm(profile, axis=1) > 0
    ratios = [hull_max_along(normals, offsets, v) / np.linalg.norm(v) for v in profile[live]]
    assert check.margin == pytest.approx(min(ratios), rel=1e-12)
    assert check.inside == (min(ratios) >= 1.0)


def test_profile_edge_cases():
    env = jet_envelope([0.25, 1.25, 1.25])
    assert check_profile(env, np.zeros((4, 3))) == ProfileCheck(True, float("inf"), -1)
    one = check_profile(env, [0.0, 0.0, 2.5])
    assert one == ProfileCheck(False, 0.5, 0)
    with pytest.raises(ValueError, match="shape"):
        check_profile(env, np.zeros((4, 2)))
    with pytest.raises(ValueError, match="finite"):
        check_profile(env, [[np.nan, 0.0, 0.0]])
