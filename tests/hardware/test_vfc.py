"""Voltage-to-frequency converters 8, 10, 12 against the exact integral of their input.

Truth: a converter with pulse weight w [arcsec/pulse] and saturation M
[pulses/s], driven by rates r_k held over frames of dt, integrates
``S_n = sum_k clip(r_k / w, +-M) dt`` [pulses]. The converter is a
charge-balance integrator: the pulses put out, P_n, plus the charge left on
it, the residue in (-1, 1), equal S_n exactly (no pulse lost or invented).
For an input of one sign this makes P_n = trunc(S_n) (truncation toward
zero); after a sign reversal an already emitted pulse is not taken back
until a full pulse of opposite charge has built up, so then only
|P_n - S_n| < 1 holds. The exact integral is computed with
:class:`fractions.Fraction` from the same floats.
"""

import math
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from allsky.hardware.vfc import VfcParams, vfc


def run(p, rates_arcsec_s, dt_s, axis=0):
    """Tiny harness: one converter over a rate sequence; cumulative pulses and residues."""
    residue = np.zeros(3)
    total = 0
    cum, res = [], []
    for r in rates_arcsec_s:
        n = vfc(p, axis, float(r), dt_s, residue)
        assert isinstance(n, int)
        total += n
        cum.append(total)
        res.append(float(residue[axis]))
    return cum, res, residue


def exact_cumulative(p, rates_arcsec_s, dt_s):
    """Exact running integral [pulses] of the clipped input, in rationals."""
    w, m, dt = Fraction(p.pulse_weight_arcsec), Fraction(p.max_rate_pps), Fraction(dt_s)
    s, out = Fraction(0), []
    for r in rates_arcsec_s:
        s += min(max(Fraction(r) / w, -m), m) * dt
        out.append(s)
    return out


def trunc(q: Fraction) -> int:
    return math.trunc(q)


# Dyadic scaling (every product and sum below is exact in binary floating
# point), so the count must equal trunc(exact) with no tolerance at all.
DYADIC = VfcParams(pulse_weight_arcsec=0.125, max_rate_pps=1000.0)
DYADIC_DT_S = 1.0 / 64.0


@pytest.mark.parametrize("rate", [0.0, 1.0 / 16, 3.0, -3.0, 100.0, -77.5, 124.9375])
def test_constant_rate_counts_the_exact_integral(rate):
    n = 500
    cum, res, _ = run(DYADIC, [rate] * n, DYADIC_DT_S)
    exact = exact_cumulative(DYADIC, [rate] * n, DYADIC_DT_S)
    assert cum == [trunc(q) for q in exact]
    assert all(-1.0 < r < 1.0 for r in res)
    # The residue is exactly what the count has not yet put out.
    assert [c + Fraction(r) for c, r in zip(cum, res)] == exact


@settings(deadline=None)
@given(st.lists(st.integers(-4800, 4800), min_size=1, max_size=200))
def test_dyadic_sequence_puts_out_the_exact_integral(sixteenths):
    """Any sequence, with sign changes and saturation (|r| > 125 "/s here): P + residue = S."""
    rates = [k / 16.0 for k in sixteenths]
    cum, res, _ = run(DYADIC, rates, DYADIC_DT_S)
    exact = exact_cumulative(DYADIC, rates, DYADIC_DT_S)
    assert [c + Fraction(r) for c, r in zip(cum, res)] == exact
    assert all(-1.0 < r < 1.0 for r in res)
    assert all(abs(c - q) < 1 for c, q in zip(cum, exact))


@settings(deadline=None)
@given(st.lists(st.integers(0, 4800), min_size=1, max_size=200), st.sampled_from([1, -1]))
def test_dyadic_one_signed_sequence_counts_trunc_of_the_integral(sixteenths, sign):
    rates = [sign * k / 16.0 for k in sixteenths]
    cum, _, _ = run(DYADIC, rates, DYADIC_DT_S)
    exact = exact_cumulative(DYADIC, rates, DYADIC_DT_S)
    assert cum == [trunc(q) for q in exact]


finite = {"allow_nan": False, "allow_infinity": False}


@settings(deadline=None)
@given(rates=st.lists(st.floats(0.0, 2.0e4, **finite), min_size=1, max_size=100),
       signs=st.lists(st.sampled_from([1.0, -1.0]), min_size=100, max_size=100),
       one_signed=st.booleans(),
       w=st.floats(0.01, 10.0, **finite), m=st.floats(10.0, 1.0e6, **finite),
       dt=st.floats(1.0e-3, 0.1, **finite))
def test_arbitrary_floats_lose_and_invent_no_pulse(rates, signs, one_signed, w, m, dt):
    """Same laws for arbitrary floats, to floating-point rounding of the running sum."""
    rates = [r * (signs[0] if one_signed else s) for r, s in zip(rates, signs)]
    p = VfcParams(w, m)
    cum, res, _ = run(p, rates, dt)
    exact = exact_cumulative(p, rates, dt)
    scale = Fraction(0)
    for c, r, q, rate in zip(cum, res, exact, rates):
        scale += abs(Fraction(rate) / Fraction(w)) * Fraction(dt)
        tol = Fraction(1, 10**9) * (1 + scale)
        assert -1.0 < r < 1.0
        assert abs(c + Fraction(r) - q) <= tol
        if not one_signed:
            continue
        if abs(q - round(q)) > tol:
            assert c == trunc(q)
        else:
            assert c in (trunc(q - tol), trunc(q + tol))


def test_saturation_at_max_rate():
    p = VfcParams(pulse_weight_arcsec=0.1, max_rate_pps=1.0e5)  # scenario default
    dt = 0.01
    # 10 x the saturating rate (w M = 10000 arcsec/s): M dt = 1000 pulses a frame.
    cum, _, _ = run(p, [1.0e5] * 50, dt)
    assert cum == [1000 * (k + 1) for k in range(50)]
    cum, _, _ = run(p, [-1.0e5] * 50, dt)
    assert cum == [-1000 * (k + 1) for k in range(50)]


def test_sign_handling_by_hand():
    """+0.75 pulse/frame for 4 frames then -0.75: 0,1,1,1 then 0,-1,-1,-1 (hand count)."""
    p = VfcParams(pulse_weight_arcsec=1.0, max_rate_pps=1.0e6)
    residue = np.zeros(3)
    per_frame = [vfc(p, 1, r, 0.25, residue) for r in [3.0] * 4 + [-3.0] * 4]
    assert per_frame == [0, 1, 1, 1, 0, -1, -1, -1]
    assert residue[1] == 0.0
    # A negative rate after a positive residue first discharges it: no spurious pulse.
    residue[:] = 0.0
    assert vfc(p, 1, 3.2, 0.25, residue) == 0  # charge 0.8
    assert vfc(p, 1, -3.0, 0.25, residue) == 0  # 0.05
    assert vfc(p, 1, -0.4, 0.25, residue) == 0  # -0.05
    assert residue[1] == pytest.approx(-0.05)


def test_emitted_pulse_is_not_taken_back_by_a_small_reversal():
    """Charge balance, not trunc: 1 pulse out, then -1/128 pulse in -> P = 1, S = 127/128."""
    residue = np.zeros(3)
    assert vfc(DYADIC, 0, 8.0, DYADIC_DT_S, residue) == 1  # 64 pps x 1/64 s
    assert vfc(DYADIC, 0, -1.0 / 16, DYADIC_DT_S, residue) == 0
    assert residue[0] == -1.0 / 128


def test_axes_keep_their_own_residue():
    p = VfcParams(pulse_weight_arcsec=1.0, max_rate_pps=1.0e6)
    residue = np.array([0.0, 0.5, -0.5])
    assert vfc(p, 0, 2.0, 0.25, residue) == 0
    assert residue.tolist() == [0.5, 0.5, -0.5]


def test_full_roll_at_default_scaling():
    """A 360 deg turn at 1.5 deg/s (SPEC sec. 4) = 1 296 000" / 0.1" = 12 960 000 pulses.

    With the non-dyadic 0.1" weight the float running sum may sit a hair
    below the integer boundary: the count is good to one pulse.
    """
    p = VfcParams(pulse_weight_arcsec=0.1, max_rate_pps=1.0e5)
    residue = np.zeros(3)
    total = 0
    for _ in range(24_000):  # 240 s at 100 Hz
        total += vfc(p, 0, 5400.0, 0.01, residue)
    assert abs(total - 12_960_000) <= 1
    assert total + residue[0] == pytest.approx(12_960_000, abs=1e-3)


def test_integrator_drift_is_counted_as_a_rate():
    """An offset d [arcsec/s] at the converter input counts trunc(d T / w) pulses over T.

    With no rate in, 1.5 deg/h (= 1.5 arcsec/s) for 40 s at w = 0.125 arcsec
    (dyadic: the sums are exact) is 60 / 0.125 = 480 pulses; on its own axis only.
    """
    p = DYADIC._replace(integrator_drift_arcsec_s=(1.5, 0.0, -0.25))
    residue = np.zeros(3)
    totals = [sum(vfc(p, a, 0.0, 0.25, residue) for _ in range(160)) for a in range(3)]
    assert totals == [480, 0, -80]
    assert residue.tolist() == [0.0, 0.0, 0.0]


def test_zero_integrator_drift_leaves_the_input_bit_for_bit():
    """Without an offset nothing is added: -0.0 stays -0.0 in the carried residue."""
    residue = np.array([-0.0, 0.0, 0.0])
    assert vfc(DYADIC, 0, -0.0, 0.01, residue) == 0
    assert math.copysign(1.0, residue[0]) == -1.0
