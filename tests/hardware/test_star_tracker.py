"""Star tracker 105 (allsky.hardware.star_tracker) against the geometry of its slit field.

Truth:
- the outputs are the rotations that bring the boresight +z onto the star
  (module docstring): a right-hand turn by a about +x carries +z to
  (0, -sin a, cos a), by b about +y to (sin b, 0, cos b); so
  yaw = atan2(-s_y, s_z) (what a roll moves) and pitch = atan2(s_x, s_z);
- field of view a slit, +-16 deg along the tracker pitch direction and
  +-8 deg across (default scenario; SPEC section 1: the Sun-Canopus angle
  moves the star along the slit);
- of several stars in the field, the one nearest the boresight is tracked; only
  stars handed to the block (those inside the magnitude window, chosen before
  flight) exist for it;
- white noise of 1-sigma sigma per output.
"""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from allsky import gauss, units
from allsky.hardware.star_tracker import StarTrackerParams, star_tracker
from allsky.vehicle import quaternion

LONG_DEG, NARROW_DEG = 16.0, 8.0  # default scenario


RNG = gauss.new_generator()  #: the noise generator these tests' blocks draw from


def seed(s):
    """Seed the generator the blocks draw from."""
    gauss.seed(RNG, s)


def params(stars_inertial, noise_arcsec=0.0):
    return StarTrackerParams(LONG_DEG * units.DEG2RAD, NARROW_DEG * units.DEG2RAD, noise_arcsec,
                             np.atleast_2d(np.asarray(stars_inertial, dtype=float)))


def star_at(yaw_deg, pitch_deg):
    """Unit body vector of a star seen at the given tracker yaw and pitch."""
    s = np.array([math.tan(math.radians(pitch_deg)), -math.tan(math.radians(yaw_deg)), 1.0])
    return s / np.linalg.norm(s)


IDENTITY = np.array([1.0, 0.0, 0.0, 0.0])


def look(p, q=IDENTITY):
    out = np.full(3, np.nan)
    star_tracker(p, np.asarray(q, dtype=float), out, RNG)
    return out


@pytest.mark.parametrize("yaw, pitch", [(0.0, 0.0), (1.0, 0.0), (0.0, -2.0), (-0.5, 12.0),
                                        (7.5, -15.5)])
def test_known_angles_are_read_back(yaw, pitch):
    out = look(params(star_at(yaw, pitch)))
    assert out[0] == pytest.approx(yaw * 3600.0, abs=1e-8)
    assert out[1] == pytest.approx(pitch * 3600.0, abs=1e-8)
    assert out[2] == 1.0


@pytest.mark.parametrize("axis, angle_deg", [(0, 1.5), (0, -6.0), (1, 3.0), (1, -14.0)])
def test_turning_by_the_output_brings_the_boresight_onto_the_star(axis, angle_deg):
    # The star sits where a body turn of +angle about +x (yaw output) or +y (pitch
    # output) would bring +z; the output reports that turn.
    star = np.array([0.0, 0.0, 1.0])
    q = quaternion.from_axis_angle(np.eye(3)[axis], -math.radians(angle_deg))
    out = look(params(star), q)
    reported = out[0] if axis == 0 else out[1]
    other = out[1] if axis == 0 else out[0]
    assert reported == pytest.approx(angle_deg * 3600.0, abs=1e-8)
    assert other == pytest.approx(0.0, abs=1e-8)
    turned = quaternion.multiply(q, quaternion.from_axis_angle(np.eye(3)[axis],
                                                                reported * units.ARCSEC2RAD))
    assert np.allclose(quaternion.dcm_body_from_inertial(turned) @ star, [0, 0, 1],
                       rtol=0, atol=1e-14)


def test_a_roll_moves_the_yaw_output_only():
    # Star on the boresight; roll the vehicle by +d about +x: the star appears at
    # yaw -d (the turn back), pitch unchanged.
    d = math.radians(0.3)
    out = look(params([0.0, 0.0, 1.0]), quaternion.from_axis_angle([1, 0, 0], d))
    assert out[0] == pytest.approx(-0.3 * 3600.0, abs=1e-8)
    assert out[1] == pytest.approx(0.0, abs=1e-8)


@settings(max_examples=50, deadline=None)
@given(yaw=st.floats(-7.9, 7.9), pitch=st.floats(-15.9, 15.9),
       axis=st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(-1, 1)).filter(
           lambda a: np.linalg.norm(a) > 0.1),
       angle=st.floats(-math.pi, math.pi))
def test_any_attitude(yaw, pitch, axis, angle):
    q = quaternion.from_axis_angle(axis, angle)
    star_inertial = quaternion.dcm_body_from_inertial(q).T @ star_at(yaw, pitch)
    out = look(params(star_inertial), q)
    assert out[0] == pytest.approx(yaw * 3600.0, abs=1e-7)
    assert out[1] == pytest.approx(pitch * 3600.0, abs=1e-7)
    assert out[2] == 1.0


@pytest.mark.parametrize("yaw, pitch, present", [
    (0.0, 15.9, True), (0.0, 16.1, False), (0.0, -15.9, True), (0.0, -16.1, False),
    (7.9, 0.0, True), (8.1, 0.0, False), (-7.9, 0.0, True), (-8.1, 0.0, False),
    (7.9, 15.9, True),   # a slit: the corner is in the field
    (10.0, 5.0, False),  # long in pitch, narrow in yaw: 10 deg across is out
])
def test_field_of_view_is_a_slit(yaw, pitch, present):
    out = look(params(star_at(yaw, pitch), noise_arcsec=2.0))
    if present:
        assert out[2] == 1.0
    else:
        assert np.array_equal(out, [0.0, 0.0, 0.0])


@pytest.mark.parametrize("star", [[0.0, 0.0, -1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0],
                                  [0.01, 0.0, -1.0]])
def test_star_behind_or_beside_is_absent(star):
    # s_z <= 0: atan2 would fold these into the +-180 deg range; they must not lock.
    star = np.asarray(star) / np.linalg.norm(star)
    assert np.array_equal(look(params(star)), [0.0, 0.0, 0.0])


def test_empty_catalog_is_absent():
    p = StarTrackerParams(LONG_DEG * units.DEG2RAD, NARROW_DEG * units.DEG2RAD, 0.0,
                          np.zeros((0, 3)))
    assert np.array_equal(look(p), [0.0, 0.0, 0.0])


@pytest.mark.parametrize("order", [(0, 1, 2), (2, 1, 0), (1, 2, 0)])
def test_the_star_nearest_the_boresight_is_tracked(order):
    stars = [star_at(0.0, 10.0),   # 10 deg along the slit
             star_at(2.0, -3.0),   # 3.6 deg off: nearest
             star_at(0.0, -30.0)]  # outside the field, though "nearer" than none
    out = look(params([stars[i] for i in order]))
    assert out[0] == pytest.approx(2.0 * 3600.0, abs=1e-8)
    assert out[1] == pytest.approx(-3.0 * 3600.0, abs=1e-8)


def test_only_stars_inside_the_magnitude_window_exist_for_the_tracker():
    # Canopus (-0.62 mag) is in the default window [-1.0, -0.3]; Sirius (-1.44) is not,
    # so the pre-flight list holds Canopus only. Even with Sirius on the boresight
    # the tracker reports Canopus.
    canopus = star_at(1.0, 9.0)
    sirius = star_at(0.0, 0.0)
    assert np.allclose(look(params([canopus]))[:2], [3600.0, 9.0 * 3600.0], rtol=0, atol=1e-8)
    both = look(params([canopus, sirius]))
    assert np.allclose(both[:2], [0.0, 0.0], rtol=0, atol=1e-8)  # with both, the nearer wins


def test_noise_standard_deviation():
    p = params(star_at(0.5, -4.0), noise_arcsec=2.0)
    seed(17)
    samples = np.array([look(p) for _ in range(4000)])
    # 4000 samples: relative standard error of the std 1/sqrt(8000) = 1.1 %.
    assert np.std(samples[:, 0]) == pytest.approx(2.0, rel=0.06)
    assert np.std(samples[:, 1]) == pytest.approx(2.0, rel=0.06)
    assert np.mean(samples[:, 0]) == pytest.approx(1800.0, abs=5 * 2.0 / math.sqrt(4000))
    assert np.mean(samples[:, 1]) == pytest.approx(-14400.0, abs=5 * 2.0 / math.sqrt(4000))
    assert np.all(samples[:, 2] == 1.0)


def test_the_tracker_tells_which_star_it_holds():
    """It returns the index of the star nearest the boresight, -1 with none in the field.

    Stars at (yaw, pitch) = (30, 0) deg (outside the +-8 deg narrow field),
    (0.5, 3) and (-2, 1): squared distances 9.25 and 5 deg^2, so star 2.
    """
    p = params([star_at(30.0, 0.0), star_at(0.5, 3.0), star_at(-2.0, 1.0)])
    out = np.full(3, np.nan)
    assert star_tracker(p, IDENTITY, out, RNG) == 2
    assert out[2] == 1.0
    assert star_tracker(params([star_at(30.0, 0.0)]), IDENTITY, out, RNG) == -1
    assert out[2] == 0.0
