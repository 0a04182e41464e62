"""Attitude quaternion helpers (allsky.vehicle.quaternion) against rotation-group identities.

Truth:
- a direction-cosine matrix is orthonormal with determinant +1;
- a frame turned by +a about z sees the inertial x axis at (cos a, -sin a, 0)
  (right-hand rule; Wertz, *Spacecraft Attitude Determination and Control*,
  app. E);
- with body rates composed on the right (dq/dt = q (x) [0, w] / 2), the
  product p (x) q is "turn by p, then by q about the new body axes", so
  C(p (x) q) = C(q) C(p);
- for rotations uniform over SO(3) (Haar measure) every DCM element has mean 0
  and mean square 1/3 (each row is a uniform unit vector).
"""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from allsky.vehicle.quaternion import (
    body_axis_inertial,
    dcm_body_from_inertial,
    from_axis_angle,
    from_dcm,
    multiply,
    random_unit,
    rotate_to_body,
)

component = st.floats(-1.0, 1.0, allow_nan=False)
quaternions = st.tuples(component, component, component, component).filter(
    lambda c: np.linalg.norm(c) > 0.1).map(lambda c: np.array(c) / np.linalg.norm(c))
vectors = st.tuples(component, component, component).map(np.array)


@settings(max_examples=60, deadline=None)
@given(q=quaternions)
def test_dcm_is_a_proper_rotation(q):
    c = dcm_body_from_inertial(q)
    assert np.allclose(c @ c.T, np.eye(3), rtol=0, atol=1e-14)
    assert np.linalg.det(c) == pytest.approx(1.0, abs=1e-14)
    # q and -q are the same rotation.
    assert np.allclose(dcm_body_from_inertial(-q), c, rtol=0, atol=0)


@settings(max_examples=60, deadline=None)
@given(q=quaternions, v=vectors)
def test_rotate_to_body_is_dcm_times_vector(q, v):
    out = np.empty(3)
    rotate_to_body(q, v, out)
    assert np.allclose(out, dcm_body_from_inertial(q) @ v, rtol=0, atol=1e-15)


@settings(max_examples=50, deadline=None)
@given(q=quaternions)
def test_body_axis_inertial_is_a_dcm_row(q):
    c = dcm_body_from_inertial(q)
    for axis in range(3):
        a = body_axis_inertial(q, axis)
        assert np.array_equal(a, c[axis])
        out = np.empty(3)
        rotate_to_body(q, a, out)  # the body axis, seen from the body, is that axis
        assert np.allclose(out, np.eye(3)[axis], rtol=0, atol=1e-14)


@pytest.mark.parametrize("angle_deg", [0.0, 30.0, 90.0, 179.0, -45.0])
def test_from_axis_angle_about_z_closed_form(angle_deg):
    a = math.radians(angle_deg)
    q = from_axis_angle([0.0, 0.0, 2.0], a)  # the axis need not be unit
    c, s = math.cos(a), math.sin(a)
    expected = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])  # Wertz app. E
    assert np.allclose(dcm_body_from_inertial(q), expected, rtol=0, atol=1e-15)
    assert np.allclose(q, [math.cos(a / 2), 0.0, 0.0, math.sin(a / 2)], rtol=0, atol=1e-16)


@settings(max_examples=100, deadline=None)
@given(v=vectors.filter(lambda v: np.linalg.norm(v) > 0.1), a=st.floats(-math.pi, math.pi))
def test_axis_angle_axis_is_fixed_and_angle_is_the_trace(v, a):
    c = dcm_body_from_inertial(from_axis_angle(v, a))
    u = v / np.linalg.norm(v)
    assert np.allclose(c @ u, u, rtol=0, atol=1e-14)  # Euler's axis is invariant
    assert np.trace(c) == pytest.approx(1.0 + 2.0 * math.cos(a), abs=1e-14)


@settings(max_examples=60, deadline=None)
@given(p=quaternions, q=quaternions)
def test_product_composes_body_rotations(p, q):
    pq = multiply(p, q)
    assert np.linalg.norm(pq) == pytest.approx(1.0, abs=1e-14)
    assert np.allclose(dcm_body_from_inertial(pq),
                       dcm_body_from_inertial(q) @ dcm_body_from_inertial(p), rtol=0, atol=1e-14)


@settings(max_examples=100, deadline=None)
@given(p=quaternions, q=quaternions, r=quaternions)
def test_product_is_associative_with_identity_and_inverse(p, q, r):
    assert np.allclose(multiply(multiply(p, q), r), multiply(p, multiply(q, r)),
                       rtol=0, atol=1e-14)
    one = np.array([1.0, 0.0, 0.0, 0.0])
    assert np.array_equal(multiply(one, p), p) and np.array_equal(multiply(p, one), p)
    conj = p * np.array([1.0, -1.0, -1.0, -1.0])
    assert np.allclose(multiply(p, conj), one, rtol=0, atol=1e-15)


def test_small_body_rate_step_matches_the_kinematics():
    # dq/dt = q (x) [0, w] / 2 (module docstring): a step of w dt about body axes
    # is q (x) from_axis_angle(w, |w| dt) to first order.
    q = from_axis_angle([1.0, 2.0, -0.5], 0.7)
    w = np.array([0.01, -0.02, 0.005])  # [rad/s]
    dt = 1e-4
    stepped = multiply(q, from_axis_angle(w, np.linalg.norm(w) * dt))
    euler = q + 0.5 * dt * multiply(q, np.array([0.0, *w]))
    assert np.allclose(stepped, euler, rtol=0, atol=1e-11)


@settings(max_examples=100, deadline=None)
@given(q=quaternions)
def test_from_dcm_round_trip(q):
    back = from_dcm(dcm_body_from_inertial(q))
    assert back[0] >= 0.0
    sign = 1.0 if q[0] >= 0 else -1.0
    # Shepperd's method is well conditioned everywhere; 1e-12 allows for q[0] ~ 0
    # where the sign choice is the only ambiguity.
    assert np.allclose(back, sign * q, rtol=0, atol=1e-12) or \
        np.allclose(back, -sign * q, rtol=0, atol=1e-12) and abs(q[0]) < 1e-12


@pytest.mark.parametrize("axis", [[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0], [0, 1, -1]])
def test_from_dcm_half_turns_use_every_branch(axis):
    # Trace -1: the scalar part is 0, so Shepperd's method must take the x, y or z branch.
    q = from_axis_angle(axis, math.pi)
    back = from_dcm(dcm_body_from_inertial(q))
    assert np.allclose(dcm_body_from_inertial(back), dcm_body_from_inertial(q), rtol=0, atol=1e-15)
    assert abs(abs(back @ q) - 1.0) < 1e-15


def test_random_unit_is_unit_canonical_and_seeded():
    a = [random_unit(np.random.default_rng(7)) for _ in range(2)]
    assert np.array_equal(a[0], a[1])  # same seed, same attitude
    assert not np.array_equal(a[0], random_unit(np.random.default_rng(8)))
    rng = np.random.default_rng(1)
    for _ in range(100):
        q = random_unit(rng)
        assert abs(np.linalg.norm(q) - 1.0) < 1e-15 and q[0] >= 0.0


def test_random_unit_is_uniform_over_the_rotation_group():
    n = 20_000
    rng = np.random.default_rng(2024)
    c = np.array([dcm_body_from_inertial(random_unit(rng)) for _ in range(n)])
    # Haar measure: E[C_ij] = 0, E[C_ij^2] = 1/3. The standard error of a mean of
    # n samples of variance 1/3 is sqrt(1/(3n)) = 0.0041; allow 5 of them.
    assert np.abs(c.mean(axis=0)).max() < 5 * math.sqrt(1 / (3 * n))
    # Var(C_ij^2) = E[C^4] - 1/9 = 1/5 - 1/9 (a uniform unit vector's component).
    se2 = math.sqrt((1 / 5 - 1 / 9) / n)
    assert np.abs((c ** 2).mean(axis=0) - 1 / 3).max() < 5 * se2
    # Rotation angle density (1 - cos t)/pi on [0, pi] gives E[cos t] = -1/2,
    # i.e. E[trace] = 1 + 2 E[cos t] = 0 (Miles 1965, Biometrika 52, 636).
    assert abs(np.trace(c, axis1=1, axis2=2).mean()) < 5 * math.sqrt(1.0 / n)
