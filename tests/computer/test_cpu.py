"""CPU 22 against the calibration and Mode 6 arithmetic of SPEC section 4.

Truth:

* Calibration: scale factor = true angle / counted angle; cross-coupling =
  counts accumulated on the other axis / true angle. A gyro triad with
  sensitivity S = diag(1 + sf)(I + M) counts S @ theta for a body rotation
  theta, so a perfect calibration stores 1/S[0,0], 1/S[2,2], S[1,0], S[2,0],
  S[1,2], S[0,2] (:func:`allsky.hardware.gyro.perfect_calibration`).
* Mode 6-2, each cycle: (1) corrections = latest corrected roll/yaw x the
  stored factors; (2) intermediate = counter - corrections into that axis;
  (3) corrected = intermediate x scale factor; (4) errors = programmed -
  corrected, pitch error = -intermediate pitch. A hand-worked example with
  dyadic numbers is checked exactly.
* With counts made by such a triad from true angles (roll phi, pitch 0,
  yaw psi) the corrected angles are the true ones and the pitch error is 0:
  the fixed point of steps 1-3 is phi' = (S00 phi + S02 psi - S02 psi')/S00
  = phi when psi' = psi, and likewise for yaw and pitch.
"""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from allsky.computer import cpu
from allsky.computer import word_registers as wr
from allsky.hardware import gyro

FULL_TURN_ARCSEC = 1_296_000.0  # 360 deg
PULSE_WEIGHT_ARCSEC = 0.1  # scenario default

# A deliberately poor triad: thousands of ppm and 1000" of misalignment.
GYRO = gyro.make_params(
    drift_deg_h=[0.0, 0.0, 0.0],
    scale_factor_error_ppm=[3000.0, -2000.0, 1500.0],
    misalignment_arcsec=[[0.0, 300.0, -1000.0], [800.0, 0.0, 600.0], [-700.0, 400.0, 0.0]],
    arw_deg_rt_h=0.0, rrw_deg_h_rt_h=0.0, range_deg_s=10.0)
S = GYRO.sensitivity


def counts_arcsec(angles_arcsec, s=S):
    """What counters 14/16/18 hold [arcsec] after a body rotation of ``angles_arcsec``."""
    return s @ np.asarray(angles_arcsec, dtype=float)


def calibrated(s=S, roll_sign=1.0, yaw_sign=1.0):
    """Register 23 after synthetic Modes 4 and 5 (full turns, perfect counters)."""
    w = wr.neutral_computed()
    phi, psi = roll_sign * FULL_TURN_ARCSEC, yaw_sign * FULL_TURN_ARCSEC
    cpu.calibrate_roll(w, counts_arcsec([phi, 0, 0], s), phi)
    cpu.calibrate_yaw(w, counts_arcsec([0, 0, psi], s), psi)
    return w


def assert_matches_perfect(w, params, rel=1e-13):
    truth = gyro.perfect_calibration(params)
    got = wr.computed_as_dict(w)
    for part in ("scale_factor", "cross_coupling"):
        assert got[part].keys() == truth[part].keys()
        for k, v in truth[part].items():
            assert got[part][k] == pytest.approx(v, rel=rel, abs=1e-18), (part, k)


@pytest.mark.parametrize("roll_sign, yaw_sign", [(1, 1), (-1, 1), (1, -1)])
def test_register_23_equals_perfect_calibration(roll_sign, yaw_sign):
    assert_matches_perfect(calibrated(roll_sign=roll_sign, yaw_sign=yaw_sign), GYRO)


def test_scale_factor_and_coupling_by_hand():
    """1 296 000" true, 1 300 000" counted: SF = 0.996923...; 6480" on another axis: 0.005."""
    assert cpu.scale_factor(FULL_TURN_ARCSEC, 1_300_000.0) == FULL_TURN_ARCSEC / 1_300_000.0
    assert cpu.cross_coupling(6480.0, FULL_TURN_ARCSEC) == 0.005
    with pytest.raises(ZeroDivisionError):
        cpu.scale_factor(FULL_TURN_ARCSEC, 0.0)


def test_pulse_quantised_counts_calibrate_to_half_a_pulse():
    """Counters hold whole pulses: errors at most 0.5 pulse / 360 deg (3.9e-8)."""
    w = wr.neutral_computed()
    q = np.round(counts_arcsec([FULL_TURN_ARCSEC, 0, 0]) / PULSE_WEIGHT_ARCSEC) \
        * PULSE_WEIGHT_ARCSEC
    cpu.calibrate_roll(w, q, FULL_TURN_ARCSEC)
    bound = 0.5 * PULSE_WEIGHT_ARCSEC / FULL_TURN_ARCSEC * 1.001
    assert abs(w[wr.SF_ROLL] - 1.0 / S[0, 0]) <= bound
    assert abs(w[wr.ROLL_INTO_PITCH] - S[1, 0]) <= bound
    assert abs(w[wr.ROLL_INTO_YAW] - S[2, 0]) <= bound


small = st.floats(-0.01, 0.01, allow_nan=False)


@settings(deadline=None)
@given(sf=st.lists(small, min_size=3, max_size=3), m=st.lists(small, min_size=9, max_size=9))
def test_any_triad_calibrates_to_its_perfect_values(sf, m):
    mis = np.array(m).reshape(3, 3)
    np.fill_diagonal(mis, 0.0)
    s = np.diag(1.0 + np.array(sf)) @ (np.eye(3) + mis)
    params = GYRO._replace(sensitivity=s)
    assert_matches_perfect(calibrated(s), params, rel=1e-12)


# ----- Mode 6-2 arithmetic, by hand ---------------------------------------------------------

def hand_registers():
    w23 = np.zeros(wr.N_COMPUTED)
    w23[wr.SF_ROLL], w23[wr.SF_YAW] = 1.25, 0.75
    w23[wr.ROLL_INTO_PITCH], w23[wr.ROLL_INTO_YAW] = 0.125, 0.25
    w23[wr.YAW_INTO_PITCH], w23[wr.YAW_INTO_ROLL] = 0.0625, 0.5
    w24 = np.zeros(wr.N_PROGRAMMED)
    w24[wr.PROGRAMMED_ROLL], w24[wr.PROGRAMMED_YAW] = 1000.0, 200.0
    return w23, w24


COUNTERS = {0: 800.0, 1: 300.0, 2: 400.0}  # [arcsec], held fixed for the example


def test_target_step_by_hand():
    """Two cycles roll, pitch, yaw; every number below is worked by hand (dyadic, exact).

    Cycle 1 (work store empty):
      roll : 800 - 0.5 x 0 = 800;  x 1.25 = 1000;  error 1000 - 1000 = 0
      pitch: 300 - 0.0625 x 0 - 0.125 x 1000 = 175;  error -175
      yaw  : 400 - 0.25 x 1000 = 150;  x 0.75 = 112.5;  error 200 - 112.5 = 87.5
    Cycle 2:
      roll : 800 - 0.5 x 112.5 = 743.75;  x 1.25 = 929.6875;  error 70.3125
      pitch: 300 - 0.0625 x 112.5 - 0.125 x 929.6875 = 176.7578125;  error -176.7578125
      yaw  : 400 - 0.25 x 929.6875 = 167.578125;  x 0.75 = 125.68359375;  error 74.31640625
    """
    w23, w24 = hand_registers()
    work = np.zeros(cpu.N_WORK)
    expected = [
        (1000.0, 0.0, 175.0, -175.0, 112.5, 87.5),
        (929.6875, 70.3125, 176.7578125, -176.7578125, 125.68359375, 74.31640625),
    ]
    for phi, e_roll, pitch, e_pitch, psi, e_yaw in expected:
        assert cpu.target_step(0, COUNTERS[0], w23, w24, work) == e_roll
        assert work[cpu.CORRECTED_ROLL] == phi and work[cpu.ERROR_ROLL] == e_roll
        assert cpu.target_step(1, COUNTERS[1], w23, w24, work) == e_pitch
        assert work[cpu.INTERMEDIATE_PITCH] == pitch and work[cpu.ERROR_PITCH] == e_pitch
        assert cpu.target_step(2, COUNTERS[2], w23, w24, work) == e_yaw
        assert work[cpu.CORRECTED_YAW] == psi and work[cpu.ERROR_YAW] == e_yaw


def test_cycles_converge_to_the_closed_form_fixed_point():
    """phi = 1.25 (800 - 0.5 psi), psi = 0.75 (400 - 0.25 phi)
    => phi = 812.5 / 0.8828125, psi = 300 - 0.1875 phi."""
    w23, w24 = hand_registers()
    work = np.zeros(cpu.N_WORK)
    for _ in range(40):
        for axis in range(3):
            cpu.target_step(axis, COUNTERS[axis], w23, w24, work)
    phi = 812.5 / 0.8828125
    psi = 300.0 - 0.1875 * phi
    assert work[cpu.CORRECTED_ROLL] == pytest.approx(phi, rel=1e-14)
    assert work[cpu.CORRECTED_YAW] == pytest.approx(psi, rel=1e-14)
    assert work[cpu.INTERMEDIATE_PITCH] == pytest.approx(300 - 0.0625 * psi - 0.125 * phi,
                                                         rel=1e-14)


# ----- Mode 6-1 -> 6-2 hand-over ---------------------------------------------------------------

finite = {"allow_nan": False, "allow_infinity": False}


@settings(deadline=None)
@given(factors=st.lists(st.floats(-0.05, 0.05, **finite), min_size=4, max_size=4),
       sfs=st.lists(st.floats(0.9, 1.1, **finite), min_size=2, max_size=2),
       roll_counter=st.floats(-6.5e5, 6.5e5, **finite),
       programmed_yaw=st.floats(-6.5e5, 6.5e5, **finite),
       pitch_first=st.booleans())
def test_preset_makes_pitch_and_yaw_start_6_2_at_exactly_zero(factors, sfs, roll_counter,
                                                              programmed_yaw, pitch_first):
    w23 = np.zeros(wr.N_COMPUTED)
    w23[wr.SF_ROLL], w23[wr.SF_YAW] = sfs
    (w23[wr.ROLL_INTO_PITCH], w23[wr.ROLL_INTO_YAW],
     w23[wr.YAW_INTO_PITCH], w23[wr.YAW_INTO_ROLL]) = factors
    w24 = np.array([0.0, programmed_yaw])
    work = np.zeros(cpu.N_WORK)
    cpu.target_step(0, roll_counter, w23, w24, work)  # Mode 6-1 services roll only
    pitch_preset, yaw_preset = cpu.mode6_preset_arcsec(w23, work)
    order = [(1, pitch_preset), (2, yaw_preset)]
    for axis, counter in order if pitch_first else order[::-1]:
        cpu.target_step(axis, counter, w23, w24, work)
    assert work[cpu.INTERMEDIATE_PITCH] == 0.0 and work[cpu.ERROR_PITCH] == 0.0
    assert work[cpu.CORRECTED_YAW] == 0.0
    assert work[cpu.ERROR_YAW] == programmed_yaw


@pytest.mark.parametrize("phi_deg, psi_deg", [(30.0, -45.0), (-120.0, 170.0), (5.0, 0.5)])
def test_consistent_gyro_gives_true_angles_through_modes_6_1_and_6_2(phi_deg, psi_deg):
    """Counts generated from true angles through S (roll phi, then yaw psi, pitch held 0)."""
    phi, psi = phi_deg * 3600.0, psi_deg * 3600.0
    w23 = calibrated()
    w24 = np.array([phi, psi])
    work = np.zeros(cpu.N_WORK)
    steps = 60
    # Mode 6-1: roll through phi; the Sun holds true pitch and yaw at zero.
    for k in range(1, steps + 1):
        cpu.target_step(0, counts_arcsec([phi * k / steps, 0, 0])[0], w23, w24, work)
    assert work[cpu.CORRECTED_ROLL] == pytest.approx(phi, rel=1e-12)
    assert work[cpu.ERROR_ROLL] == pytest.approx(0.0, abs=1e-6)
    # Preset = what the pitch and yaw counters of a consistent triad already hold.
    preset = np.array(cpu.mode6_preset_arcsec(w23, work))
    np.testing.assert_allclose(preset, counts_arcsec([phi, 0, 0])[1:], rtol=1e-12)
    counters = np.array([counts_arcsec([phi, 0, 0])[0], *preset])
    # Mode 6-2: yaw through psi, the computer cycling roll, pitch, yaw each step.
    for k in range(1, steps + 1):
        now = counters + counts_arcsec([0, 0, psi * k / steps])
        for axis in range(3):
            cpu.target_step(axis, now[axis], w23, w24, work)
    for _ in range(3):  # on target: the cycles settle the last step's coupling lag
        for axis in range(3):
            cpu.target_step(axis, now[axis], w23, w24, work)
    assert work[cpu.CORRECTED_ROLL] == pytest.approx(phi, rel=1e-12, abs=1e-6)
    assert work[cpu.CORRECTED_YAW] == pytest.approx(psi, rel=1e-12, abs=1e-6)
    assert work[cpu.ERROR_PITCH] == pytest.approx(0.0, abs=1e-6)
    assert work[cpu.ERROR_ROLL] == pytest.approx(0.0, abs=1e-6)
    assert work[cpu.ERROR_YAW] == pytest.approx(0.0, abs=1e-6)


def test_uncorrected_counts_would_miss_by_the_gyro_errors():
    """Control: neutral register 23 on the same counts leaves errors of the gyro's size."""
    phi, psi = 30.0 * 3600.0, -45.0 * 3600.0
    w23 = wr.neutral_computed()
    work = np.zeros(cpu.N_WORK)
    now = counts_arcsec([phi, 0, psi])
    for _ in range(3):
        for axis in range(3):
            cpu.target_step(axis, now[axis], w23, np.array([phi, psi]), work)
    # roll error = phi - (S00 phi + S02 psi): about 0.3% of 30 deg plus 1000" x 45 deg.
    assert work[cpu.ERROR_ROLL] == pytest.approx(phi - (S[0, 0] * phi + S[0, 2] * psi))
    assert abs(work[cpu.ERROR_ROLL]) > 100.0
