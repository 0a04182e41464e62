"""Reaction wheels: the gyrostat plant, torque distribution, unloading, missions on wheels."""

import math

import control
import numba
import numpy as np
import pytest

from allsky.apps.cli import main
from allsky.config.scenario import load_scenario
from allsky.sim.mission import DITHER_PLAN, Mission, dither_params, wheel_params
from allsky.sim.results import calibration_errors
from allsky.units import RAD2ARCSEC
from allsky.vehicle import plant, wheels
from allsky.vehicle.envelopes import make_envelope, pyramid_axes
from allsky.vehicle.plant_control import gyrostat_nlsys

WHEELS = ['actuators.kind="wheels"']
#: [kg m^2] A body with products of inertia, so that the gyroscopic terms couple the axes.
BODY_KG_M2 = np.array([[100.0, 1.5, -1.0], [1.5, 650.0, 2.0], [-1.0, 2.0, 680.0]])


def _params(overrides=()):
    return wheel_params(load_scenario(overrides=[*WHEELS, *overrides]))


def _fly(x, h, p_body, axes, motor_torques, dt_s):
    """Step the compiled gyrostat through ``motor_torques`` (one row per step).

    Returns the states, the wheel momenta, and the motors' work [J] per step.
    """
    x = np.array(x, dtype=float)
    h = np.array(h, dtype=float)
    j_w = np.full(len(h), 0.03)
    dtheta = np.zeros(3)
    xs, hs, work = [x.copy()], [h.copy()], []
    for u in motor_torques:
        hb, hdot = axes.T @ h, axes.T @ u
        plant.rk4_step_gyrostat(p_body, x, np.zeros(3), hb, hdot, dt_s, dtheta)
        # Work of u_i against the wheel's speed relative to the body, h_i / J_i - g_i . w,
        # integrated exactly: h is linear in time, and int w dt is the body-angle increment.
        work.append(float(np.sum(u * ((h * dt_s + 0.5 * u * dt_s ** 2) / j_w
                                      - axes @ dtheta))))
        h = h + u * dt_s
        xs.append(x.copy())
        hs.append(h.copy())
    return np.array(xs), np.array(hs), np.array(work)


# ---------------------------------------------------------------------------
# The gyrostat plant
# ---------------------------------------------------------------------------

def test_default_array_is_the_equal_facet_pyramid():
    p = _params()
    np.testing.assert_allclose(p.axes, pyramid_axes(math.degrees(math.atan(math.sqrt(2.0)))),
                               atol=1e-15)


def test_momentum_is_conserved_and_energy_changes_by_the_motor_work():
    rng = np.random.default_rng(4)
    axes = pyramid_axes(54.7356103172)
    p_body = plant.make_params(BODY_KG_M2)
    q0 = rng.normal(size=4)
    x0 = np.concatenate([q0 / np.linalg.norm(q0), [0.02, -0.01, 0.015]])
    h0 = np.array([3.0, -2.0, 1.0, 0.5])
    # Motor torques changing every step (as the frame loop's commands do), 60 s at 100 Hz.
    u = 0.3 * np.sin(np.outer(np.arange(6000) * 0.01, [0.7, 1.1, 1.9, 2.3]) + [0, 1, 2, 3])
    xs, hs, work = _fly(x0, h0, p_body, axes, u, 0.01)
    momentum = np.array([plant.gyrostat_momentum_inertial(p_body, x, axes.T @ h)
                         for x, h in zip(xs[::600], hs[::600], strict=True)])
    size = np.linalg.norm(momentum[0])
    assert np.max(np.linalg.norm(momentum - momentum[0], axis=1)) < 1e-10 * size
    j_w = np.full(4, 0.03)
    energy = np.array([plant.gyrostat_energy_j(p_body, x, h, j_w)
                       for x, h in zip(xs, hs, strict=True)])
    assert abs(energy[-1] - energy[0]) > 1.0  # the motors do work worth checking
    np.testing.assert_allclose(np.diff(energy), work, rtol=0, atol=1e-9)
    # The wheel's energy bookkeeping: its speed relative to the body.
    speeds = wheels.wheel_speeds_rad_s(_params(), hs[-1], xs[-1][4:7])
    np.testing.assert_allclose(speeds, hs[-1] / 0.03 - _params().axes @ xs[-1][4:7])


def test_gyrostat_without_wheels_is_the_rigid_body():
    x1 = np.array([0.5, 0.5, -0.5, 0.5, 0.01, -0.02, 0.03])
    x2 = x1.copy()
    p_body = plant.make_params(BODY_KG_M2)
    tau = np.array([0.1, -0.2, 0.05])
    d1, d2 = np.zeros(3), np.zeros(3)
    plant.rk4_step(p_body, x1, tau, 0.01, d1)
    plant.rk4_step_gyrostat(p_body, x2, tau, np.zeros(3), np.zeros(3), 0.01, d2)
    np.testing.assert_array_equal(x1, x2)
    np.testing.assert_array_equal(d1, d2)


def test_nlsys_and_the_compiled_plant_agree():
    axes = pyramid_axes(54.7356103172)
    p_body = plant.make_params(BODY_KG_M2)
    sys_ = gyrostat_nlsys(BODY_KG_M2, axes)
    assert sys_.ninputs == 7 and sys_.nstates == 11
    x0 = np.concatenate([[1.0, 0.0, 0.0, 0.0], [0.01, -0.005, 0.02], [2.0, -1.0, 0.5, 0.0]])
    u = np.array([0.2, -0.1, 0.05, 0.3])
    tau = np.array([0.01, 0.0, -0.02])
    t = np.linspace(0.0, 20.0, 2001)
    resp = control.input_output_response(
        sys_, t, np.tile(np.concatenate([tau, u]), (t.size, 1)).T, x0,
        solve_ivp_kwargs={"rtol": 1e-11, "atol": 1e-13})
    x = x0[:7].copy()
    h = x0[7:].copy()
    dtheta = np.zeros(3)
    for _ in range(t.size - 1):
        plant.rk4_step_gyrostat(p_body, x, tau, axes.T @ h, axes.T @ u, 0.01, dtheta)
        h += u * 0.01
    end = resp.states[:, -1]
    q = end[:4] / np.linalg.norm(end[:4])  # the ODE does not renormalise
    np.testing.assert_allclose(x[:4] * np.sign(x[0] * q[0]), q, atol=1e-9)
    np.testing.assert_allclose(x[4:7], end[4:7], atol=1e-11)
    np.testing.assert_allclose(h, end[7:], atol=1e-12)


# ---------------------------------------------------------------------------
# Distribution
# ---------------------------------------------------------------------------

def test_pseudo_inverse_gives_a_torque_inside_the_envelope_exactly():
    p = _params()
    rng = np.random.default_rng(1)
    envelope = make_envelope(p.axes, p.max_torque_n_m)
    u = np.zeros(4)
    for _ in range(50):
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        # Half the inscribed radius: inside what the minimum-norm solution reaches.
        tau = 0.5 * envelope.min_radius * d
        assert wheels.distribute(p, tau, np.zeros(4), 0.01, u) == 1.0
        np.testing.assert_allclose(-p.axes.T @ u, tau, atol=1e-15)
        # Minimum norm: no part of u in the array's null space.
        assert abs(np.linalg.svd(p.axes.T)[2][-1] @ u) < 1e-15


def test_a_torque_beyond_the_envelope_is_scaled_keeping_its_direction():
    p = _params()
    envelope = make_envelope(p.axes, p.max_torque_n_m)
    u = np.zeros(4)
    for d in ([1.0, 1.0, 1.0], [0.3, -1.0, 0.5], [1.0, 0.0, 0.0]):
        d = np.array(d) / np.linalg.norm(d)
        # Within each axis's reach (no axis is clipped), beyond what the array gives.
        tau = d * np.min(p.axis_reach_n_m / np.maximum(np.abs(d), 1e-300))
        assert np.linalg.norm(tau) > 0.999 * envelope.min_radius
        scale = wheels.distribute(p, tau, np.zeros(4), 0.01, u)
        got = -p.axes.T @ u
        np.testing.assert_allclose(got, scale * tau, atol=1e-15)
        assert np.max(np.abs(u) / p.max_torque_n_m) == pytest.approx(1.0, abs=1e-12)
        assert scale <= 1.0


def test_each_axis_is_first_limited_to_its_reach():
    p = _params()
    u = np.zeros(4)
    # A turn commanded far beyond the wheels (the rate loop's 1.5 deg/s error) beside a
    # small command on a held axis: the held axis keeps most of its torque.
    tau = np.array([0.01, 0.0, 400.0])
    wheels.distribute(p, tau, np.zeros(4), 0.01, u)
    got = -p.axes.T @ u
    assert got[2] == pytest.approx(p.axis_reach_n_m[2], rel=0.02)
    assert got[0] == pytest.approx(0.01, rel=0.02)


def test_a_wheel_at_its_momentum_limit_is_not_spun_further():
    p = _params()
    h = np.zeros(4)
    h[1] = p.max_momentum_n_m_s[1] - 1e-4  # room for 1e-4 N m s
    u = np.zeros(4)
    tau = np.array([0.0, 0.0, -0.5])  # needs wheel 1 spun up (+z axis component)
    scale = wheels.distribute(p, tau, h, 0.01, u)
    assert 0.0 < scale < 1.0
    assert abs(h[1] + u[1] * 0.01) == pytest.approx(p.max_momentum_n_m_s[1], abs=1e-12)
    np.testing.assert_allclose(-p.axes.T @ u, scale * tau, atol=1e-15)
    # Slowing it down is always allowed.
    assert wheels.distribute(p, -tau, h, 0.01, u) == 1.0


# ---------------------------------------------------------------------------
# Unloading
# ---------------------------------------------------------------------------

@numba.njit(cache=False)
def _hold(p, p_body, jet_torque_n_m, disturbance_n_m, kp, kd, dt_s, frames, h, unload, x,
          record):
    """Hold the identity attitude under a constant disturbance; per frame: |h|/limit max,
    attitude error [rad], the jets' impulse used [N m s]."""
    valve = np.zeros(3, dtype=np.int64)
    tau_j = np.zeros(3)
    cmd = np.zeros(3)
    u = np.zeros(h.size)
    hb = np.zeros(3)
    hdot = np.zeros(3)
    dtheta = np.zeros(3)
    ext = np.zeros(3)
    impulse = 0.0
    for k in range(frames):
        wheels.unload_valves(p, h, unload, valve)
        for a in range(3):
            tau_j[a] = valve[a] * jet_torque_n_m[a]
            impulse += abs(tau_j[a]) * dt_s
            # Small-angle attitude error 2 q_vec (target: identity), PD loop.
            cmd[a] = -kp[a] * 2.0 * x[1 + a] * np.sign(x[0]) - kd[a] * x[4 + a] - tau_j[a]
            ext[a] = tau_j[a] + disturbance_n_m[a]
        wheels.distribute(p, cmd, h, dt_s, u)
        wheels.body_vector(p.axes, h, hb)
        wheels.body_vector(p.axes, u, hdot)
        plant.rk4_step_gyrostat(p_body, x, ext, hb, hdot, dt_s, dtheta)
        peak = 0.0
        for i in range(h.size):
            h[i] += u[i] * dt_s
            peak = max(peak, abs(h[i]) / p.max_momentum_n_m_s[i])
        record[k, 0] = peak
        record[k, 1] = 2.0 * np.sqrt(x[1] ** 2 + x[2] ** 2 + x[3] ** 2)
        record[k, 2] = impulse


def test_unloading_keeps_the_momentum_under_its_limit_over_a_long_hold():
    cfg = load_scenario(overrides=WHEELS)
    p = wheel_params(cfg)
    j = np.array(cfg.vehicle.inertia_kg_m2)
    p_body = plant.make_params(j)
    jet = 2.0 * np.array(cfg.jets.thrust_n) * np.array(cfg.jets.moment_arm_m)
    # A constant disturbance (solar pressure on a lopsided vehicle, say), 40 N m s an hour:
    # the array holds about 33 N m s, so without unloading it would saturate in 50 minutes.
    dist = np.array([2e-3, -8e-3, 6e-3])
    # The mission's hold loop: control amplifiers 31-33 at the wheels' torque per volt.
    kp = p.torque_per_volt_n_m_v * np.array(cfg.control.position_gain_v_per_arcsec) * RAD2ARCSEC
    kd = p.torque_per_volt_n_m_v * np.array(cfg.control.rate_gain_v_per_arcsec_s) * RAD2ARCSEC
    frames = 1_000_000  # 2.8 h at 100 Hz
    record = np.zeros((frames, 3))
    x = np.array([1.0, 0, 0, 0, 0, 0, 0])
    _hold(p, p_body, jet, dist, kp, kd, cfg.mission.frame_s, frames, np.zeros(4),
          np.zeros(4, dtype=np.int64), x, record)
    stored = np.linalg.norm(dist) * frames * cfg.mission.frame_s
    assert stored > 3 * 0.8 * 20.0  # the disturbance alone would fill the wheels thrice
    assert record[:, 0].max() < 0.81  # unloading starts at 0.8 and wins at once
    # The jets took out the disturbance's momentum, at their mean torque in pulses.
    assert record[-1, 2] > 0.5 * stored
    # Each pulse is cancelled by the wheels to their torque limit: the hold stays within
    # a few arcsec (measured 1.5").
    assert record[1000:, 1].max() * RAD2ARCSEC < 5.0


# ---------------------------------------------------------------------------
# Missions on wheels
# ---------------------------------------------------------------------------

#: [arcsec] Bound on the legacy mission's pointing on wheels (seed 1: 8.3"; on the jets 8.7").
WHEEL_POINTING_BOUND_ARCSEC = 30.0


def test_legacy_mission_on_wheels_completes_and_points():
    m = Mission(load_scenario(overrides=WHEELS), telemetry=False)
    s = m.run()
    assert s["status"] == "complete", s["abort_reason"]
    assert s["target"]["pointing_error_arcsec"] < WHEEL_POINTING_BOUND_ARCSEC
    err = calibration_errors(s["calibration"], s["truth"])
    assert all(abs(v) < 100.0 for v in err["scale_factor_ppm"].values())
    assert all(abs(v) < 20.0 for v in err["cross_coupling_arcsec"].values())
    assert 0.0 < s["wheels"]["peak_momentum_fraction"] < 1.0


def test_a_wheel_mission_resumes_from_a_snapshot_bit_for_bit():
    cfg = load_scenario(overrides=[*WHEELS, "wheels.max_momentum_n_m_s=8.0"])
    m = Mission(cfg, telemetry=False)
    for _ in range(2):
        m.run_mode()
    assert np.any(m.state.wheel_h[:4])
    history, arrays = m.snapshot()
    resumed = Mission.from_snapshot(history, arrays, telemetry=False)
    assert m.run() == resumed.run()
    # The small wheels needed unloading: the jets fired, their propellant counted.
    assert m.summary()["wheels"]["unloading_propellant_kg"] > 0.0


def test_jet_mission_has_no_wheel_summary():
    m = Mission(load_scenario(), telemetry=False)
    m.run_mode()
    assert "wheels" not in m.summary()
    assert not np.any(m.state.wheel_h)


def test_dither_feedforward_reaches_the_wheels_as_the_torque_itself():
    cfg = load_scenario(overrides=WHEELS)
    d, p = dither_params(cfg), wheel_params(cfg)
    # Volts per N m of the feed-forward times N m per volt of the wheel command.
    np.testing.assert_allclose(d.ff_volts_per_n_m * p.torque_per_volt_n_m_v, 1.0, rtol=1e-15)


def test_dither_plan_flies_on_wheels():
    m = Mission(load_scenario(overrides=WHEELS), telemetry=False, plan=DITHER_PLAN)
    s = m.run()
    assert s["status"] == "complete", s["abort_reason"]
    for axis in ("roll", "yaw"):
        assert abs(m.dither_estimates[axis]["tracking_ratio"] - 1.0) < 0.1


def test_compare_on_the_wheel_vehicle(capsys):
    from allsky.studies.compare import compare, on_vehicle

    cfg = load_scenario()
    assert on_vehicle(cfg) is cfg and on_vehicle(cfg, "jets") is cfg
    assert on_vehicle(cfg, "wheels").actuators.kind == "wheels"
    result = compare(cfg, runs=1, workers=1, vehicle="wheels")
    assert result["vehicle"] == "wheels"
    assert result["legacy"]["status"] == result["dither"]["status"] == "complete"
    assert "vehicle" not in compare(cfg, runs=1, workers=1)


# ---------------------------------------------------------------------------
# The compiled loop on wheels
# ---------------------------------------------------------------------------

needs_jit = pytest.mark.skipif(numba.config.DISABLE_JIT, reason="about compiled code")


@needs_jit
def test_wheel_blocks_are_compiled_without_the_runtime():
    from allsky.sim import frame_loop

    for block in (wheels.distribute, wheels.unload_valves, wheels.body_vector,
                  wheels.advance_momentum, plant.rk4_step_gyrostat):
        assert block.targetoptions["_nrt"] is False, block.py_func.__name__
    assert frame_loop.actuate_wheels.targetoptions["inline"] == "always"


def _wheel_leg_allocations(frames):
    from numba.core.runtime import rtsys

    from allsky.sequencer import legs
    from allsky.sim import frame_loop, recorder

    m = Mission(load_scenario(overrides=WHEELS), telemetry=False)
    leg = legs.Leg(1, 1.0, legs.PROGRAM_MODE1, legs.WATCH_ELAPSED, 0, 0, 0.0,
                   frames * m.params.frame_s, 1e9)
    args = (np.empty((0, recorder.N_TLM)), np.zeros(1, dtype=np.int64),
            np.empty((0, recorder.N_REC)), np.zeros(1, dtype=np.int64))
    before = rtsys.get_allocation_stats().alloc
    frame_loop.run_leg(m.params, m.state, leg, *args)
    assert m.state.frame[0] == frames and np.any(m.state.wheel_h)
    return rtsys.get_allocation_stats().alloc - before


@needs_jit
def test_a_wheel_leg_allocates_the_same_for_10_and_10000_frames():
    from numba.core.runtime import _nrt_python

    was_on = _nrt_python.memsys_stats_enabled()
    _nrt_python.memsys_enable_stats()
    try:
        _wheel_leg_allocations(1)
        assert _wheel_leg_allocations(10) == _wheel_leg_allocations(10_000)
    finally:
        if not was_on:
            _nrt_python.memsys_disable_stats()


# ---------------------------------------------------------------------------
# Configuration
# ---------------------------------------------------------------------------

@pytest.mark.parametrize("setting, key", [
    ("actuators.kind=\"thrusters\"", "actuators.kind"),
    ("wheels.axes=[[1,0,0],[0,1,0]]", "wheels.axes"),
    ("wheels.axes=[[1,0,0],[0,1,0],[0.7071,0.7071,0]]", "wheels.axes"),
    ("wheels.axes=[[2,0,0],[0,1,0],[0,0,1]]", "wheels.axes"),
    ("wheels.axes=[[1,0,0],[0,1,0],[0,0,0]]", "wheels.axes"),
    ("wheels.max_torque_n_m=0", "wheels.max_torque_n_m"),
    ("wheels.max_momentum_n_m_s=[20,20,-1,20]", "wheels.max_momentum_n_m_s"),
    ("wheels.max_momentum_n_m_s=[20,20,20]", "wheels.max_momentum_n_m_s"),
    ("wheels.inertia_kg_m2=-0.1", "wheels.inertia_kg_m2"),
    ("wheels.unload_fraction=1.2", "wheels.unload_fraction"),
    ("wheels.unload_end_fraction=0.9", "wheels.unload_end_fraction"),
])
def test_bad_wheel_settings_exit_2_naming_the_key(capsys, setting, key):
    assert main(["config", "check", "--set", setting]) == 2
    err = capsys.readouterr().err
    assert err.startswith("allsky: error: ") and key in err, err


def test_axes_near_unit_length_are_normalised_and_limits_may_be_per_wheel():
    cfg = load_scenario(overrides=["wheels.axes=[[1.001,0,0],[0,0.999,0],[0,0,1]]",
                                   "wheels.max_torque_n_m=[0.1,0.2,0.3]"])
    np.testing.assert_allclose(np.linalg.norm(cfg.wheels.axes, axis=1), 1.0, rtol=1e-15)
    p = wheel_params(load_scenario(overrides=[
        "wheels.axes=[[1,0,0],[0,1,0],[0,0,1]]", "wheels.max_torque_n_m=[0.1,0.2,0.3]"]))
    np.testing.assert_array_equal(p.max_torque_n_m, [0.1, 0.2, 0.3])
    np.testing.assert_array_equal(p.axis_reach_n_m, [0.1, 0.2, 0.3])
