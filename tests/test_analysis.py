"""Loop margins against closed forms, and the default scenario's loops.

Truth: for L(s) = (kp + kd s)/(J s^2) the gain crossover solves
J^2 w^4 = kp^2 + kd^2 w^2, the phase margin is atan(kd w_gc / kp), the phase
never reaches -180 deg (infinite gain margin), and the -3 dB closed-loop
bandwidth solves g J^2 w^4 + ((g - 1) kd^2 - 2 g kp J) w^2 + (g - 1) kp^2 = 0
(from |T|^2 = g = 10^(-3/10) with T = L/(1+L)); for L(s) = k e^{-Ts}/(J s): w_gc = k/J,
PM = 90 deg - w_gc T, and the phase crosses -180 deg at w T = pi/2 with gain
margin J pi / (2 T k). (Franklin, Powell & Emami-Naeini, *Feedback Control
of Dynamic Systems*, ch. 6.)
"""

import math

import numpy as np
import pytest

from allsky.hardware.jets import make_params as make_jet_params
from allsky.studies.analysis import (
    AXES,
    format_margins,
    loop_margins,
    position_loop,
    scenario_loop_arguments,
)
from allsky.units import RAD2ARCSEC

J_KG_M2 = np.array([100.0, 650.0, 680.0])
TORQUE_N_M = np.array([0.25, 1.25, 1.25])
FULL_ON_V = 0.008
KP_V_PER_ARCSEC = np.array([1e-3, 2e-3, 5e-4])
KD_V_PER_ARCSEC_S = np.array([5e-4, 1e-3, 1e-3])


def textbook(i):
    """(kp [N m/rad], kd [N m s/rad], J) of axis i in plain loop units."""
    ka = TORQUE_N_M[i] / FULL_ON_V
    return KP_V_PER_ARCSEC[i] * RAD2ARCSEC * ka, KD_V_PER_ARCSEC_S[i] * RAD2ARCSEC * ka, J_KG_M2[i]


@pytest.fixture(scope="module")
def pure_pd():
    return loop_margins(np.diag(J_KG_M2), TORQUE_N_M, FULL_ON_V, 0.0, KP_V_PER_ARCSEC,
                        KD_V_PER_ARCSEC_S, 0.0)


@pytest.mark.parametrize("i", [0, 1, 2])
def test_pure_pd_on_a_double_integrator_matches_closed_form(pure_pd, i):
    kp, kd, j = textbook(i)
    w_gc = math.sqrt((kd**2 + math.sqrt(kd**4 + 4.0 * j**2 * kp**2)) / (2.0 * j**2))
    g = 10.0 ** (-3.0 / 10.0)  # |T|^2 at -3 dB, as control.bandwidth defines it
    qa, qb, qc = g * j**2, (g - 1.0) * kd**2 - 2.0 * g * kp * j, (g - 1.0) * kp**2
    w_bw = math.sqrt((-qb + math.sqrt(qb**2 - 4.0 * qa * qc)) / (2.0 * qa))
    m = pure_pd["position"][AXES[i]]
    assert m["crossover_rad_s"] == pytest.approx(w_gc, rel=1e-9)
    assert m["phase_margin_deg"] == pytest.approx(math.degrees(math.atan(kd * w_gc / kp)),
                                                  rel=1e-9)
    assert m["gain_margin_db"] == math.inf
    assert math.isnan(m["phase_crossover_rad_s"])
    assert m["bandwidth_rad_s"] == pytest.approx(w_bw, rel=1e-6)
    assert m["stable"]
    # Diagonal tensor: no coupling, the effective inertia is J_ii.
    assert m["coupling_ratio"] == 0.0
    assert m["effective_inertia_kg_m2"] == pytest.approx(j, rel=1e-12)


@pytest.mark.parametrize("i", [0, 2])
def test_rate_loop_with_one_frame_delay_matches_closed_form(i):
    frame_s = 0.01
    m = loop_margins(np.diag(J_KG_M2), TORQUE_N_M, FULL_ON_V, 0.0, KP_V_PER_ARCSEC,
                     KD_V_PER_ARCSEC_S, frame_s)["rate"][AXES[i]]
    _, k, j = textbook(i)
    w_gc = k / j  # the Pade approximant is all-pass: the delay leaves |L| alone
    assert m["crossover_rad_s"] == pytest.approx(w_gc, rel=1e-9)
    assert m["phase_margin_deg"] == pytest.approx(90.0 - math.degrees(w_gc * frame_s), abs=1e-3)
    w_pc = math.pi / (2.0 * frame_s)
    # The 3rd-order Pade approximant's phase is ~0.4% short at w T = pi/2.
    assert m["phase_crossover_rad_s"] == pytest.approx(w_pc, rel=1e-2)
    assert m["gain_margin_db"] == pytest.approx(20.0 * math.log10(j * w_pc / k), abs=0.1)


def test_pitch_has_no_rate_command_loop(pure_pd):
    assert set(pure_pd["rate"]) == {"roll", "yaw"}


def test_coupling_ratio_of_products_of_inertia():
    j = np.array([[100.0, 1.5, -1.0], [1.5, 650.0, 2.0], [-1.0, 2.0, 680.0]])
    m = loop_margins(j, TORQUE_N_M, FULL_ON_V, 0.0, KP_V_PER_ARCSEC, KD_V_PER_ARCSEC_S, 0.0)
    j_inv = np.linalg.inv(j)
    # Pitch: a roll torque accelerates pitch by -J_xy/(J_xx J_yy) to first order,
    # i.e. 1.5/100 = 1.5 % of a pitch torque's effect.
    assert m["position"]["pitch"]["coupling_ratio"] == pytest.approx(
        abs(j_inv[1, 0]) / j_inv[1, 1], rel=1e-12)
    assert m["position"]["pitch"]["coupling_ratio"] == pytest.approx(0.015, rel=0.01)


@pytest.fixture(scope="module")
def default_args(default_cfg):
    return scenario_loop_arguments(default_cfg)


def test_scenario_torque_is_the_jet_couple(default_cfg, default_args):
    jets = make_jet_params(default_cfg.jets.thrust_n, default_cfg.jets.moment_arm_m,
                           default_cfg.jets.isp_s)
    np.testing.assert_array_equal(default_args["torque_n_m"], jets.torque_n_m)


def test_default_scenario_loops_have_positive_margins(default_args):
    m = loop_margins(**default_args)
    table = format_margins(m)
    print("\n" + table)
    for kind in ("position", "rate"):
        for axis, r in m[kind].items():
            assert r["stable"], (kind, axis)
            assert r["gain_margin_db"] > 0.0, (kind, axis)
            assert r["phase_margin_deg"] > 0.0, (kind, axis)
            assert 0.0 < r["crossover_rad_s"] < r["phase_crossover_rad_s"]
    assert len(table.splitlines()) == 2 + 3 + 2


@pytest.mark.parametrize("i", [0, 1, 2])
def test_default_position_loop_crossover_satisfies_the_full_closed_form(default_args, i):
    # |L(j w_gc)| = 1 and the phase margin, written out with the exact delay
    # e^{-j w T} (the approximant's phase error at w T ~ 0.17 is ~1e-8 rad).
    a = default_args
    m = loop_margins(**a)["position"][AXES[i]]
    w = m["crossover_rad_s"]
    ka = a["torque_n_m"][i] / a["full_on_v"]
    kp = a["position_gain_v_per_arcsec"][i] * RAD2ARCSEC
    kd = a["rate_gain_v_per_arcsec_s"][i] * RAD2ARCSEC
    tau, t, j = a["pwpf_time_constant_s"], a["frame_s"], a["inertia_kg_m2"][i, i]
    s = 1j * w
    ell = (kp + kd * s) * ka / (tau * s + 1.0) * np.exp(-s * t) / (j * s**2)
    assert abs(ell) == pytest.approx(1.0, rel=1e-6)
    assert m["phase_margin_deg"] == pytest.approx(180.0 + math.degrees(np.angle(ell)), abs=1e-4)
    # And the transfer function itself evaluates to the same number.
    lt = position_loop(j, a["torque_n_m"][i], a["full_on_v"], tau,
                       a["position_gain_v_per_arcsec"][i], a["rate_gain_v_per_arcsec_s"][i], t)
    assert lt(s) == pytest.approx(ell, rel=1e-6)
