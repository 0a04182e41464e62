"""Control amplifiers 31, 32, 33 against their transfer law (allsky.hardware.control_amp).

Truth, integral held (``integrate`` False)::

    V = clip(Kp * clip(pos, +-limit[axis]) - Kd * rate, +-V_max)

so a position loop on its limiter comes to rest (V = 0) at the slew rate
Kp * limit / Kd. With the integral on: I grows by pos dt / T_i a frame
while |pos| < I_max, is clamped to +-I_max, and adds Kp * I to V.
"""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from allsky.hardware.control_amp import ControlParams, control_amp

# Scenario defaults: Kp = 1e-3 V/", Kd = 5e-4 V/("/s), limits 500/400/400 ".
P = ControlParams(
    position_gain_v_per_arcsec=np.array([1.0e-3, 2.0e-3, 1.0e-3]),
    rate_gain_v_per_arcsec_s=np.array([5.0e-4, 5.0e-4, 2.5e-4]),
    position_limit_arcsec=np.array([500.0, 400.0, 300.0]),
    output_limit_v=10.0,
    integral_time_s=20.0,
    integral_limit_arcsec=30.0,
)
DT_S = 0.01


def volts(axis, pos, rate, p=P, integral=None, integrate=False, frames=1):
    """Tiny harness: one amplifier for ``frames`` frames; returns (V, integral state)."""
    integral = np.zeros(3) if integral is None else integral
    for _ in range(frames):
        v = control_amp(p, axis, float(pos), float(rate), integral, integrate, DT_S)
    return v, integral


def law(axis, pos, rate, integral=0.0, p=P):
    lim = p.position_limit_arcsec[axis]
    e = min(max(pos, -lim), lim)
    v = p.position_gain_v_per_arcsec[axis] * (e + integral) \
        - p.rate_gain_v_per_arcsec_s[axis] * rate
    return min(max(v, -p.output_limit_v), p.output_limit_v)


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_inside_the_limiter_it_is_pd(axis):
    kp, kd = P.position_gain_v_per_arcsec[axis], P.rate_gain_v_per_arcsec_s[axis]
    v, _ = volts(axis, 100.0, 20.0)
    assert v == pytest.approx(kp * 100.0 - kd * 20.0, rel=1e-15)


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_position_is_limited_per_axis(axis):
    lim = P.position_limit_arcsec[axis]
    kp = P.position_gain_v_per_arcsec[axis]
    assert volts(axis, 1.0e6, 0.0)[0] == pytest.approx(kp * lim)
    assert volts(axis, -1.0e6, 0.0)[0] == pytest.approx(-kp * lim)


@pytest.mark.parametrize("axis", [0, 1, 2])
@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_limiter_sets_the_slew_rate(axis, sign):
    """On the limiter, V = 0 at rate = Kp * limit / Kd (1000 "/s with the defaults)."""
    kp, kd = P.position_gain_v_per_arcsec[axis], P.rate_gain_v_per_arcsec_s[axis]
    slew = kp * P.position_limit_arcsec[axis] / kd
    assert volts(axis, sign * 1.0e5, sign * slew)[0] == pytest.approx(0.0, abs=1e-12)
    # Slower than the slew rate it keeps accelerating, faster it brakes.
    assert sign * volts(axis, sign * 1.0e5, sign * 0.9 * slew)[0] > 0
    assert sign * volts(axis, sign * 1.0e5, sign * 1.1 * slew)[0] < 0


def test_output_saturates():
    assert volts(0, 0.0, -1.0e6)[0] == P.output_limit_v
    assert volts(0, 0.0, 1.0e6)[0] == -P.output_limit_v


finite = {"allow_nan": False, "allow_infinity": False}


@settings(deadline=None)
@given(axis=st.integers(0, 2), pos=st.floats(-1e7, 1e7, **finite),
       rate=st.floats(-1e7, 1e7, **finite))
def test_transfer_law_with_integral_held(axis, pos, rate):
    v, integral = volts(axis, pos, rate, integral=np.full(3, 7.0))
    assert v == pytest.approx(law(axis, pos, rate), rel=1e-12, abs=1e-15)
    assert integral[axis] == 0.0  # held at zero, whatever it was
    assert np.delete(integral, axis).tolist() == [7.0, 7.0]  # other axes untouched


def test_integral_ramps_by_pos_dt_over_ti_and_clamps():
    pos = 10.0  # inside I_max = 30"
    v, integral = volts(1, pos, 0.0, integrate=True, frames=100)
    expected = 100 * pos * DT_S / P.integral_time_s  # 0.5" after 1 s
    assert integral[1] == pytest.approx(expected, rel=1e-12)
    assert v == pytest.approx(law(1, pos, 0.0, expected), rel=1e-12)
    # 10" for 60 s would be 30" plus: clamped at I_max.
    _, integral = volts(1, pos, 0.0, integral=integral, integrate=True, frames=6000)
    assert integral[1] == P.integral_limit_arcsec
    assert integral[0] == integral[2] == 0.0


def test_integral_frozen_outside_its_window():
    integral = np.array([0.0, 2.0, 0.0])
    _, integral = volts(1, 45.0, 0.0, integral=integral, integrate=True, frames=10)
    assert integral[1] == 2.0
