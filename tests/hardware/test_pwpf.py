"""PWPF valve modulators 34, 35, 36 against their analytic static characteristic.

Truth: for a constant input e the continuous-time modulator settles into a
pulse train with on-time T_on = tau ln((U_on - K(e-U_m))/(U_off - K(e-U_m)))
and off-time T_off = tau ln((K e - U_off)/(K e - U_on)); dead zone K e < U_on;
saturation K(e - U_m) >= U_off (Wie, Space Vehicle Dynamics and Control,
2nd ed., sec. 7.4; derivation in allsky.hardware.pwpf).
"""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from allsky.hardware.pwpf import make_params, pwpf_step, static_on_off_times_s

K, TAU, U_ON, U_OFF, U_M = 1.0, 0.1, 0.001, 0.0003, 0.008


def run(e, dt=1e-4, t_end=3.0, min_on_time=None, p=None, f0=0.0):
    """Valve trace of modulator 0 for a constant input ``e``, filter starting at ``f0``."""
    p = p or make_params(K, TAU, U_ON, U_OFF, U_M, min_on_time or dt, dt)
    f = np.array([f0, 0.0, 0.0])
    out = np.zeros(3, dtype=np.int64)
    on = np.zeros(3, dtype=np.int64)
    n = int(t_end / dt)
    y = np.empty(n, dtype=np.int64)
    for i in range(n):
        y[i] = pwpf_step(p, 0, e, f, out, on)
    return y


def pulses(y, dt):
    """Steady on-times and off-times [s] of a valve trace (first cycle dropped)."""
    edges = np.flatnonzero(np.diff((y != 0).astype(int))) + 1
    runs = np.diff(edges) * dt
    states = (y[edges[:-1]] != 0)
    on, off = runs[states][1:], runs[~states][1:]
    return on, off


@pytest.mark.parametrize("e", [0.0015, 0.002, 0.004, 0.006])
def test_on_and_off_times_match_the_static_characteristic(e):
    dt = 1e-5
    y = run(e, dt=dt, t_end=2.0)
    on, off = pulses(y, dt)
    t_on, t_off = static_on_off_times_s(K, TAU, U_ON, U_OFF, U_M, e)
    assert on.size > 3 and off.size > 3
    # Within two integration steps of the continuous-time formulas.
    assert np.allclose(on, t_on, atol=2 * dt)
    assert np.allclose(off, t_off, atol=2 * dt)
    duty = t_on / (t_on + t_off)
    assert np.mean(y != 0) == pytest.approx(duty, rel=0.03)


def test_dead_zone_is_u_on_over_k():
    assert not run(0.999 * U_ON / K).any()
    assert run(1.01 * U_ON / K, t_end=5.0).any()


def test_saturation_beyond_u_m_plus_u_off_over_k():
    e_sat = U_M + U_OFF / K
    y = run(1.001 * e_sat)
    assert np.all(y[500:] == 1)  # after the first switch-on (about 13 ms)
    assert static_on_off_times_s(K, TAU, U_ON, U_OFF, U_M, 1.001 * e_sat) == (math.inf, 0.0)
    assert not np.all(run(0.95 * e_sat)[500:] == 1)


def test_negative_input_mirrors_positive():
    assert np.array_equal(run(-0.004), -run(0.004))


def test_minimum_on_time_respected_at_the_mission_frame():
    dt = 0.01
    for e in (0.0011, 0.002, 0.005):
        y = run(e, dt=dt, t_end=20.0, min_on_time=0.01)
        on, _ = pulses(y, dt)
        assert on.size and on.min() >= 0.01 - 1e-12
    y = run(0.0011, dt=dt, t_end=20.0, min_on_time=0.03)
    on, _ = pulses(y, dt)
    assert on.min() >= 0.03 - 1e-12


def test_minimum_pulse_sized_for_the_valve():
    # The filter's own minimum pulse tau (U_on - U_off) / U_m, about 9 ms with the
    # default parameters: close to the 10 ms valve minimum on-time by design.
    t_min_filter = TAU * (U_ON - U_OFF) / (K * U_M)
    assert t_min_filter == pytest.approx(0.00875)
    on, _ = pulses(run(1.05 * U_ON, dt=1e-5, t_end=3.0), 1e-5)
    assert on.min() == pytest.approx(t_min_filter, rel=0.1)


@settings(max_examples=40, deadline=None)
@given(a=st.floats(0.0012, 0.0079), b=st.floats(0.0012, 0.0079))
def test_duty_cycle_monotone_in_input(a, b):
    lo, hi = sorted((a, b))
    d = [static_on_off_times_s(K, TAU, U_ON, U_OFF, U_M, e) for e in (lo, hi)]
    duty = [t_on / (t_on + t_off) for t_on, t_off in d]
    assert duty[0] <= duty[1] + 1e-12



# Thresholds drawn over a wide design space: a linear region exists when
# K U_m > U_on - U_off, guaranteed here by K U_m >= 1.5 U_on.
designs = st.fixed_dictionaries({
    "k": st.floats(0.5, 5.0),
    "tau": st.floats(0.05, 0.5),
    "u_on": st.floats(1e-4, 1e-2),
    "off_ratio": st.floats(0.05, 0.9),  # U_off / U_on
    "m_ratio": st.floats(1.5, 20.0),  # K U_m / U_on
})


def design_values(d):
    u_off = d["off_ratio"] * d["u_on"]
    u_m = d["m_ratio"] * d["u_on"] / d["k"]
    return d["k"], d["tau"], d["u_on"], u_off, u_m


def input_at(k, u_on, u_off, u_m, frac):
    """Input ``frac`` of the way from the dead-zone edge (0) to saturation (1)."""
    lo, hi = u_on / k, u_m + u_off / k
    return lo + frac * (hi - lo)


def duty_of(t_on, t_off):
    if t_on == 0.0:
        return 0.0  # dead zone
    if math.isinf(t_on):
        return 1.0  # saturation
    return t_on / (t_on + t_off)


def test_dead_zone_edge_itself_does_not_fire():
    # At K e = U_on exactly the filter only approaches U_on: T_off is infinite.
    # (Before the fix this divided by zero.)
    assert static_on_off_times_s(K, TAU, U_ON, U_OFF, U_M, U_ON / K) == (0.0, math.inf)


@settings(max_examples=150, deadline=None)
@given(d=designs, a=st.floats(-0.2, 1.2), b=st.floats(-0.2, 1.2))
def test_duty_cycle_monotone_in_input_for_any_thresholds(d, a, b):
    k, tau, u_on, u_off, u_m = design_values(d)
    lo, hi = sorted((input_at(k, u_on, u_off, u_m, a), input_at(k, u_on, u_off, u_m, b)))
    duty = [duty_of(*static_on_off_times_s(k, tau, u_on, u_off, u_m, e)) for e in (lo, hi)]
    assert 0.0 <= duty[0] <= duty[1] + 1e-12 <= 1.0 + 1e-12


def run_from_switch_off(p, e, dt, t_end):
    """Valve trace for input ``e``, the filter starting at U_off just after a switch-off."""
    return run(e, dt=dt, t_end=t_end, p=p, f0=p.off_threshold_v)


@settings(max_examples=12, deadline=None)
@given(d=designs, frac=st.floats(0.15, 0.85))
def test_simulated_pulses_match_the_formulas_for_any_thresholds(d, frac):
    k, tau, u_on, u_off, u_m = design_values(d)
    e = input_at(k, u_on, u_off, u_m, frac)
    t_on, t_off = static_on_off_times_s(k, tau, u_on, u_off, u_m, e)
    dt = (t_on + t_off) / 1000.0
    p = make_params(k, tau, u_on, u_off, u_m, dt, dt)
    y = run_from_switch_off(p, e, dt, 6.0 * (t_on + t_off))
    on, off = pulses(y, dt)
    assert on.size >= 3 and off.size >= 3
    # The discrete modulator (filter exact for a held input) switches at frame
    # boundaries, so the filter overshoots a threshold by up to one frame of its
    # slope, which the next phase spends at its own slope. Slopes tau f' at
    # f = U_on: K e - U_on before, K(e - U_m) - U_on after; at f = U_off:
    # K(e - U_m) - U_off before, K e - U_off after.
    r_on = (k * e - u_on) / (u_on - k * (e - u_m))
    r_off = (u_off - k * (e - u_m)) / (k * e - u_off)
    assert np.allclose(on, t_on, rtol=0, atol=(2.0 + r_on) * dt)
    assert np.allclose(off, t_off, rtol=0, atol=(2.0 + r_off) * dt)
