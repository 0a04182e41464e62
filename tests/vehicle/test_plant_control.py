"""The python-control model of the plant against the compiled core and against physics.

Truth: the closed loop integrated by scipy's DOP853 at rtol = atol = 1e-12
(through :func:`control.input_output_response`); Euler's equations and the
quaternion kinematics written out independently here with numpy; the
conservation of inertial angular momentum and of kinetic energy without
torque; the Jacobian of those equations at rest, written out by hand
(d q_vec/dt = w/2, d w/dt = J^-1 tau, the gyroscopic term quadratic in w),
hence the double integrator 1/(J s^2) of a rigid body near rest.
"""

import math

import control
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from allsky.jit import njit, njit_alloc
from allsky.vehicle import quaternion as quat
from allsky.vehicle.plant import (
    N_INTEGRATED,
    angular_momentum_inertial,
    derivatives,
    kinetic_energy_j,
    make_params,
    rk4_step,
)
from allsky.vehicle.plant_control import (
    INPUT_NAMES,
    LINEAR_STATE_NAMES,
    STATE_NAMES,
    linearize,
    operating_point,
    vehicle_nlsys,
)

# [kg m^2] the default scenario's tensor, products of inertia included.
INERTIA_KG_M2 = np.array([[100.0, 1.5, -1.0], [1.5, 650.0, 2.0], [-1.0, 2.0, 680.0]])
# Smooth PD attitude law tau = -Kp 2 q_vec sign(q_w) - Kd w: natural frequency
# 0.3 rad/s, damping 0.8 per axis on the diagonal inertia.
OMEGA_N_RAD_S, ZETA = 0.3, 0.8
KP_N_M_RAD = np.diag(INERTIA_KG_M2) * OMEGA_N_RAD_S**2
KD_N_M_S_RAD = 2.0 * ZETA * OMEGA_N_RAD_S * np.diag(INERTIA_KG_M2)
T_END_S = 60.0
IVP = {"solve_ivp_method": "DOP853", "solve_ivp_kwargs": {"rtol": 1e-12, "atol": 1e-12}}


def initial_state():
    """15 deg about a skew axis, with a small tumble [rad/s]."""
    q0 = quat.from_axis_angle([1.0, 2.0, -1.5], math.radians(15.0))
    return np.concatenate([q0, [0.01, -0.005, 0.008]])


def pd_law(x):
    s = 1.0 if x[0] >= 0.0 else -1.0
    return -KP_N_M_RAD * 2.0 * np.asarray(x[1:4]) * s - KD_N_M_S_RAD * np.asarray(x[4:7])


def angle_between_rad(q1, q2):
    """Rotation angle [rad] between two attitude quaternions (sign-insensitive)."""
    d = quat.multiply(np.array([q1[0], -q1[1], -q1[2], -q1[3]]), np.asarray(q2))
    return 2.0 * math.atan2(np.linalg.norm(d[1:]), abs(d[0]))


@pytest.fixture(scope="module")
def reference():
    """The closed loop built and integrated by python-control: (times [s], states (7, n))."""
    vehicle = vehicle_nlsys(INERTIA_KG_M2)
    controller = control.nlsys(None, lambda t, x, u, params: pd_law(u), inputs=list(STATE_NAMES),
                               outputs=list(INPUT_NAMES), name="pd")
    loop = control.interconnect([vehicle, controller], inplist=[],
                                outlist=[f"vehicle.{n}" for n in STATE_NAMES],
                                outputs=list(STATE_NAMES), name="closed_loop")
    t_s = np.linspace(0.0, T_END_S, 121)
    r = control.input_output_response(loop, t_s, 0.0, initial_state(), **IVP)
    assert r.success
    return t_s, r.outputs


@njit
def _closed_loop_derivatives(p, kp, kd, y, dy, tau):
    s = 1.0 if y[0] >= 0.0 else -1.0
    for i in range(3):
        tau[i] = -kp[i] * 2.0 * y[1 + i] * s - kd[i] * y[4 + i]
    derivatives(p, y, tau, dy)


@njit_alloc
def _closed_loop_rk4(p, kp, kd, x0, dt_s, n_steps, every, out):
    """Classical RK4 of the core's derivatives with the PD law inside them."""
    y = np.zeros(N_INTEGRATED)
    y[:7] = x0
    k1, k2, k3, k4 = np.empty(10), np.empty(10), np.empty(10), np.empty(10)
    tmp, tau = np.empty(10), np.empty(3)
    out[0, :] = y[:7]
    for k in range(n_steps):
        _closed_loop_derivatives(p, kp, kd, y, k1, tau)
        for i in range(10):
            tmp[i] = y[i] + 0.5 * dt_s * k1[i]
        _closed_loop_derivatives(p, kp, kd, tmp, k2, tau)
        for i in range(10):
            tmp[i] = y[i] + 0.5 * dt_s * k2[i]
        _closed_loop_derivatives(p, kp, kd, tmp, k3, tau)
        for i in range(10):
            tmp[i] = y[i] + dt_s * k3[i]
        _closed_loop_derivatives(p, kp, kd, tmp, k4, tau)
        for i in range(10):
            y[i] += dt_s / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
        if (k + 1) % every == 0:
            out[(k + 1) // every, :] = y[:7]


def test_closed_loop_core_derivatives_agree_with_input_output_response(reference):
    # The torque held over a step (rk4_step, as the jets do) makes the core a
    # first-order method for a continuous law (next test); with the law inside
    # the derivative the RK4 error at 0.01 s is far below the reference's
    # tolerance. Measured: 1.4e-11 rad (dt 0.01 s and 0.001 s alike).
    t_s, ref = reference
    dt_s = 0.01
    every = round((t_s[1] - t_s[0]) / dt_s)
    out = np.empty((t_s.size, 7))
    _closed_loop_rk4(make_params(INERTIA_KG_M2), KP_N_M_RAD, KD_N_M_S_RAD, initial_state(), dt_s,
                     every * (t_s.size - 1), every, out)
    err_rad = max(angle_between_rad(out[i, :4], ref[:4, i]) for i in range(t_s.size))
    assert err_rad <= 1e-9
    assert np.max(np.abs(out[:, 4:].T - ref[4:])) <= 1e-9  # [rad/s]
    # The case is not trivial: it turns 15 deg and settles.
    assert angle_between_rad(ref[:4, 0], ref[:4, -1]) > math.radians(14.0)


def core_zoh_error_rad(reference, dt_s):
    """Largest attitude difference of rk4_step (law evaluated once a step, torque held)."""
    t_s, ref = reference
    p = make_params(INERTIA_KG_M2)
    x, dtheta = initial_state(), np.zeros(3)
    every = round((t_s[1] - t_s[0]) / dt_s)
    err = 0.0
    for k in range(every * (t_s.size - 1)):
        rk4_step(p, x, pd_law(x), dt_s, dtheta)
        if (k + 1) % every == 0:
            err = max(err, angle_between_rad(x[:4], ref[:4, (k + 1) // every]))
    return err


def test_core_rk4_step_with_held_torque_converges_at_first_order(reference):
    # Zero-order hold of a continuous law is an O(dt) error: measured 1.65e-4
    # rad at 0.01 s and 1.65e-5 rad at 0.001 s, so 1e-9 rad would need
    # dt ~ 1e-8 s; hence the law-inside-the-derivative comparison above.
    e1 = core_zoh_error_rad(reference, 0.01)
    e2 = core_zoh_error_rad(reference, 0.002)
    assert e1 < 3e-4
    assert e1 / e2 == pytest.approx(5.0, rel=0.05)


def test_torque_free_motion_conserves_momentum_and_energy():
    p = make_params(INERTIA_KG_M2)
    x0 = np.concatenate([quat.from_axis_angle([0.3, -1.0, 0.2], 1.0), [0.05, 0.02, -0.03]])
    t_s = np.linspace(0.0, 200.0, 201)
    r = control.input_output_response(vehicle_nlsys(INERTIA_KG_M2), t_s, 0.0, x0, **IVP)
    h0, e0 = angular_momentum_inertial(p, x0), kinetic_energy_j(p, x0)
    h = np.array([angular_momentum_inertial(p, x) for x in r.states.T])
    e = np.array([kinetic_energy_j(p, x) for x in r.states.T])
    assert np.max(np.linalg.norm(h - h0, axis=1)) <= 1e-9 * np.linalg.norm(h0)
    assert np.max(np.abs(e - e0)) <= 1e-9 * e0
    assert np.max(np.abs(np.linalg.norm(r.states[:4], axis=0) - 1.0)) <= 1e-10
    # Not trivially conserved: the body rate itself changes (it nutates).
    assert np.ptp(r.states[4]) > 1e-3


def textbook_derivative(inertia, x, u):
    """Euler's equations and quaternion kinematics written out with numpy."""
    q, w = np.asarray(x[:4]), np.asarray(x[4:])
    dq = 0.5 * quat.multiply(q, np.concatenate([[0.0], w]))
    dw = np.linalg.solve(inertia, u - np.cross(w, inertia @ w))
    return np.concatenate([dq, dw])


finite = st.floats(-1.0, 1.0, allow_nan=False)


@settings(max_examples=30, deadline=None)
@given(st.lists(finite, min_size=7, max_size=7), st.lists(finite, min_size=3, max_size=3),
       st.lists(st.floats(-0.3, 0.3), min_size=3, max_size=3))
def test_nlsys_right_hand_side_is_eulers_equations(x, u, products):
    # A tensor with products of inertia, kept positive definite.
    j = np.diag([100.0, 650.0, 680.0])
    j[0, 1] = j[1, 0] = products[0] * 100.0
    j[0, 2] = j[2, 0] = products[1] * 100.0
    j[1, 2] = j[2, 1] = products[2] * 650.0
    vehicle = vehicle_nlsys(j)
    # The equations hold for any quaternion, unit or not (they are bilinear).
    x, u = np.array(x), np.array(u)
    np.testing.assert_allclose(vehicle.dynamics(0.0, x, u), textbook_derivative(j, x, u),
                               rtol=1e-12, atol=1e-14)
    np.testing.assert_array_equal(vehicle.output(0.0, x, u), x)


def test_signal_names():
    vehicle = vehicle_nlsys(INERTIA_KG_M2, name="veh")
    assert vehicle.name == "veh"
    assert vehicle.state_labels == list(STATE_NAMES)
    assert vehicle.input_labels == ["tau_x", "tau_y", "tau_z"]
    assert vehicle.output_labels == list(STATE_NAMES)


def test_operating_point_is_an_equilibrium():
    op = operating_point()
    vehicle = vehicle_nlsys(INERTIA_KG_M2)
    np.testing.assert_array_equal(vehicle.dynamics(0.0, op.states, op.inputs), np.zeros(7))
    xeq, _ = control.find_operating_point(vehicle, op.states, op.inputs)
    np.testing.assert_allclose(xeq, op.states, atol=1e-12)


def test_quaternion_scalar_part_decouples_at_the_operating_point():
    # Why linearize() may drop q_w: its row and column of the nlsys's Jacobian
    # are exactly zero at the identity (d q_w/dt = -q_vec . w / 2 is second order).
    full = control.linearize(vehicle_nlsys(INERTIA_KG_M2), operating_point())
    assert not full.A[0, :].any() and not full.A[:, 0].any() and not full.B[0, :].any()


def test_linearisation_is_the_jacobian_at_rest_in_small_angles():
    lin = linearize(INERTIA_KG_M2)
    # By hand, states phi = 2 q_vec and w: d phi/dt = w, d w/dt = J^-1 tau.
    a = np.zeros((6, 6))
    a[:3, 3:] = np.eye(3)
    b = np.vstack([np.zeros((3, 3)), np.linalg.inv(INERTIA_KG_M2)])
    # Forward differences (step 1e-6) leave O(step) of the gyroscopic term:
    # 2e-8 1/s measured with these products of inertia.
    np.testing.assert_allclose(lin.A, a, rtol=0.0, atol=1e-7)
    np.testing.assert_array_equal(lin.A[:3], a[:3])
    np.testing.assert_allclose(lin.B, b, rtol=1e-9, atol=1e-15)
    np.testing.assert_array_equal(lin.C, np.eye(6))
    np.testing.assert_array_equal(lin.D, np.zeros((6, 3)))
    assert lin.state_labels == lin.output_labels == list(LINEAR_STATE_NAMES)
    assert lin.input_labels == list(INPUT_NAMES)


def test_small_angle_is_twice_the_quaternion_vector_part():
    # A small constant torque from rest: phi(t) = J^-1 tau t^2 / 2 for the
    # linearisation (up to its ~2e-8 1/s of gyroscopic residue over 2 s:
    # 9e-9 measured), and 2 q_vec of the nlsys to first order: the dropped
    # terms q_vec x w and w x (J w) are products of two small quantities,
    # relative size ~ the angle (2e-5 rad; 7.5e-6 measured).
    lin = linearize(INERTIA_KG_M2)
    t_s = np.linspace(0.0, 2.0, 21)
    tau_n_m = np.array([1e-3, -2e-3, 1.5e-3])
    u = np.tile(tau_n_m[:, None], t_s.size)
    angle_rad = np.linalg.solve(INERTIA_KG_M2, tau_n_m) * t_s[-1] ** 2 / 2.0
    nl = control.input_output_response(vehicle_nlsys(INERTIA_KG_M2), t_s, u,
                                       operating_point().states, **IVP)
    ln = control.input_output_response(lin, t_s, u, np.zeros(6))
    np.testing.assert_allclose(ln.outputs[:3, -1], angle_rad, rtol=1e-7)
    np.testing.assert_allclose(2.0 * nl.outputs[1:4, -1], angle_rad, rtol=2e-5)
    assert np.min(np.abs(angle_rad)) > 1e-6


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_linearisation_is_a_double_integrator_per_axis(axis):
    j_kg_m2 = np.array([100.0, 650.0, 680.0])
    lin = linearize(np.diag(j_kg_m2))
    # angle_i / tau_i = 1 / (J_ii s^2).
    g = control.minreal(control.tf(lin[axis, axis]), verbose=False)
    np.testing.assert_allclose(g.num[0][0], [1.0 / j_kg_m2[axis]], rtol=1e-12)
    np.testing.assert_allclose(g.den[0][0], [1.0, 0.0, 0.0], atol=1e-12)
    for w_rad_s in (0.01, 1.0, 30.0):
        assert lin[axis, axis](1j * w_rad_s) == pytest.approx(
            -1.0 / (j_kg_m2[axis] * w_rad_s**2), rel=1e-12)
    # No cross-axis path with a diagonal tensor: exactly, the gyroscopic term
    # e_j x (J e_j) of the forward difference vanishes too.
    for other in {0, 1, 2} - {axis}:
        assert lin[axis, other](1j) == 0.0
