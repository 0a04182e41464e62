"""Loop margins against closed forms, and the default scenario's loops.

Truth, per axis: for L(s) = (kp + kd s)/(J s^2) the gain crossover solves
J^2 w^4 = kp^2 + kd^2 w^2, the phase margin is atan(kd w_gc / kp), the phase
never reaches -180 deg (infinite gain margin), and the -3 dB closed-loop
bandwidth solves g J^2 w^4 + ((g - 1) kd^2 - 2 g kp J) w^2 + (g - 1) kp^2 = 0
(from |T|^2 = g = 10^(-3/10) with T = L/(1+L)); for L(s) = k e^{-Ts}/(J s): w_gc = k/J,
PM = 90 deg - w_gc T, and the phase crosses -180 deg at w T = pi/2 with gain
margin J pi / (2 T k). (Franklin, Powell & Emami-Naeini, *Feedback Control
of Dynamic Systems*, ch. 6.) With a diagonal inertia tensor the loop is the
product C(s) K_a lag delay / (J_ii s^2), written out here with
control.tf.

Truth, three axes: near rest the angles obey phi = G(s) tau with
G = J^-1 / s^2 (Euler's equations linearised). Each axis feeds back
tau_j = -K_j(s) phi_j. Cutting axis i at its torque input with the others
closed (M = diag(K) with M_ii = 0): phi = (I + G M)^-1 G e_i tau_i, so
L_i(s) = K_i(s) [(I + G M)^-1 G]_ii, evaluated here with numpy.
"""

import math

import control
import numpy as np
import pytest

from allsky.hardware.jets import make_params as make_jet_params
from allsky.studies.analysis import (
    AXES,
    PADE_ORDER,
    loop_margins,
    loop_transfer,
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
    for kind in ("position", "rate"):
        for axis, r in m[kind].items():
            assert r["stable"], (kind, axis)
            assert r["gain_margin_db"] > 0.0, (kind, axis)
            assert r["phase_margin_deg"] > 0.0, (kind, axis)
            assert 0.0 < r["crossover_rad_s"] < r["phase_crossover_rad_s"]


# -- the three-axis loops against the per-axis and three-axis closed forms ---------------

def axis_controller(a, i, s, rate_commanded=False, delay=None):
    """K_i(s) [N m/rad]: amplifier (V/rad), describing gain, lag and frame delay of axis i."""
    kp = 0.0 if rate_commanded else a["position_gain_v_per_arcsec"][i] * RAD2ARCSEC
    kd = a["rate_gain_v_per_arcsec_s"][i] * RAD2ARCSEC
    if delay is None:
        num, den = control.pade(a["frame_s"], PADE_ORDER)
        delay = np.polyval(num, s) / np.polyval(den, s)
    ka = a["torque_n_m"][i] / a["full_on_v"]
    return (kp + kd * s) * ka / (a["pwpf_time_constant_s"] * s + 1.0) * delay


def textbook_loop(a, i, rate_commanded=False):
    """The per-axis loop C(s) K_a lag delay / (J_ii s^2), built as a product of control.tf.

    Rate-commanded: C(s) = RAD2ARCSEC Kd s, written as RAD2ARCSEC Kd / (J_ii s).
    """
    kd = a["rate_gain_v_per_arcsec_s"][i] * RAD2ARCSEC
    if rate_commanded:
        c, plant = control.tf([kd], [1.0]), control.tf([1.0], [a["inertia_kg_m2"][i, i], 0.0])
    else:
        c = control.tf([kd, a["position_gain_v_per_arcsec"][i] * RAD2ARCSEC], [1.0])
        plant = control.tf([1.0], [a["inertia_kg_m2"][i, i], 0.0, 0.0])
    num, den = control.pade(a["frame_s"], PADE_ORDER)
    return (c * (a["torque_n_m"][i] / a["full_on_v"])
            * control.tf([1.0], [a["pwpf_time_constant_s"], 1.0]) * control.tf(num, den) * plant)


def three_axis_loop(a, i, s, rate_commanded=False, delay=None):
    """L_i(s) = K_i [(I + G M)^-1 G]_ii with G = J^-1 / s^2, the other axes closed."""
    g = np.linalg.inv(a["inertia_kg_m2"]) / s**2
    k = [axis_controller(a, j, s, rate_commanded and j == i, delay) for j in range(3)]
    m = np.diag([0.0 if j == i else k[j] for j in range(3)])
    return k[i] * np.linalg.solve(np.eye(3) + g @ m, g)[i, i]


@pytest.fixture(scope="module")
def diagonal_args(default_args):
    return {**default_args, "inertia_kg_m2": np.diag(np.diag(default_args["inertia_kg_m2"]))}


@pytest.fixture(scope="module")
def default_margins(default_args):
    return loop_margins(**default_args)


LOOPS = [("position", 0), ("position", 1), ("position", 2), ("rate", 0), ("rate", 2)]


@pytest.mark.parametrize("kind, i", LOOPS)
def test_diagonal_inertia_gives_the_per_axis_margins(diagonal_args, kind, i):
    # The vehicle's nlsys, linearised and interconnected, equals the textbook
    # product when nothing couples the axes. Measured: 3e-13 relative.
    m = loop_margins(**diagonal_args)[kind][AXES[i]]
    gm, pm, _, w_pc, w_gc, _ = control.stability_margins(
        textbook_loop(diagonal_args, i, kind == "rate"))
    assert m["gain_margin_db"] == pytest.approx(20.0 * math.log10(gm), rel=1e-9)
    assert m["phase_margin_deg"] == pytest.approx(pm, rel=1e-9)
    assert m["crossover_rad_s"] == pytest.approx(w_gc, rel=1e-9)
    assert m["phase_crossover_rad_s"] == pytest.approx(w_pc, rel=1e-9)


@pytest.mark.parametrize("kind, i", LOOPS)
def test_diagonal_inertia_loop_has_only_its_own_axis_states(diagonal_args, kind, i):
    loop = loop_transfer(**diagonal_args, axis=i, rate_commanded=kind == "rate")
    # Position: angle, rate, lag, 3 Pade states; rate: the angle is not fed back.
    assert loop.nstates == (6 if kind == "position" else 5)
    axis = "xyz"[i]
    own = (f"vehicle_phi_{axis}", f"vehicle_w_{axis}", f"modulator_{34 + i}_", f"frame_{axis}_")
    assert all(name.startswith(own) for name in loop.state_labels), loop.state_labels


@pytest.mark.parametrize("kind, i", LOOPS)
def test_coupled_loop_is_the_three_axis_closed_form(default_args, kind, i):
    loop = loop_transfer(**default_args, axis=i, rate_commanded=kind == "rate")
    assert loop.nstates == (18 if kind == "position" else 17)
    for w_rad_s in (0.3, 3.0, 14.0, 30.0, 100.0):
        s = 1j * w_rad_s
        # The numerical linearisation leaves ~2e-8 1/s of the gyroscopic term;
        # measured 2e-11 relative.
        assert complex(loop(s)) == pytest.approx(
            three_axis_loop(default_args, i, s, kind == "rate"), rel=1e-9)


@pytest.mark.parametrize("kind, i", LOOPS)
def test_default_crossover_satisfies_the_closed_form_with_the_exact_delay(default_args,
                                                                          default_margins,
                                                                          kind, i):
    # |L(j w_gc)| = 1 and the phase margin, written out with the exact delay
    # e^{-j w T} (the approximant's phase error at w T ~ 0.17 is ~1e-8 rad).
    m = default_margins[kind][AXES[i]]
    s = 1j * m["crossover_rad_s"]
    ell = three_axis_loop(default_args, i, s, kind == "rate",
                          delay=np.exp(-s * default_args["frame_s"]))
    assert abs(ell) == pytest.approx(1.0, rel=1e-6)
    assert m["phase_margin_deg"] == pytest.approx(180.0 + math.degrees(np.angle(ell)), abs=1e-4)


@pytest.mark.parametrize("kind, i", LOOPS)
def test_products_of_inertia_move_the_default_margins_little(default_args, diagonal_args,
                                                             default_margins, kind, i):
    # Coupling 0.2-1.5 % (J_xy = 1.5, J_xz = -1, J_yz = 2 kg m^2): measured
    # -0.0003 to -0.0006 dB and +0.003 to +0.006 deg against the diagonal tensor.
    coupled = default_margins[kind][AXES[i]]
    alone = loop_margins(**diagonal_args)[kind][AXES[i]]
    d_gm = coupled["gain_margin_db"] - alone["gain_margin_db"]
    d_pm = coupled["phase_margin_deg"] - alone["phase_margin_deg"]
    assert 1e-5 < abs(d_gm) < 0.01
    assert 1e-4 < abs(d_pm) < 0.01
