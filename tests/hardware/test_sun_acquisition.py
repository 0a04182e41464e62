"""Mode 1 sun-acquisition controller (allsky.hardware.sun_acquisition) against geometry.

Truth:
- a body rate about u = x x s (s the Sun in body axes) turns the roll axis
  +x toward the Sun in the plane of x and s, so the Sun angle falls at
  exactly |rate| (u is normal to both x and s);
- the slew command is gain x angle, capped at the slew limit (module
  docstring; default scenario: 0.05 /s and 1 deg/s = 3600 "/s);
- inside the fine sensor's +-7200" linear range (SPEC section 2) the fine
  pitch and yaw errors become the control amplifiers' position inputs and the
  gyro rates damp them;
- the control amplifiers use V = Kp pos - Kd rate (allsky.hardware.control_amp): the
  rate input is "measured minus commanded", so the commanded rate is
  gyro - rate.
"""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from allsky import gauss, units
from allsky.hardware.sun_acquisition import SunAcquisitionParams, sun_acquisition
from allsky.hardware.sun_sensor import SunSensorParams, sun_sensor
from allsky.vehicle import quaternion

GAIN_PER_S = 0.05
CAP_ARCSEC_S = 3600.0
LINEAR_ARCSEC = 7200.0
P = SunAcquisitionParams(GAIN_PER_S, CAP_ARCSEC_S)
GYRO = np.array([12.0, -7.0, 3.0])  # [arcsec/s] some measured rates
ABSENT = np.array([0.0, 0.0, 0.0])

component = st.floats(-1.0, 1.0, allow_nan=False)
directions = st.tuples(component, component, component).filter(
    lambda v: np.linalg.norm(v) > 0.1).map(lambda v: np.array(v) / np.linalg.norm(v))


def run(fine, coarse_body, gyro=GYRO):
    pos = np.full(3, np.nan)
    rate = np.full(3, np.nan)
    sun_acquisition(P, LINEAR_ARCSEC, np.asarray(fine, dtype=float),
                    np.asarray(coarse_body, dtype=float), np.asarray(gyro, dtype=float), pos, rate)
    return pos, rate


def commanded(rate, gyro=GYRO):
    return np.asarray(gyro) - rate


@pytest.mark.parametrize("pitch, yaw", [(0.0, 0.0), (7199.0, -7199.0), (-300.0, 45.0)])
def test_in_range_fine_errors_are_the_position_inputs(pitch, yaw):
    pos, rate = run([pitch, yaw, 1.0], [1.0, 0.0, 0.0])
    assert np.array_equal(pos, [0.0, pitch, yaw])
    assert np.array_equal(rate, GYRO)  # plain damping, no command


@pytest.mark.parametrize("fine", [[7200.0, 0.0, 1.0], [0.0, -7200.0, 1.0], [100.0, 100.0, 0.0]])
def test_saturated_or_absent_fine_sensor_means_slew(fine):
    s = np.array([0.9, 0.3, -0.3])
    s /= np.linalg.norm(s)
    pos, rate = run(fine, s)
    assert np.array_equal(pos, [0.0, 0.0, 0.0])
    assert np.linalg.norm(commanded(rate)[1:]) > 0.0


@settings(max_examples=100, deadline=None)
@given(s=directions.filter(lambda s: math.hypot(s[1], s[2]) > 1e-6))
def test_slew_command_turns_x_toward_the_sun_at_gain_times_angle_capped(s):
    pos, rate = run(ABSENT, s)
    cmd = commanded(rate)
    assert np.array_equal(pos, [0.0, 0.0, 0.0])
    assert cmd[0] == 0.0 and rate[0] == GYRO[0]  # roll rate nulled, not commanded
    u = np.cross([1.0, 0.0, 0.0], s)
    u /= np.linalg.norm(u)
    angle = math.atan2(math.hypot(s[1], s[2]), s[0])
    magnitude = min(GAIN_PER_S * angle * units.RAD2ARCSEC, CAP_ARCSEC_S)
    assert np.allclose(cmd, magnitude * u, rtol=1e-12, atol=1e-9)
    # Turn the body by a small step of that rate about its body axis: the Sun
    # angle falls by exactly the step (a step short of the Sun: no overshoot).
    step_rad = min(1e-4, 0.1 * angle)
    dq = quaternion.from_axis_angle(cmd, step_rad)
    s_after = quaternion.dcm_body_from_inertial(dq) @ s  # body frame turned by dq
    angle_after = math.atan2(math.hypot(s_after[1], s_after[2]), s_after[0])
    assert angle_after == pytest.approx(angle - step_rad, abs=1e-12)


@pytest.mark.parametrize("angle_deg, expected_arcsec_s", [
    (1.0, 0.05 * math.radians(1.0) * units.RAD2ARCSEC),    # 180 "/s: proportional
    (10.0, 0.05 * math.radians(10.0) * units.RAD2ARCSEC),  # 1800 "/s: proportional
    (20.0, 3600.0),  # 0.05 /s x 72000" = 3600 "/s: the corner
    (25.0, 3600.0),  # 4500 "/s asked: capped
    (90.0, 3600.0),
    (179.0, 3600.0),
])
def test_command_magnitude(angle_deg, expected_arcsec_s):
    a = math.radians(angle_deg)
    s = np.array([math.cos(a), 0.0, math.sin(a)])
    _, rate = run(ABSENT, s)
    assert np.linalg.norm(commanded(rate)) == pytest.approx(expected_arcsec_s, rel=1e-12)


def test_sun_exactly_behind_gives_a_capped_turn_normal_to_x():
    pos, rate = run(ABSENT, [-1.0, 0.0, 0.0])
    cmd = commanded(rate)
    assert np.all(np.isfinite(rate)) and np.array_equal(pos, [0.0, 0.0, 0.0])
    assert cmd[0] == 0.0
    assert np.linalg.norm(cmd) == pytest.approx(CAP_ARCSEC_S, rel=1e-15)  # pi rad off


def test_sun_almost_behind_is_finite_and_capped():
    for eps in (1e-9, 1e-13, 1e-300):
        s = np.array([-1.0, eps, -eps])
        _, rate = run(ABSENT, s / np.linalg.norm(s))
        assert np.all(np.isfinite(rate))
        assert np.linalg.norm(commanded(rate)) == pytest.approx(CAP_ARCSEC_S, rel=1e-15)


@pytest.mark.parametrize("pitch_deg, yaw_deg", [(3.0, 0.0), (0.0, -3.0), (2.5, 2.5), (-5.0, 4.0)])
def test_slew_agrees_in_sign_with_the_fine_errors_at_hand_over(pitch_deg, yaw_deg):
    # Just outside the linear range the fine sensor reads saturated errors whose
    # signs say which way to turn (+pitch about +y, +yaw about +z); the slew
    # command must turn the same way, so the hand-over does not reverse the loop.
    s = np.array([1.0, math.tan(math.radians(yaw_deg)), -math.tan(math.radians(pitch_deg))])
    s /= np.linalg.norm(s)
    fine = np.zeros(3)
    sun_sensor(SunSensorParams(LINEAR_ARCSEC, math.cos(math.radians(30.0)), 0.0, 0.0), s, fine,
               gauss.new_generator())
    assert fine[2] == 1.0
    _, rate = run(fine, s)
    cmd = commanded(rate)
    assert np.array_equal(np.sign(cmd[1:]), np.sign(fine[:2]))
