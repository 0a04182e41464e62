"""Rigid-body plant (allsky.vehicle.plant) against the mechanics of a rigid body.

Truth:
- torque-free motion conserves the inertial angular momentum and the kinetic
  energy (Euler's equations; Goldstein, *Classical Mechanics*, 3rd ed., sec. 5.5);
- under a constant torque along a principal axis, from rest, the body spins
  about that fixed axis with w = tau/J t and turns through tau/(2J) t^2; RK4 is
  exact for these polynomials (degree <= 4), so only rounding remains;
- a spin about the axis of least or greatest inertia is stable, about the
  intermediate axis it diverges at the rate
  W sqrt((J3 - J2)(J2 - J1)/(J1 J3)) (linearised Euler equations; Landau &
  Lifshitz, *Mechanics*, sec. 37, problem 1; the Dzhanibekov effect).
"""

import math

import numba
import numpy as np
import pytest

from allsky.vehicle import quaternion
from allsky.vehicle.plant import angular_momentum_inertial, kinetic_energy_j, make_params, rk4_step

# [kg m^2] the default scenario's full tensor (src/allsky/scenarios/default.toml).
INERTIA_KG_M2 = [[100.0, 1.5, -1.0], [1.5, 650.0, 2.0], [-1.0, 2.0, 680.0]]
P = make_params(INERTIA_KG_M2)
# Principal moments (ascending) and axes (columns), body components.
J_PRINCIPAL, V_PRINCIPAL = np.linalg.eigh(np.array(INERTIA_KG_M2))


def fly(x0, torque_n_m, dt_s, n_steps, every=None):
    """Integrate n_steps; return final state, summed dtheta and optional samples of x."""
    x = np.array(x0, dtype=float)
    tq = np.asarray(torque_n_m, dtype=float)
    dth = np.zeros(3)
    total = np.zeros(3)
    samples = []
    for k in range(n_steps):
        rk4_step(P, x, tq, dt_s, dth)
        total += dth
        if every and (k + 1) % every == 0:
            samples.append(x.copy())
    return x, total, samples


def tumbling_state():
    q0 = quaternion.from_axis_angle([0.3, -0.5, 0.8], 1.1)
    return np.array([*q0, 0.3, 0.1, -0.2])  # [rad/s] a general tumble, not about a principal axis


def test_torque_free_motion_conserves_momentum_energy_and_norm():
    x0 = tumbling_state()
    h0 = angular_momentum_inertial(P, x0)
    e0 = kinetic_energy_j(P, x0)
    # 100 s at the mission's 0.01 s frame.
    x, _, samples = fly(x0, np.zeros(3), 0.01, 10_000, every=500)
    for xs in samples + [x]:
        h = angular_momentum_inertial(P, xs)
        assert np.linalg.norm(h - h0) / np.linalg.norm(h0) < 1e-10
        assert abs(kinetic_energy_j(P, xs) - e0) / e0 < 1e-10
        assert abs(np.linalg.norm(xs[0:4]) - 1.0) < 1e-14
    # The motion is a real tumble: the body rate changed a lot while h stayed put.
    assert np.linalg.norm(x[4:7] - x0[4:7]) > 0.05


def test_kinetic_energy_and_momentum_helpers_closed_form():
    # Rest frame = inertial frame (identity quaternion): h = J w, T = w.J.w / 2.
    w = np.array([0.1, -0.2, 0.05])
    x = np.array([1.0, 0.0, 0.0, 0.0, *w])
    j = np.array(INERTIA_KG_M2)
    assert np.allclose(angular_momentum_inertial(P, x), j @ w, rtol=1e-15, atol=0)
    assert kinetic_energy_j(P, x) == pytest.approx(0.5 * w @ j @ w, rel=1e-15)


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_constant_torque_about_a_principal_axis_from_rest(axis):
    v = V_PRINCIPAL[:, axis]
    j = J_PRINCIPAL[axis]
    tau = 2.0  # [N m]
    dt, n = 0.01, 1000
    t = n * dt
    x0 = [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
    x, total, _ = fly(x0, tau * v, dt, n)
    # w = tau/J t; angle = tau/(2J) t^2 (Goldstein 5.5 with w x Jw = 0 on a principal axis).
    assert np.allclose(x[4:7], tau / j * t * v, rtol=0, atol=1e-13 * tau / j * t)
    angle = tau / (2.0 * j) * t * t
    assert np.allclose(total, angle * v, rtol=0, atol=1e-12 * angle)
    # The attitude is the rotation through that angle about the fixed axis.
    q_true = quaternion.from_axis_angle(v, angle)
    assert np.allclose(x[0:4], q_true, rtol=0, atol=1e-10)


def test_dtheta_is_the_integral_of_the_rate_over_each_frame():
    # Constant torque on the major axis from a spin w0: w(t) = w0 + a t, so a frame
    # [t, t+dt] turns through w(t) dt + a dt^2/2 (exact for RK4: a polynomial).
    v = V_PRINCIPAL[:, 2]
    a = 0.5 / J_PRINCIPAL[2]  # [rad/s^2]
    w0 = 0.02  # [rad/s]
    x = np.array([1.0, 0.0, 0.0, 0.0, *(w0 * v)])
    dth = np.zeros(3)
    dt = 0.01
    for k in range(200):
        t = k * dt
        rk4_step(P, x, 0.5 * v, dt, dth)
        expected = ((w0 + a * t) * dt + 0.5 * a * dt * dt) * v
        assert np.allclose(dth, expected, rtol=0, atol=1e-16)


def test_dtheta_of_a_torque_free_tumble_is_simpsons_integral_of_the_rate():
    # Off the principal axes the rate changes within the frame. Simpson's rule
    # over the rates at the start, middle and end of the frame is exact to
    # O(dt^5) (Abramowitz & Stegun 25.4.5): at dt = 1 ms, below 1e-17 rad here.
    dt = 1e-3
    x = tumbling_state()
    w0 = x[4:7].copy()
    half = x.copy()
    rk4_step(P, half, np.zeros(3), 0.5 * dt, np.zeros(3))
    dth = np.zeros(3)
    rk4_step(P, x, np.zeros(3), dt, dth)
    simpson = dt / 6.0 * (w0 + 4.0 * half[4:7] + x[4:7])
    assert np.allclose(dth, simpson, rtol=0, atol=1e-16)
    # ... and the rate really did change: a constant-rate guess is far off.
    assert not np.allclose(dth, w0 * dt, rtol=0, atol=1e-9)


def spin_perturbation(axis, rate_rad_s=1.0, eps=1e-9, dt=0.01, t_end=16.0):
    """Spin about principal axis ``axis`` with a tiny off-axis rate; |w_perp| vs time."""
    v = V_PRINCIPAL[:, axis]
    others = [V_PRINCIPAL[:, k] for k in range(3) if k != axis]
    w0 = rate_rad_s * v + eps * (others[0] + others[1])
    x = np.array([1.0, 0.0, 0.0, 0.0, *w0])
    n = round(t_end / dt)
    _, _, samples = fly(x, np.zeros(3), dt, n, every=100)
    w = np.array([s[4:7] for s in samples])
    perp = np.linalg.norm(w - np.outer(w @ v, v), axis=1)
    times = dt * 100 * np.arange(1, len(samples) + 1)
    return times, perp


def test_intermediate_axis_spin_diverges_at_the_linearised_rate():
    j1, j2, j3 = J_PRINCIPAL
    sigma = 1.0 * math.sqrt((j3 - j2) * (j2 - j1) / (j1 * j3))  # [1/s] Landau & Lifshitz sec. 37
    times, perp = spin_perturbation(1)
    i6, i16 = np.searchsorted(times, [6.0 - 1e-9, 16.0 - 1e-9])
    measured = math.log(perp[i16] / perp[i6]) / (times[i16] - times[i6])
    assert measured == pytest.approx(sigma, rel=2e-3)


@pytest.mark.parametrize("axis", [0, 2])
def test_minor_and_major_axis_spins_are_stable(axis):
    _, perp = spin_perturbation(axis)
    assert perp.max() < 10 * 1e-9 * math.sqrt(2)


def test_rk4_step_does_not_allocate():
    """The plant step runs once a frame: it must not touch the heap.

    Counted with numba's runtime allocation statistics: the same number of
    allocations (only argument unboxing) for 1 and for 1000 steps. A positive
    control (``dcm_body_from_inertial`` allocates its 3x3 result) proves the
    counter works.
    """
    if numba.config.DISABLE_JIT:
        pytest.skip("allocation counting needs compiled code")
    from numba.core.runtime import _nrt_python, rtsys

    @numba.njit
    def steps(p, x, tq, dt, dth, n):
        for _ in range(n):
            rk4_step(p, x, tq, dt, dth)

    @numba.njit
    def dcms(q, n):
        s = 0.0
        for _ in range(n):
            s += quaternion.dcm_body_from_inertial(q)[0, 0]
        return s

    def allocations(f, *args):
        before = rtsys.get_allocation_stats().alloc
        f(*args)
        return rtsys.get_allocation_stats().alloc - before

    x = tumbling_state()
    args = (P, x, np.zeros(3), 0.01, np.zeros(3))
    steps(*args, 1)
    dcms(x[0:4], 1)  # compile outside the counted window
    was_on = _nrt_python.memsys_stats_enabled()
    _nrt_python.memsys_enable_stats()
    try:
        assert allocations(steps, *args, 1000) == allocations(steps, *args, 1)
        assert allocations(dcms, x[0:4], 1000) - allocations(dcms, x[0:4], 1) == 999
    finally:
        if not was_on:
            _nrt_python.memsys_disable_stats()


