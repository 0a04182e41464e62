"""Star tracker 105 (allsky.hardware.star_tracker) against the geometry of its slit field.

Truth:
- the outputs are the rotations that bring the boresight +z onto the star
  (module docstring): a right-hand turn by a about +x carries +z to
  (0, -sin a, cos a), by b about +y to (sin b, 0, cos b); so
  yaw = atan2(-s_y, s_z) (what a roll moves) and pitch = atan2(s_x, s_z);
- field of view a slit, +-16 deg along the tracker pitch direction and
  +-8 deg across (default scenario; SPEC section 1: the Sun-Canopus angle
  moves the star along the slit);
- a slit tracker of the era (SPEC section 2) locks the first window star it
  finds in its slit (of several found at once, the one nearest the
  boresight) and holds it until it leaves the field: a second window star
  entering the slit does not take the lock; only then does it search again;
  only stars handed to the block (those inside the magnitude window, chosen
  before flight) exist for it;
- the pitch output is the star's cone angle, 90 deg less its angle from the
  Sun when the roll axis is on the Sun; the cone-angle check refuses a star
  whose cone angle is further than the check from the reference star's;
- white noise of 1-sigma sigma per output.
"""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from allsky import gauss, units
from allsky.hardware import star_tracker as trk
from allsky.hardware.star_tracker import make_params, new_lock, star_tracker
from allsky.vehicle import quaternion, sky

LONG_DEG, NARROW_DEG = 16.0, 8.0  # default scenario


RNG = gauss.new_generator()  #: the noise generator these tests' blocks draw from


def seed(s):
    """Seed the generator the blocks draw from."""
    gauss.seed(RNG, s)


def params(stars_inertial, noise_arcsec=0.0, **kwargs):
    return make_params(LONG_DEG * units.DEG2RAD, NARROW_DEG * units.DEG2RAD, noise_arcsec,
                       np.atleast_2d(np.asarray(stars_inertial, dtype=float)), **kwargs)


def star_at(yaw_deg, pitch_deg):
    """Unit body vector of a star seen at the given tracker yaw and pitch."""
    s = np.array([math.tan(math.radians(pitch_deg)), -math.tan(math.radians(yaw_deg)), 1.0])
    return s / np.linalg.norm(s)


IDENTITY = np.array([1.0, 0.0, 0.0, 0.0])


def look(p, q=IDENTITY, lock=None):
    """The outputs for attitude ``q``: a tracker that held nothing, or the memory ``lock``."""
    out = np.full(3, np.nan)
    star_tracker(p, np.asarray(q, dtype=float), new_lock() if lock is None else lock, out, RNG)
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
    p = make_params(LONG_DEG * units.DEG2RAD, NARROW_DEG * units.DEG2RAD, 0.0, np.zeros((0, 3)))
    assert np.array_equal(look(p), [0.0, 0.0, 0.0])


@pytest.mark.parametrize("order", [(0, 1, 2), (2, 1, 0), (1, 2, 0)])
def test_of_stars_found_at_once_the_one_nearest_the_boresight_is_locked(order):
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
    """It returns the index of the star it locked, -1 with none in the field.

    Stars at (yaw, pitch) = (30, 0) deg (outside the +-8 deg narrow field),
    (0.5, 3) and (-2, 1): squared distances 9.25 and 5 deg^2, so star 2.
    """
    p = params([star_at(30.0, 0.0), star_at(0.5, 3.0), star_at(-2.0, 1.0)])
    out = np.full(3, np.nan)
    lock = new_lock()
    assert star_tracker(p, IDENTITY, lock, out, RNG) == 2
    assert out[2] == 1.0 and lock[trk.HELD] == 2
    lock = new_lock()
    assert star_tracker(params([star_at(30.0, 0.0)]), IDENTITY, lock, out, RNG) == -1
    assert out[2] == 0.0 and lock[trk.HELD] == trk.NONE


def _roll(deg):
    """The attitude rolled by ``deg`` about +x (the Sun line) from the identity."""
    return quaternion.from_axis_angle([1.0, 0.0, 0.0], math.radians(deg))


def _geometric_deg(star_body, roll_deg):
    """(yaw, pitch) outputs [deg] of a star for a roll about +x: the body turns, not the star."""
    v = quaternion.dcm_body_from_inertial(_roll(roll_deg)) @ star_body
    return math.degrees(math.atan2(-v[1], v[2])), math.degrees(math.atan2(v[0], v[2]))


def test_a_second_star_entering_the_slit_does_not_take_the_lock():
    """Rolling about the Sun line, star A (pitch 5 deg) enters the slit first, then star B
    (pitch -2 deg, nearer the boresight) while A is still in it: the tracker holds A, frame
    after frame, until A leaves the narrow field (|yaw| > 8 deg); then it searches and
    takes B. The outputs are A's geometry throughout, then B's.

    A sits at yaw +12 deg, B at yaw +15 deg at zero roll; a roll of r moves both to
    about yaw - r (a roll of +d shows a star on the boresight at yaw -d).
    """
    a, b = star_at(12.0, 5.0), star_at(15.0, -2.0)
    p = params([a, b])
    lock = new_lock()
    rolls = np.arange(0.0, 30.0, 0.25)
    held = []
    for roll in rolls:
        out = look(p, _roll(roll), lock)
        k = int(lock[trk.HELD])
        held.append(k)
        if k >= 0:
            yaw, pitch = _geometric_deg((a, b)[k], roll)
            assert out[0] == pytest.approx(yaw * 3600.0, abs=1e-6)
            assert out[1] == pytest.approx(pitch * 3600.0, abs=1e-6)
    held = np.array(held)
    inside_a = np.array([abs(_geometric_deg(a, r)[0]) <= NARROW_DEG for r in rolls])
    inside_b = np.array([abs(_geometric_deg(b, r)[0]) <= NARROW_DEG for r in rolls])
    assert np.any(inside_a & inside_b & (np.abs([_geometric_deg(b, r)[0] for r in rolls])
                                         < np.abs([_geometric_deg(a, r)[0] for r in rolls])))
    assert np.all(held[inside_a] == 0)  # A, all the while it is in the slit
    first_out = np.flatnonzero(~inside_a & (rolls > 10.0))[0]
    assert held[first_out] == 1  # the frame A has left, the search finds B
    # Without the memory (a fresh search each frame) B, nearer the boresight, would win:
    both = np.flatnonzero(inside_a & inside_b)[-1]
    assert look(p, _roll(rolls[both]))[0] == pytest.approx(
        _geometric_deg(b, rolls[both])[0] * 3600.0, abs=1e-6)


def test_a_held_star_is_kept_only_while_in_the_field():
    p = params([star_at(0.0, 15.0)])
    lock = new_lock()
    assert look(p, IDENTITY, lock)[2] == 1.0
    gone = quaternion.from_axis_angle([0.0, 1.0, 0.0], math.radians(-2.0))  # pitch 17 deg
    assert look(p, gone, lock)[2] == 0.0 and lock[trk.HELD] == trk.NONE


def _sun_frame_attitude(date, star_name, yaw_deg=0.0):
    """The attitude with +x on the Sun and ``star_name`` at tracker yaw ``yaw_deg``.

    The body frame of the reference attitude (computer.targeting's), rolled
    so that the star sits ``yaw_deg`` off the slit's centre line.
    """
    from allsky.computer.targeting import reference_frame

    sun = sky.sun_direction_inertial(date)
    star = sky.star_direction_inertial(star_name, date)
    dcm = reference_frame(sun, star)  # rows: body axes in inertial components
    q = quaternion.from_dcm(dcm)
    return quaternion.multiply(q, quaternion.from_axis_angle([1, 0, 0],
                                                             -math.radians(yaw_deg)))


#: The default mission's date (scenarios/default.toml).
DEFAULT_DATE = "2026-11-22T12:00:00Z"


def test_cone_angles_are_90_deg_less_the_angle_from_the_sun():
    """The issue's figures: Canopus -9.95 deg, Avior +6.76 deg on the default date."""
    from datetime import datetime

    date = datetime.fromisoformat(DEFAULT_DATE)
    sun = sky.sun_direction_inertial(date)
    for name, cone in (("Canopus", -9.95), ("Avior", 6.76)):
        star = sky.star_direction_inertial(name, date)
        theta = math.degrees(math.acos(sun @ star))
        assert trk.cone_angle_deg(theta) == pytest.approx(cone, abs=0.005)
        out = look(params([star]), _sun_frame_attitude(date, name))
        assert out[1] / 3600.0 == pytest.approx(cone, abs=0.005)  # the pitch output


def test_the_cone_angle_check_refuses_avior_and_the_search_goes_on():
    """Reference Canopus (cone -9.95 deg), check 5 deg. Rolling positive about the Sun
    line from the reference attitude, Avior (cone +6.76, 16.7 deg away), 5.83 deg of roll
    ahead of Canopus, enters the slit first: it is refused once, remembered while it
    crosses, and Canopus, entering 5.83 deg of roll later, is locked; Avior is forgotten
    once it has left. Without the check Avior is locked, and held."""
    from datetime import datetime

    from allsky.computer.targeting import reference_frame

    date = datetime.fromisoformat(DEFAULT_DATE)
    sun = sky.sun_direction_inertial(date)
    stars = [sky.star_direction_inertial(n, date) for n in ("Avior", "Canopus")]
    frame = reference_frame(sun, stars[1])  # rows: body axes, Canopus at yaw 0
    in_ref = [frame @ v for v in stars]
    avior_yaw0 = math.degrees(math.atan2(-in_ref[0][1], in_ref[0][2]))
    assert avior_yaw0 == pytest.approx(-5.83, abs=0.01)
    ref = math.radians(-9.95)
    checked = params(in_ref, reference_cone_rad=ref, cone_check_rad=math.radians(5.0))
    plain = params(in_ref, reference_cone_rad=ref)
    lock, lock_plain = new_lock(), new_lock()
    refusals = []
    for roll in np.arange(-20.0, 10.0, 0.1):
        look(checked, _roll(roll), lock)
        look(plain, _roll(roll), lock_plain)
        if lock[trk.NEW_REFUSAL] != trk.NONE:
            refusals.append((roll, int(lock[trk.NEW_REFUSAL]),
                             lock[trk.REFUSED_CONE_ARCSEC] / 3600.0))
        canopus_yaw = _geometric_deg(in_ref[1], roll)[0]
        assert lock[trk.HELD] == (1 if abs(canopus_yaw) <= NARROW_DEG else trk.NONE)
        if roll > 2.3:  # Avior has left the slit (yaw < -8 deg): forgotten
            assert not trk.refused(lock, 0)
        avior_yaw = _geometric_deg(in_ref[0], roll)[0]
        if abs(avior_yaw) <= NARROW_DEG and roll < -2.0:
            assert lock_plain[trk.HELD] == 0  # no check: Avior, met first, is held
    assert len(refusals) == 1
    roll, k, cone = refusals[0]
    # Its cone angle as seen where it entered: the pitch output at |yaw| = 8 deg, a little
    # more than at the slit's centre line (tan pitch = cot theta / cos yaw).
    assert k == 0 and cone == pytest.approx(_geometric_deg(in_ref[0], roll)[1], abs=1e-9)
    assert math.degrees(math.atan(math.tan(math.radians(6.76)) / math.cos(
        math.radians(8.0)))) == pytest.approx(cone, abs=0.005)
    assert roll == pytest.approx(avior_yaw0 - NARROW_DEG, abs=0.15)  # as it enters the slit


def test_the_cone_angle_check_acts_only_while_armed():
    """Unarmed (the roll axis off the Sun: the pitch output is not the cone angle) the
    tracker takes a star the check would refuse, and flags no refusal."""
    p = params([star_at(0.0, 6.0)], reference_cone_rad=math.radians(-10.0),
               cone_check_rad=math.radians(2.0))
    lock = new_lock()
    out = np.zeros(3)
    assert star_tracker(p, IDENTITY, lock, out, RNG, False) == 0
    assert lock[trk.NEW_REFUSAL] == trk.NONE and out[2] == 1.0
    lock = new_lock()
    assert star_tracker(p, IDENTITY, lock, out, RNG, True) == -1
    assert lock[trk.NEW_REFUSAL] == 0


# -- the bright gate counts every light in the slit -----------------------------------


def _gate_params(gate_stars, gate_mags, window=(-2.88, 1.64)):
    """A tracker whose window holds the first gate star, with the gate on."""
    return params(gate_stars[0], magnitudes=[gate_mags[0]], window_mag=window,
                  bright_gate=True, gate_stars_inertial=gate_stars, gate_magnitudes=gate_mags)


def pogson(*mags):
    """The magnitude of several sources together: fluxes add (Pogson)."""
    return -2.5 * math.log10(sum(10.0 ** (-0.4 * m) for m in mags))


def test_the_gate_counts_the_held_star_the_other_stars_in_the_slit_and_no_star_outside():
    held, other, faint, outside = (star_at(0.0, 0.0), star_at(3.0, 10.0), star_at(-6.0, -14.0),
                                   star_at(9.0, 0.0))  # the last beyond the 8 deg half-width
    mags = [-0.62, -2.8, 3.5, -5.0]  # the faint one outside the window, yet its light counts
    p = _gate_params(np.array([held, other, faint, outside]), mags, window=(-2.88, 1.64))
    lock = new_lock()
    out = np.zeros(3)
    star_tracker(p, IDENTITY, lock, out, RNG)
    seen = pogson(*mags[:3])
    assert -2.5 * math.log10(lock[trk.SLIT_FLUX]) == pytest.approx(seen, abs=1e-12)
    assert seen < -2.88 < pogson(mags[0], mags[2]) < pogson(mags[0])  # only the three trip it
    assert trk.bright_gate(p, lock, 0, out) == -1 and out[2] == 0.0
    assert lock[trk.NEW_DROP] == 0 and lock[trk.SEEN_MAG] == pytest.approx(seen, abs=1e-12)
    # Without the bright neighbour the slit stays under the gate, and the lock is kept.
    p2 = _gate_params(np.array([held, faint, outside]), [mags[0], mags[2], mags[3]])
    lock2 = new_lock()
    star_tracker(p2, IDENTITY, lock2, out, RNG)
    assert trk.bright_gate(p2, lock2, 0, out) == 0 and lock2[trk.GATE] == 0.0


def test_a_tracker_without_a_gate_counts_no_light():
    p = params(star_at(0.0, 0.0), bright_gate=False)
    assert p.gate_stars_inertial.shape == (0, 3)
    lock = new_lock()
    star_tracker(p, IDENTITY, lock, np.zeros(3), RNG)
    assert lock[trk.SLIT_FLUX] == 0.0
