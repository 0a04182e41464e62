"""Sun sensor 104 and the coarse sun eyes (allsky.hardware.sun_sensor) against geometry.

Truth:
- the fine outputs are the rotations about body +y (pitch) and +z (yaw) that
  bring the roll axis +x onto the Sun (module docstring): a right-hand turn by
  p about +y carries +x to (cos p, 0, -sin p), by y about +z to
  (cos y, sin y, 0); so pitch = atan2(-s_z, s_x), yaw = atan2(s_y, s_x);
- linear within +-7200" (SPEC sections 2 and 6), saturated beyond, zero and
  "absent" outside the presence cone (30 deg half-angle in the default
  scenario);
- white noise of 1-sigma sigma per output; the coarse eyes' direction error, two
  independent normal components of sigma across the line of sight, has a
  Rayleigh distribution of mean sigma sqrt(pi/2).
"""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from allsky import gauss, units
from allsky.hardware.sun_sensor import SunSensorParams, coarse_sun, sun_sensor
from allsky.vehicle import quaternion

LINEAR_ARCSEC = 7200.0
PRESENCE_DEG = 30.0  # default scenario


def params(noise_arcsec=0.0, coarse_noise_rad=0.0):
    return SunSensorParams(LINEAR_ARCSEC, math.cos(PRESENCE_DEG * units.DEG2RAD),
                           noise_arcsec, coarse_noise_rad)


RNG = gauss.new_generator()  #: the noise generator these tests' blocks draw from


def seed(s):
    """Seed the generator the blocks draw from."""
    gauss.seed(RNG, s)


def sun_at(pitch_arcsec, yaw_arcsec):
    """Unit Sun vector (body) whose in-plane angles are the given pitch and yaw."""
    s = np.array([1.0, math.tan(yaw_arcsec * units.ARCSEC2RAD),
                  -math.tan(pitch_arcsec * units.ARCSEC2RAD)])
    return s / np.linalg.norm(s)


def measure(s_body, p=None):
    out = np.full(3, np.nan)
    sun_sensor(p or params(), np.asarray(s_body, dtype=float), out, RNG)
    return out


@pytest.mark.parametrize("pitch, yaw", [(0.0, 0.0), (100.0, 0.0), (0.0, -250.0),
                                        (3000.0, -7000.0), (-7199.0, 7199.0)])
def test_known_small_angles_are_read_back(pitch, yaw):
    out = measure(sun_at(pitch, yaw))
    assert out[0] == pytest.approx(pitch, abs=1e-9)
    assert out[1] == pytest.approx(yaw, abs=1e-9)
    assert out[2] == 1.0


@pytest.mark.parametrize("axis, angle_arcsec", [(1, 600.0), (1, -1800.0), (2, 900.0), (2, -60.0)])
def test_turning_by_the_output_brings_the_roll_axis_onto_the_sun(axis, angle_arcsec):
    # Put the Sun where a body turn of +angle about +y (pitch) or +z (yaw) would
    # bring +x: the sensor must report that angle on that output, zero on the other.
    sun_inertial = np.array([1.0, 0.0, 0.0])
    q = quaternion.from_axis_angle(np.eye(3)[axis], -angle_arcsec * units.ARCSEC2RAD)
    out = measure(quaternion.dcm_body_from_inertial(q) @ sun_inertial)
    reported = out[0] if axis == 1 else out[1]
    other = out[1] if axis == 1 else out[0]
    assert reported == pytest.approx(angle_arcsec, abs=1e-9)
    assert other == pytest.approx(0.0, abs=1e-9)
    # Apply the reported turn: the Sun lands on +x.
    turned = quaternion.multiply(q, quaternion.from_axis_angle(np.eye(3)[axis],
                                                                reported * units.ARCSEC2RAD))
    assert np.allclose(quaternion.dcm_body_from_inertial(turned) @ sun_inertial, [1, 0, 0],
                       rtol=0, atol=1e-14)


def test_sign_convention_of_the_docstring():
    s = np.array([1.0, 0.009, -0.006])  # about 1900" and 1200" off: inside the linear range
    s /= np.linalg.norm(s)
    out = measure(s)
    assert out[0] > 0.0 and out[1] > 0.0
    assert out[0] == pytest.approx(math.atan2(-s[2], s[0]) * units.RAD2ARCSEC, rel=1e-15)
    assert out[1] == pytest.approx(math.atan2(s[1], s[0]) * units.RAD2ARCSEC, rel=1e-15)


@settings(max_examples=60, deadline=None)
@given(pitch=st.floats(-20000.0, 20000.0), yaw=st.floats(-20000.0, 20000.0))
def test_linear_then_saturated(pitch, yaw):
    out = measure(sun_at(pitch, yaw))
    assert out[0] == pytest.approx(np.clip(pitch, -LINEAR_ARCSEC, LINEAR_ARCSEC), abs=1e-8)
    assert out[1] == pytest.approx(np.clip(yaw, -LINEAR_ARCSEC, LINEAR_ARCSEC), abs=1e-8)
    assert out[2] == 1.0  # 20000" = 5.6 deg: well inside the 30 deg cone


@pytest.mark.parametrize("off_deg, present", [(29.9, True), (30.1, False), (90.0, False),
                                              (180.0, False)])
def test_presence_cone(off_deg, present):
    # Sun off +x by off_deg toward (y + z)/sqrt(2).
    a = math.radians(off_deg)
    s = np.array([math.cos(a), math.sin(a) / math.sqrt(2), math.sin(a) / math.sqrt(2)])
    out = measure(s, params(noise_arcsec=1.0))
    if present:
        assert out[2] == 1.0
        assert abs(out[0]) == LINEAR_ARCSEC and abs(out[1]) == LINEAR_ARCSEC  # saturated
    else:
        assert np.array_equal(out, [0.0, 0.0, 0.0])  # noise off too when absent


def test_noise_standard_deviation():
    p = params(noise_arcsec=0.5)
    seed(5)
    s = sun_at(40.0, -30.0)
    samples = np.array([measure(s, p) for _ in range(4000)])
    # 4000 samples: relative standard error of the std 1/sqrt(8000) = 1.1 %.
    assert np.std(samples[:, 0]) == pytest.approx(0.5, rel=0.06)
    assert np.std(samples[:, 1]) == pytest.approx(0.5, rel=0.06)
    assert np.mean(samples[:, 0]) == pytest.approx(40.0, abs=5 * 0.5 / math.sqrt(4000))
    assert np.mean(samples[:, 1]) == pytest.approx(-30.0, abs=5 * 0.5 / math.sqrt(4000))
    assert abs(np.corrcoef(samples[:, 0], samples[:, 1])[0, 1]) < 5 / math.sqrt(4000)


def test_coarse_sun_without_noise_is_the_truth():
    s = np.array([-0.3, 0.5, 0.81])
    s /= np.linalg.norm(s)
    out = np.zeros(3)
    coarse_sun(params(), s, out, RNG)
    assert np.allclose(out, s, rtol=0, atol=1e-16)


def test_coarse_sun_is_a_unit_vector_near_the_truth():
    sigma = 0.5 * units.DEG2RAD  # default scenario
    p = params(coarse_noise_rad=sigma)
    seed(9)
    rng = np.random.default_rng(9)
    errors = []
    out = np.zeros(3)
    for _ in range(3000):
        s = rng.normal(size=3)
        s /= np.linalg.norm(s)  # anywhere on the sphere (Mode 1 starts tumbling)
        coarse_sun(p, s, out, RNG)
        assert abs(np.linalg.norm(out) - 1.0) < 1e-15
        errors.append(math.acos(min(1.0, out @ s)))
    errors = np.array(errors)
    # Rayleigh mean sigma sqrt(pi/2) (small-angle: the radial component only rescales).
    assert errors.mean() == pytest.approx(sigma * math.sqrt(math.pi / 2), rel=0.05)
    assert errors.max() < 6 * sigma
