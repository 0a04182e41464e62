"""Cold-gas jet couples 39, 40, 41 (allsky.hardware.jets) against the rocket equations.

Truth:
- a couple of two jets of thrust F at +-r from the centre of mass gives a pure
  torque 2 F r (statics);
- a jet of thrust F and specific impulse Isp uses propellant at
  F / (Isp g0), g0 = 9.80665 m/s^2 by definition (Sutton & Biblarz, *Rocket
  Propulsion Elements*, 9th ed., eq. 2-5); a couple fires two jets;
- the default scenario: F = [0.25, 0.5, 0.5] N, r = [0.5, 1.25, 1.25] m,
  Isp = 65 s (cold nitrogen);
- a blow-down feed: the ideal gas law in a tank of fixed volume at constant
  temperature, thrust proportional to the tank pressure.
"""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from allsky.hardware.jets import JetParams, jets, make_params, thrust_fraction

THRUST_N = [0.25, 0.5, 0.5]
ARM_M = [0.5, 1.25, 1.25]
ISP_S = 65.0
G0 = 9.80665  # [m/s^2] standard gravity (CGPM 1901)
DT_S = 0.01
P = make_params(THRUST_N, ARM_M, ISP_S)


def fire(p, valve, propellant_kg, dt_s=DT_S):
    tank = np.array([propellant_kg], dtype=float)
    torque = np.full(3, np.nan)
    ok = jets(p, np.asarray(valve, dtype=np.int64), dt_s, tank, torque)
    return ok, torque, tank[0]


def test_make_params_couple_torque_and_flow():
    assert np.allclose(P.torque_n_m, [2 * 0.25 * 0.5, 2 * 0.5 * 1.25, 2 * 0.5 * 1.25],
                       rtol=1e-15, atol=0)
    assert np.allclose(P.torque_n_m, [0.25, 1.25, 1.25], rtol=1e-15, atol=0)
    assert np.allclose(P.flow_kg_s, 2 * np.array(THRUST_N) / (ISP_S * G0), rtol=1e-15, atol=0)
    assert P.flow_kg_s[0] == pytest.approx(7.8446e-4, rel=1e-4)  # 0.5 N / (65 s * 9.80665)


@pytest.mark.parametrize("valve", [[1, 0, 0], [0, -1, 0], [0, 0, 1], [1, -1, 1], [-1, -1, -1],
                                   [0, 0, 0]])
def test_torque_sign_and_one_frame_of_propellant(valve):
    ok, torque, left = fire(P, valve, 4.0)
    assert ok
    assert np.array_equal(torque, np.array(valve) * P.torque_n_m)
    used = sum(abs(v) * f for v, f in zip(valve, P.flow_kg_s)) * DT_S
    # One rounding of the 4 kg tank reading: half an ulp of 4.0 (8.9e-16 kg).
    assert 4.0 - left == pytest.approx(used, rel=0, abs=np.spacing(4.0))


def test_mass_used_over_many_frames():
    # Roll and yaw couples on for N frames: 2 couples x 2 jets x F / (Isp g0) x N dt.
    n = 5000
    tank = np.array([4.0])
    torque = np.zeros(3)
    valve = np.array([1, 0, -1], dtype=np.int64)
    for _ in range(n):
        assert jets(P, valve, DT_S, tank, torque)
    expected = (2 * 0.25 + 2 * 0.5) / (ISP_S * G0) * n * DT_S
    # At most half an ulp of the tank reading (< 4 kg) lost per subtraction.
    assert 4.0 - tank[0] == pytest.approx(expected, rel=1e-14, abs=n * 0.5 * np.spacing(4.0))


def test_mass_used_is_exact_in_binary_arithmetic():
    # With flows and frame that are powers of two every subtraction is exact: the
    # tank reads exactly start - N * dt * sum(flows).
    p = JetParams(np.array([0.25, 1.25, 1.25]), np.array([2.0 ** -10, 2.0 ** -9, 2.0 ** -9]))
    dt = 2.0 ** -7
    tank = np.array([1.0])
    torque = np.zeros(3)
    n = 1000
    for _ in range(n):
        jets(p, np.array([1, 1, 0], dtype=np.int64), dt, tank, torque)
    assert tank[0] == 1.0 - n * dt * (2.0 ** -10 + 2.0 ** -9)


def test_empty_tank_gives_no_torque_and_false():
    ok, torque, left = fire(P, [1, 1, 1], 0.0)
    assert not ok and np.array_equal(torque, [0.0, 0.0, 0.0]) and left == 0.0
    # Valves closed on an empty tank: still reported empty.
    ok, torque, left = fire(P, [0, 0, 0], 0.0)
    assert not ok and np.array_equal(torque, [0.0, 0.0, 0.0])


def test_last_frame_that_the_tank_cannot_supply():
    # Less than one frame's worth left: no torque, tank emptied, False.
    need = P.flow_kg_s[1] * DT_S
    ok, torque, left = fire(P, [0, 1, 0], 0.5 * need)
    assert not ok and np.array_equal(torque, [0.0, 0.0, 0.0]) and left == 0.0
    ok, torque, left = fire(P, [0, 1, 0], need)  # exactly enough: one last pulse
    assert ok and torque[1] == P.torque_n_m[1] and left == 0.0


@settings(max_examples=50, deadline=None)
@given(valve=st.lists(st.sampled_from([-1, 0, 1]), min_size=3, max_size=3),
       tank=st.floats(0.0, 5.0))
def test_no_net_propellant_gain_and_torque_only_when_fed(valve, tank):
    ok, torque, left = fire(P, valve, tank)
    assert 0.0 <= left <= tank
    if ok:
        assert np.array_equal(torque, np.array(valve) * P.torque_n_m)
    else:
        assert np.array_equal(torque, [0.0, 0.0, 0.0]) and left == 0.0


# -- the feed: regulated and blow-down ------------------------------------------------------

def test_a_regulated_feed_holds_thrust_until_the_tank_is_empty():
    p = make_params(THRUST_N, ARM_M, ISP_S, "regulated", 20.0, 5.0, 4.0)
    for kg in (4.0, 1.0, 0.01):
        _, torque, _ = fire(p, [1, 0, 0], kg)
        assert torque[0] == P.torque_n_m[0]  # the same number, whatever is left


def test_blowdown_thrust_and_impulse_follow_the_ideal_gas_in_a_fixed_tank():
    """An ideal gas at constant temperature in a tank of fixed volume: p V = (m/M_w) R T,
    so p is proportional to the gas held. With p0 = 20 bar full and 5 bar once the usable
    M = 0.01 kg is gone, the gas held is M / (1 - f) at first, f = 5/20, and the feed
    pressure over p0 is u = f + (1 - f) m / M. Thrust and flow (constant Isp) go as u:
    dm/dt = -k u, k = 2 F0 / (Isp g0) for a couple, so u = exp(-t / tau),
    tau = M / ((1 - f) k); the tank is empty when u = f, at tau ln(1/f); the angular
    impulse to t is T0 tau (1 - exp(-t / tau)), T0 = 2 F0 r, and to the end
    T0 M / k = r Isp g0 M (the rocket's impulse Isp g0 M on the couple's arm)."""
    usable, f = 0.01, 5.0 / 20.0
    p = make_params(THRUST_N, ARM_M, ISP_S, "blowdown", 20.0, 5.0, usable)
    k = 2 * THRUST_N[0] / (ISP_S * G0)
    t0 = 2 * THRUST_N[0] * ARM_M[0]
    tau = usable / ((1 - f) * k)
    tank = np.array([usable])
    torque = np.zeros(3)
    impulse, t, at_10s = 0.0, 0.0, None
    while jets(p, np.array([1, 0, 0], dtype=np.int64), DT_S, tank, torque):
        impulse += torque[0] * DT_S
        t += DT_S
        if at_10s is None and t >= 10.0 - 1e-9:
            at_10s = impulse
            # thrust at 10 s, as the frame after it starts: the tank pressure then
            assert torque[0] / t0 == pytest.approx(math.exp(-(t - DT_S) / tau), rel=1e-3)
    assert at_10s == pytest.approx(t0 * tau * (1 - math.exp(-10.0 / tau)), rel=1e-3)
    assert t == pytest.approx(tau * math.log(1 / f), abs=2 * DT_S)
    assert impulse == pytest.approx(ARM_M[0] * ISP_S * G0 * usable, rel=2e-3)
    # At the end the feed is at the final pressure: a quarter of the thrust.
    assert torque[0] == 0.0 and tank[0] == 0.0
    assert thrust_fraction(p, 0.0) == pytest.approx(f, abs=1e-15)
    assert thrust_fraction(p, usable) == pytest.approx(1.0, abs=1e-15)
