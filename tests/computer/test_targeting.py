"""Programmed target angles, register 24 (allsky.computer.targeting), against spherical geometry.

Truth:
- the reference attitude left by Modes 1-5 has +x on the Sun and the reference
  star in the body x-z plane on the +z side (SPEC sections 1 and 4);
- a roll phi about +x then a yaw psi about the rolled +z carries +x to
  cos(psi) x + sin(psi)(cos(phi) y + sin(phi) z) (module docstring); the
  same manoeuvre composed with quaternions (body rotations on the right,
  allsky.vehicle.quaternion) must land +x on the target;
- |psi| is the Sun-target angle, and of the two (phi, psi) solutions the one
  with |phi| <= 90 deg is programmed.
"""

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from allsky.computer.targeting import (
    attitude_after,
    pointing_direction,
    programmed_angles_deg,
    reference_frame,
    turn_between_deg,
)
from allsky.vehicle import quaternion

component = st.floats(-1.0, 1.0, allow_nan=False)
directions = st.tuples(component, component, component).filter(
    lambda v: np.linalg.norm(v) > 0.1).map(lambda v: np.array(v) / np.linalg.norm(v))

# A late-November geometry (SPEC section 1: Sun-Canopus about 100 deg), equatorial.
SUN = np.array([-0.55, -0.76, -0.33])
CANOPUS = np.array([-0.063, 0.603, -0.795])


def unit(v):
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


def manoeuvre_lands_on(sun, star, roll_deg, yaw_deg):
    """Inertial direction of +x after the roll-then-yaw manoeuvre, by quaternions."""
    q_ref = quaternion.from_dcm(reference_frame(sun, star))
    q = quaternion.multiply(q_ref, quaternion.from_axis_angle([1, 0, 0], math.radians(roll_deg)))
    q = quaternion.multiply(q, quaternion.from_axis_angle([0, 0, 1], math.radians(yaw_deg)))
    return quaternion.body_axis_inertial(q, 0)


def not_on_the_sun_line(sun, star):
    return np.linalg.norm(np.cross(sun, star)) > 1e-3


@settings(max_examples=60, deadline=None)
@given(sun=directions, star=directions)
def test_reference_frame_is_orthonormal_sun_on_x_star_in_x_z_plane(sun, star):
    assume(not_on_the_sun_line(sun, star))
    r = reference_frame(3.0 * sun, 0.5 * star)  # lengths do not matter
    # One Gram-Schmidt step: rounding grows as eps / sin(Sun-star angle).
    tol = 2e-15 / np.linalg.norm(np.cross(sun, star))
    assert np.allclose(r @ r.T, np.eye(3), rtol=0, atol=tol)
    assert np.linalg.det(r) == pytest.approx(1.0, abs=1e-14)
    assert np.allclose(r[0], sun, rtol=0, atol=1e-15)
    star_ref = r @ star
    assert abs(star_ref[1]) < 1e-14  # in the x-z plane ...
    assert star_ref[2] > 0.0  # ... on the +z side


def test_reference_frame_rejects_a_star_on_the_sun_line():
    with pytest.raises(ValueError):
        reference_frame(SUN, -2.0 * SUN)


@settings(max_examples=80, deadline=None)
@given(sun=directions, star=directions, target=directions)
def test_programmed_angles_point_x_at_the_target(sun, star, target):
    assume(not_on_the_sun_line(sun, star))
    roll, yaw = programmed_angles_deg(sun, star, target)
    assert -90.0 <= roll <= 90.0
    assert -180.0 <= yaw <= 180.0
    t_ref = reference_frame(sun, star) @ target
    assert np.allclose(pointing_direction(roll, yaw), t_ref, rtol=0, atol=1e-12)
    assert np.allclose(manoeuvre_lands_on(sun, star, roll, yaw), target, rtol=0, atol=1e-12)
    # The yaw is the Sun-target angle.
    sun_target_deg = math.degrees(math.atan2(np.linalg.norm(np.cross(sun, target)), sun @ target))
    assert abs(yaw) == pytest.approx(sun_target_deg, abs=1e-9)


@pytest.mark.parametrize("t_ref, roll, yaw", [
    ([0, 1, 0], 0.0, 90.0),     # reference +y: a pure yaw
    ([0, -1, 0], 0.0, -90.0),   # -y: yaw the other way rather than roll 180
    ([0, 0, 1], 90.0, 90.0),    # toward the star side: roll a quarter turn, then yaw
    ([0, 0, -1], -90.0, 90.0),  # roll exactly -90 keeps |roll| <= 90
])
def test_targets_on_the_reference_axes(t_ref, roll, yaw):
    r = reference_frame(SUN, CANOPUS)
    target = r.T @ np.array(t_ref, dtype=float)
    got = programmed_angles_deg(SUN, CANOPUS, target)
    assert got == pytest.approx((roll, yaw), abs=1e-12)
    assert np.allclose(manoeuvre_lands_on(SUN, CANOPUS, *got), target, rtol=0, atol=1e-14)


def test_the_sun_itself_needs_no_yaw():
    # On the Sun line the roll is immaterial (any roll leaves +x on the Sun).
    roll, yaw = programmed_angles_deg(SUN, CANOPUS, SUN)
    assert abs(roll) <= 90.0 and yaw == pytest.approx(0.0, abs=1e-9)
    assert np.allclose(manoeuvre_lands_on(SUN, CANOPUS, roll, yaw), unit(SUN), rtol=0, atol=1e-14)


@pytest.mark.parametrize("off_rad", [1e-3, 1e-7, 1e-12])
def test_targets_near_the_sun_line(off_rad):
    r = reference_frame(SUN, CANOPUS)
    # Slightly off the Sun toward reference -y -z: roll -45 deg, yaw off_rad (tiny).
    t_ref = unit([1.0, -off_rad / math.sqrt(2), -off_rad / math.sqrt(2)])
    roll, yaw = programmed_angles_deg(SUN, CANOPUS, r.T @ t_ref)
    assert abs(roll) <= 90.0
    assert abs(yaw) == pytest.approx(math.degrees(off_rad), rel=1e-6)
    assert np.allclose(pointing_direction(roll, yaw), t_ref, rtol=0, atol=1e-15)


def test_anti_sun_target():
    roll, yaw = programmed_angles_deg(SUN, CANOPUS, -SUN)
    assert abs(roll) <= 90.0 and abs(yaw) == pytest.approx(180.0, abs=1e-9)
    assert np.allclose(manoeuvre_lands_on(SUN, CANOPUS, roll, yaw), unit(-SUN), rtol=0, atol=1e-12)


def test_the_star_itself_is_a_pure_yaw_toward_plus_z():
    # Canopus lies in the x-z plane on +z: roll +90 deg (the rolled +y is then the
    # reference +z), then yaw by the Sun-Canopus angle.
    roll, yaw = programmed_angles_deg(SUN, CANOPUS, CANOPUS)
    sun_canopus_deg = math.degrees(math.acos(unit(SUN) @ unit(CANOPUS)))
    assert roll == pytest.approx(90.0, abs=1e-9)
    assert yaw == pytest.approx(sun_canopus_deg, abs=1e-9)
    assert 90.0 < sun_canopus_deg < 110.0  # the geometry SPEC section 1 describes


@settings(max_examples=200, deadline=None)
@given(sun=directions, star=directions, first=directions, second=directions)
def test_the_turn_between_two_targets_lands_on_the_second(sun, star, first, second):
    """Fly the first target's programmed roll and yaw from the reference attitude, then the
    turn between the targets from there, by quaternions: +x lands on the second target."""
    assume(np.linalg.norm(np.cross(sun, star)) > 0.1)
    r1, y1 = programmed_angles_deg(sun, star, first)
    r2, y2 = programmed_angles_deg(sun, star, second)
    roll, yaw = turn_between_deg(r1, y1, r2, y2)
    assert abs(roll) <= 90.0 + 1e-9
    q = quaternion.from_dcm(reference_frame(sun, star))
    for axis, angle in (((1, 0, 0), r1), ((0, 0, 1), y1), ((1, 0, 0), roll), ((0, 0, 1), yaw)):
        q = quaternion.multiply(q, quaternion.from_axis_angle(axis, math.radians(angle)))
    x_inertial = quaternion.dcm_body_from_inertial(q)[0]
    assert np.allclose(x_inertial, second, atol=1e-9)
    # The turn's yaw is the angle between the two targets (a roll does not move +x).
    between = math.atan2(np.linalg.norm(np.cross(first, second)), first @ second)
    assert abs(yaw) == pytest.approx(math.degrees(between), abs=1e-7)


def test_the_attitude_after_a_manoeuvre_points_x_where_pointing_direction_says():
    for roll, yaw in ((0.0, 0.0), (30.0, 45.0), (-80.0, 170.0), (90.0, -10.0)):
        b = attitude_after(roll, yaw)
        assert np.allclose(b.T @ b, np.eye(3), atol=1e-15)
        assert np.allclose(b[:, 0], pointing_direction(roll, yaw), atol=1e-15)
