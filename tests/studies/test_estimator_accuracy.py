"""Closed-form steady-state accuracy (allsky.studies.estimator_accuracy) against Riccati solutions.

Truth:
- the discrete Kalman filter of the model written out below from the physics
  (attitude error grows as -bias x time plus integrated white rate noise; the
  bias walks; the angle sensor adds white noise; the rate-integrating gyro's
  readout adds white noise to the gyro angle at every sample, carried here
  as a third state) has, as steady state, the limit of its Riccati recursion
  from zero covariance. That limit is computed three independent ways: the
  recursion looped in float64; scipy's ``solve_discrete_are``; and the
  recursion doubled (P after 2^k steps from P after 2^(k-1), the doubling
  algorithm) in 50-digit decimal arithmetic, which stays exact to far
  better than 1e-9 however ill-conditioned the grid point (and agrees with
  the other two where they are well conditioned);
- the continuous algebraic Riccati equation (Kalman-Bucy filter) of the same
  model, solved by scipy's ``solve_continuous_are``, is the dt -> 0 limit
  with sigma_n^2 dt held fixed; the discrete pre- and post-update values
  approach it from either side within dt/tau (docs/kalman.md);
- the optimal filter's error covariance cannot decrease with more noise or
  with fewer samples (a garbled or thinned data set), and the post-update
  covariance cannot exceed the pre-update one;
- units: scaling every angle by lambda scales sigmas by lambda; scaling time
  by mu (sigma_v by mu^-1/2, sigma_u by mu^-3/2) leaves the attitude sigma
  unchanged and divides the bias sigma by mu;
- a seeded Monte Carlo run of the rate-integrating gyro and the sensor,
  filtered with the closed-form gains, shows the predicted sigmas.
"""

import decimal
import math

import numpy as np
import pytest
import scipy.linalg
from hypothesis import given, settings
from hypothesis import strategies as st

from allsky import units
from allsky.studies import estimator_accuracy as ea

D = decimal.Decimal
CTX = decimal.Context(prec=50)

# ---------------------------------------------------------------- the model


def model(sigma_v, sigma_u, sigma_n, dt, sigma_e=None, num=float):
    """``(Phi, Q, H, R)`` of the error dynamics over one sample, as nested lists of ``num``.

    States: attitude error, bias error (truth - estimate); with ``sigma_e``
    also the present readout error ``e_k`` of the rate-integrating gyro.
    Over a step the attitude error changes by ``-dt b - int(eta_v) -
    int((dt - s) eta_u ds)`` (plus ``e_k - e_(k+1)`` with readout noise: the
    gyro angle increment between two readouts carries both readout errors),
    the bias by ``int(eta_u)``.
    """
    sv, su, sn, t = (num(x) for x in (sigma_v, sigma_u, sigma_n, dt))
    q_aa = sv * sv * t + su * su * t * t * t / num(3)
    q_ab = -su * su * t * t / num(2)
    q_bb = su * su * t
    if sigma_e is None:
        phi = [[num(1), -t], [num(0), num(1)]]
        q = [[q_aa, q_ab], [q_ab, q_bb]]
        h = [[num(1), num(0)]]
    else:
        se2 = num(sigma_e) * num(sigma_e)
        z = num(0)
        # e_(k+1) enters the attitude with sign -1 and becomes the new third state.
        phi = [[num(1), -t, num(1)], [z, num(1), z], [z, z, z]]
        q = [[q_aa + se2, q_ab, -se2], [q_ab, q_bb, z], [-se2, z, se2]]
        h = [[num(1), z, z]]
    return phi, q, h, [[sn * sn]]


def update(p, h, r):
    """Post-update covariance and gain for the pre-update covariance ``p`` (float64)."""
    p, h, r = np.asarray(p), np.asarray(h), np.asarray(r)
    k = p @ h.T / (h @ p @ h.T + r)
    return p - k @ h @ p, k[:, 0]


# ---------------------------------------------- reference solvers of the DARE


def riccati_loop(phi, q, h, r, steps):
    """Pre-update covariance after ``steps`` plain predict/update cycles from zero (float64)."""
    phi, q, h, r = (np.asarray(m, dtype=float) for m in (phi, q, h, r))
    p = q.copy()
    for _ in range(steps):
        post, _ = update(p, h, r)
        p = phi @ post @ phi.T + q
    return p


def scipy_dare(phi, q, h, r):
    """Pre-update covariance from scipy (the filter DARE is the control one transposed)."""
    phi, q, h, r = (np.asarray(m, dtype=float) for m in (phi, q, h, r))
    return scipy.linalg.solve_discrete_are(phi.T, h.T, q, r)


def _mul(a, b):
    return [[sum((a[i][k] * b[k][j] for k in range(len(b))), D(0)) for j in range(len(b[0]))]
            for i in range(len(a))]


def _add(a, b):
    return [[x + y for x, y in zip(ra, rb)] for ra, rb in zip(a, b)]


def _t(a):
    return [list(r) for r in zip(*a)]


def _solve(a, b):
    """``a^-1 b`` by Gauss-Jordan elimination with partial pivoting."""
    n = len(a)
    m = [list(a[i]) + list(b[i]) for i in range(n)]
    for c in range(n):
        piv = max(range(c, n), key=lambda i: abs(m[i][c]))
        m[c], m[piv] = m[piv], m[c]
        inv = 1 / m[c][c]
        m[c] = [x * inv for x in m[c]]
        for i in range(n):
            if i != c and m[i][c] != 0:
                f = m[i][c]
                m[i] = [x - f * y for x, y in zip(m[i], m[c])]
    return [row[n:] for row in m]


def _as_float(m):
    return np.array([[float(v) for v in row] for row in m])


def doubling_dare(phi, q, h, r, max_doublings=400):
    """Steady-state pre- and post-update covariances and gain, doubling in 50-digit decimals.

    With ``A = Phi^T``, ``G = H^T R^-1 H``, ``X = Q``: ``A <- A (I + G X)^-1 A``,
    ``G <- G + A (I + G X)^-1 G A^T``, ``X <- X + A^T X (I + G X)^-1 A``;
    after k doublings ``X`` is the pre-update covariance 2^k steps after
    starting from zero post-update covariance.
    """
    with decimal.localcontext(CTX):
        n = len(phi)
        eye = [[D(int(i == j)) for j in range(n)] for i in range(n)]
        a = _t(phi)
        g = _mul(_t(h), [[x / r[0][0] for x in h[0]]])
        x = [list(row) for row in q]
        for _ in range(max_doublings):
            m = _add(eye, _mul(g, x))
            m_a = _solve(m, a)
            m_g = _solve(m, g)
            x_new = _add(x, _mul(_mul(_t(a), x), m_a))
            g = _add(g, _mul(_mul(a, m_g), _t(a)))
            a = _mul(a, m_a)
            done = all(abs(xn - xo) <= D("1e-40") * abs(xn) for rn, ro in zip(x_new, x)
                       for xn, xo in zip(rn, ro))
            x = x_new
            if done:
                break
        else:
            raise AssertionError("doubling did not converge")
        # The measurement update in decimals too: a - a^2/(a + r) cancels badly
        # in float64 when the sensor is far better than the propagation.
        ph = [row[0] for row in x]  # P H^T, with H = [1, 0, ...]
        s = ph[0] + r[0][0]
        gain = [v / s for v in ph]
        post = [[x[i][j] - gain[i] * ph[j] for j in range(n)] for i in range(n)]
        return _as_float(x), _as_float(post), np.array([float(v) for v in gain])


# ----------------------------------------------------------- comparisons


def closed_form_covariances(acc):
    """Pre- and post-update 2x2 covariances (attitude, bias) from a result."""
    def cov(att, bias, ab):
        return np.array([[att**2, ab], [ab, bias**2]])
    return (cov(acc.attitude_pre_rad, acc.bias_pre_rad_s, acc.attitude_bias_pre_rad2_s),
            cov(acc.attitude_post_rad, acc.bias_post_rad_s, acc.attitude_bias_post_rad2_s))


def assert_matches(acc, p_pre, p_post, k, rel):
    """Closed form ``acc`` against reference pre/post covariances and gain."""
    want_pre, want_post = closed_form_covariances(acc)
    np.testing.assert_allclose(want_pre, p_pre[:2, :2], rtol=rel, atol=0)
    np.testing.assert_allclose(want_post, p_post[:2, :2], rtol=rel, atol=0)
    assert acc.gain_attitude == pytest.approx(k[0], rel=rel)
    assert acc.gain_bias_per_s == pytest.approx(k[1], rel=rel)
    # With readout noise, the attitude update carried forward is the attitude
    # gain plus that of the readout error (the third state re-enters the
    # attitude in the next propagation); without, it is all of it. The two
    # partly cancel, so the sum is known to ``rel`` of the larger.
    carried = k[0] + (k[2] if len(k) == 3 else 0.0)
    assert acc.gain_attitude_propagated == pytest.approx(carried, rel=rel, abs=rel * k[0])


def log_uniform(lo, hi):
    return st.floats(math.log10(lo), math.log10(hi)).map(lambda e: 10.0**e)


# Spans far past any real gyro or sensor: ARW 1e-9..1e-3 rad/s^0.5
# (2e-4..200 deg/h^0.5), RRW 1e-14..1e-6 rad/s^1.5, sensor 1e-7..1e-2 rad
# (0.02"..0.6 deg), sample 1 ms..1000 s.
SIGMA_V = log_uniform(1e-9, 1e-3)
SIGMA_U = log_uniform(1e-14, 1e-6)
SIGMA_N = log_uniform(1e-7, 1e-2)
SIGMA_E = log_uniform(1e-8, 1e-3)
DT = log_uniform(1e-3, 1e3)


# ------------------------------------------- (a) closed form = exact DARE


@settings(max_examples=150, deadline=None, derandomize=True)
@given(sv=SIGMA_V, su=SIGMA_U, sn=SIGMA_N, dt=DT)
def test_farrenkopf_is_the_riccati_steady_state(sv, su, sn, dt):
    ref = doubling_dare(*model(sv, su, sn, dt, num=D))
    assert_matches(ea.farrenkopf(sv, su, sn, dt), *ref, rel=1e-9)


@settings(max_examples=150, deadline=None, derandomize=True)
@given(sv=SIGMA_V, su=SIGMA_U, sn=SIGMA_N, se=st.just(0.0) | SIGMA_E, dt=DT)
def test_rate_integrating_is_the_riccati_steady_state(sv, su, sn, se, dt):
    ref = doubling_dare(*model(sv, su, sn, dt, sigma_e=se, num=D))
    assert_matches(ea.rate_integrating(sv, su, sn, se, dt), *ref, rel=1e-9)


# Moderate points (S_u 1e-3..0.1, S_v 0..1), where the plain recursion
# settles within a few thousand steps and scipy's DARE is well conditioned.
MODERATE = [  # sigma_v [rad/s^0.5], sigma_u [rad/s^1.5], sigma_n [rad], sigma_e [rad], dt [s]
    (1e-6, 1e-9, 1e-5, 3e-6, 4.0),
    (3e-6, 1e-7, 1e-5, 1e-5, 0.5),
    (1e-7, 1e-10, 1e-6, 3e-7, 10.0),
    (1e-4, 1e-6, 1e-4, 1e-6, 1.0),
    (0.0, 1e-9, 1e-5, 1e-5, 100.0),
]


@pytest.mark.parametrize("sv, su, sn, se, dt", MODERATE)
@pytest.mark.parametrize("readout", [False, True])
def test_closed_forms_match_plain_recursion_and_scipy(sv, su, sn, se, dt, readout):
    phi, q, h, r = model(sv, su, sn, dt, sigma_e=se if readout else None)
    acc = (ea.rate_integrating(sv, su, sn, se, dt) if readout
           else ea.farrenkopf(sv, su, sn, dt))
    for p in (riccati_loop(phi, q, h, r, steps=5000), scipy_dare(phi, q, h, r)):
        assert_matches(acc, p, *update(p, h, r), rel=1e-9)


@pytest.mark.parametrize("sv, su, sn, se, dt", MODERATE)
@pytest.mark.parametrize("readout", [False, True])
def test_doubling_reference_agrees_with_plain_recursion_and_scipy(sv, su, sn, se, dt, readout):
    e = se if readout else None
    phi, q, h, r = model(sv, su, sn, dt, sigma_e=e)
    p_pre, _, _ = doubling_dare(*model(sv, su, sn, dt, sigma_e=e, num=D))
    for p in (riccati_loop(phi, q, h, r, steps=5000), scipy_dare(phi, q, h, r)):
        np.testing.assert_allclose(p, p_pre, rtol=1e-9, atol=1e-9 * np.max(np.abs(p_pre)))


def test_no_bias_walk_leaves_no_bias_error():
    # sigma_u = 0: the bias is a constant, learned exactly in the limit; the
    # attitude filter is then a random walk observed in white noise.
    acc = ea.farrenkopf(1e-6, 0.0, 1e-5, 1.0)
    assert acc.bias_pre_rad_s == acc.bias_post_rad_s == 0.0
    p_pre, _, _ = doubling_dare(*model(1e-6, 0.0, 1e-5, 1.0, num=D))
    assert acc.attitude_pre_rad**2 == pytest.approx(p_pre[0, 0], rel=1e-9)
    # Scalar random walk q = sigma_v^2 dt seen with noise r: P^- = q/2 + sqrt(q^2/4 + q r).
    q0, r0 = (1e-6) ** 2 * 1.0, (1e-5) ** 2
    assert acc.attitude_pre_rad**2 == pytest.approx(q0 / 2 + math.sqrt(q0**2 / 4 + q0 * r0),
                                                    rel=1e-12)


# --------------------------------------------------- (b) continuous limit

CONTINUOUS = [  # sigma_v [rad/s^0.5], sigma_u [rad/s^1.5], N [rad/Hz^0.5]
    (1e-6, 1e-9, 1e-5),
    (1e-7, 1e-11, 3e-6),
    (0.0, 1e-10, 1e-5),
    (1e-5, 0.0, 1e-6),
]


@pytest.mark.parametrize("sv, su, density", CONTINUOUS)
def test_continuous_is_the_kalman_bucy_steady_state(sv, su, density):
    f = np.array([[0.0, -1.0], [0.0, 0.0]])
    q = np.diag([sv**2, su**2])
    p = scipy.linalg.solve_continuous_are(f.T, np.array([[1.0], [0.0]]), q, [[density**2]])
    c = ea.continuous(sv, su, density)
    assert c.attitude_rad**2 == pytest.approx(p[0, 0], rel=1e-9)
    assert c.attitude_bias_rad2_s == pytest.approx(p[0, 1], rel=1e-9)
    assert c.bias_rad_s**2 == pytest.approx(p[1, 1], rel=1e-9, abs=1e-300)


@pytest.mark.parametrize("sv, su, density", CONTINUOUS[:3])
def test_discrete_tends_to_continuous_as_dt_shrinks(sv, su, density):
    c = ea.continuous(sv, su, density)
    # Filter time constant [s]: xi - 1 ~ dt / (2 tau) as dt -> 0.
    tau_s = density / math.sqrt(sv**2 + 2.0 * su * density)
    for k in range(2, 7):
        dt = tau_s * 10.0**-k
        d = ea.farrenkopf(sv, su, density / math.sqrt(dt), dt)  # sigma_n^2 dt = N^2
        pairs = [(d.attitude_pre_rad, c.attitude_rad), (d.attitude_post_rad, c.attitude_rad),
                 (d.bias_pre_rad_s, c.bias_rad_s), (d.bias_post_rad_s, c.bias_rad_s),
                 (d.attitude_bias_pre_rad2_s, c.attitude_bias_rad2_s),
                 (d.attitude_bias_post_rad2_s, c.attitude_bias_rad2_s)]
        for got, limit in pairs:
            assert abs(got / limit - 1.0) <= dt / tau_s
        # Pre-update above the limit, post-update below it.
        assert d.attitude_post_rad < c.attitude_rad < d.attitude_pre_rad


# ---------------------------------------------------- (c) sigma_e -> 0


def _farrenkopf_as_published(sv, su, sn, dt):
    """Farrenkopf's steady state written out as his paper gives it, with no care for digits.

    gamma = sqrt(4 + S_v^2 + S_u^2/12), xi = (gamma + S_u/2 + sqrt(S_u gamma + S_v^2 +
    S_u^2/3)) / 2; post-update attitude variance sigma_n^2 (1 - xi^-2), bias variance
    (sigma_n/dt)^2 (S_u (xi - 1/xi) - S_u^2/2) (docs/kalman.md, the table).
    """
    s_u, s_v = su * dt**1.5 / sn, sv * math.sqrt(dt) / sn
    gamma = math.sqrt(4 + s_v**2 + s_u**2 / 12)
    xi = 0.5 * (gamma + s_u / 2 + math.sqrt(s_u * gamma + s_v**2 + s_u**2 / 3))
    return (math.sqrt(sn**2 * (1 - xi**-2)),
            math.sqrt((sn / dt) ** 2 * (s_u * (xi - 1 / xi) - s_u**2 / 2)), xi)


@settings(max_examples=100, deadline=None, derandomize=True)
@given(sv=log_uniform(1e-7, 1e-4), su=log_uniform(1e-11, 1e-8), sn=log_uniform(1e-6, 1e-3),
       dt=log_uniform(1e-1, 1e1))
def test_rate_integrating_without_readout_is_farrenkopfs_published_form(sv, su, sn, dt):
    """sigma_e = 0 against the paper's expressions evaluated naively, where they keep
    their digits (S_u and S_v between ~1e-7 and ~10: no cancellation worse than 1e-8)."""
    att, bias, xi = _farrenkopf_as_published(sv, su, sn, dt)
    got = ea.rate_integrating(sv, su, sn, 0.0, dt)
    assert float(got.xi) == pytest.approx(xi, rel=1e-12)
    assert float(got.attitude_post_rad) == pytest.approx(att, rel=1e-6)
    assert float(got.bias_post_rad_s) == pytest.approx(bias, rel=1e-5)


@settings(max_examples=100, deadline=None, derandomize=True)
@given(sv=SIGMA_V, su=SIGMA_U, sn=SIGMA_N, dt=DT)
def test_rate_integrating_is_continuous_in_the_readout_noise(sv, su, sn, dt):
    """sigma_e -> 0: sigma_e^2 enters as a fraction of R = sigma_n^2 + sigma_e^2 and of
    the attitude variance, 1e-14 of either here."""
    f = ea.rate_integrating(sv, su, sn, 0.0, dt)
    small = ea.rate_integrating(sv, su, sn, 1e-7 * f.attitude_post_rad, dt)
    for got, want in zip(small, f):
        assert got == pytest.approx(want, rel=1e-12, abs=0)


# ---------------------------------------------------- (d) invariants


@settings(max_examples=100, deadline=None, derandomize=True)
@given(sv=SIGMA_V, su=SIGMA_U, sn=SIGMA_N, se=SIGMA_E, dt=DT,
       which=st.sampled_from(["sv", "su", "sn", "se"]), factor=st.floats(1.0, 100.0))
def test_more_noise_never_helps(sv, su, sn, se, dt, which, factor):
    base = {"sv": sv, "su": su, "sn": sn, "se": se}
    worse = {**base, which: base[which] * factor}
    a = ea.rate_integrating(base["sv"], base["su"], base["sn"], base["se"], dt)
    b = ea.rate_integrating(worse["sv"], worse["su"], worse["sn"], worse["se"], dt)
    slack = 1.0 + 1e-12  # rounding when the change is negligible
    for name in ("attitude_pre_rad", "attitude_post_rad", "bias_pre_rad_s", "bias_post_rad_s"):
        assert getattr(b, name) * slack >= getattr(a, name), name


@settings(max_examples=100, deadline=None, derandomize=True)
@given(sv=SIGMA_V, su=SIGMA_U, sn=SIGMA_N, se=SIGMA_E, dt=DT)
def test_fewer_samples_never_help(sv, su, sn, se, dt):
    # Every second sample dropped: the data are a subset, the sample instants
    # a subset of the old ones.
    a = ea.rate_integrating(sv, su, sn, se, dt)
    b = ea.rate_integrating(sv, su, sn, se, 2.0 * dt)
    slack = 1.0 + 1e-12
    for name in ("attitude_pre_rad", "attitude_post_rad", "bias_pre_rad_s", "bias_post_rad_s"):
        assert getattr(b, name) * slack >= getattr(a, name), name


@settings(max_examples=100, deadline=None, derandomize=True)
@given(sv=SIGMA_V, su=SIGMA_U, sn=SIGMA_N, se=st.just(0.0) | SIGMA_E, dt=DT)
def test_update_shrinks_and_gains_are_bounded(sv, su, sn, se, dt):
    a = ea.rate_integrating(sv, su, sn, se, dt)
    assert a.attitude_post_rad <= a.attitude_pre_rad
    assert a.attitude_post_rad <= sn  # never worse than the sensor alone
    assert a.bias_post_rad_s <= a.bias_pre_rad_s
    assert 0.0 <= a.gain_attitude_propagated <= a.gain_attitude < 1.0
    assert a.gain_bias_per_s <= 0.0
    assert a.xi >= 1.0
    # Positive semi-definite covariances (Cauchy-Schwarz), to rounding.
    slack = 1.0 + 1e-12
    assert a.attitude_bias_pre_rad2_s**2 <= (a.attitude_pre_rad * a.bias_pre_rad_s) ** 2 * slack
    assert a.attitude_bias_post_rad2_s**2 <= (a.attitude_post_rad * a.bias_post_rad_s) ** 2 * slack


@settings(max_examples=100, deadline=None, derandomize=True)
@given(sv=SIGMA_V, su=SIGMA_U, sn=SIGMA_N, se=SIGMA_E, dt=DT,
       lam=log_uniform(1e-3, 1e3), mu=log_uniform(1e-3, 1e3))
def test_units_scale(sv, su, sn, se, dt, lam, mu):
    a = ea.rate_integrating(sv, su, sn, se, dt)
    angle = ea.rate_integrating(lam * sv, lam * su, lam * sn, lam * se, dt)
    time = ea.rate_integrating(sv / math.sqrt(mu), su / mu**1.5, sn, se, mu * dt)
    rel = 1e-11
    assert angle.attitude_post_rad == pytest.approx(lam * a.attitude_post_rad, rel=rel)
    assert angle.bias_pre_rad_s == pytest.approx(lam * a.bias_pre_rad_s, rel=rel)
    assert angle.attitude_bias_post_rad2_s == pytest.approx(lam**2 * a.attitude_bias_post_rad2_s,
                                                            rel=rel)
    assert angle.gain_attitude == pytest.approx(a.gain_attitude, rel=rel)
    assert time.attitude_pre_rad == pytest.approx(a.attitude_pre_rad, rel=rel)
    assert time.attitude_post_rad == pytest.approx(a.attitude_post_rad, rel=rel)
    assert time.bias_pre_rad_s == pytest.approx(a.bias_pre_rad_s / mu, rel=rel)
    assert time.gain_bias_per_s == pytest.approx(a.gain_bias_per_s / mu, rel=rel)
    assert time.attitude_bias_pre_rad2_s == pytest.approx(a.attitude_bias_pre_rad2_s / mu, rel=rel)


def test_broadcasts_over_arrays():
    sn = np.array([1e-6, 1e-5, 1e-4])
    acc = ea.rate_integrating(1e-6, 1e-9, sn[:, None], np.array([0.0, 1e-5]), 1.0)
    assert acc.attitude_post_rad.shape == (3, 2)
    for i, j in np.ndindex(3, 2):
        one = ea.rate_integrating(1e-6, 1e-9, sn[i], [0.0, 1e-5][j], 1.0)
        assert acc.attitude_post_rad[i, j] == one.attitude_post_rad


@pytest.mark.parametrize("key, value", [
    ("sigma_n_rad", 0.0), ("dt_s", 0.0), ("sigma_v_rad_rt_s", -1e-6),
    ("sigma_u_rad_s_rt_s", float("nan")), ("sigma_e_rad", -1.0), ("dt_s", float("inf")),
])
def test_bad_input_raises(key, value):
    args = {"sigma_v_rad_rt_s": 1e-6, "sigma_u_rad_s_rt_s": 1e-9, "sigma_n_rad": 1e-5,
            "sigma_e_rad": 1e-6, "dt_s": 1.0}
    with pytest.raises(ValueError, match=key):
        ea.rate_integrating(**{**args, key: value})


def test_quantization_sigma_is_uniform_over_one_pulse():
    # Variance of a uniform distribution of width w: w^2 / 12.
    w_rad = 0.1 * units.ARCSEC2RAD  # default vfc_pulse_weight_arcsec
    assert ea.quantization_sigma_rad(w_rad) == pytest.approx(w_rad / math.sqrt(12.0), rel=1e-15)
    frac = (np.arange(100_000) * (math.sqrt(5.0) - 1.0) / 2.0) % 1.0  # equidistributed on [0, 1)
    assert np.std(frac * w_rad) == pytest.approx(ea.quantization_sigma_rad(w_rad), rel=1e-3)


# ----------------------------------------------------------- Monte Carlo


def test_monte_carlo_rate_integrating_gyro_shows_the_predicted_sigmas():
    """Simulate truth, gyro angle readout and sensor; filter with the closed-form gains."""
    sv, su, sn, se, dt = 2e-6, 2e-8, 1e-5, 8e-6, 1.0  # S_v ~ 0.16, S_u ~ 1.6e-3, xi ~ 1.09
    acc = ea.rate_integrating(sv, su, sn, se, dt)
    rng = np.random.default_rng(20000601)
    chains, steps = 20_000, 800  # slowest closed-loop mode 0.99 per step
    _, q, _, _ = model(sv, su, sn, dt)
    # The increments of (drift angle, bias) over a step are jointly Gaussian
    # with the covariance of the integrated noises (q with the sign of the
    # drift angle flipped back: it adds to the gyro angle).
    chol = np.linalg.cholesky(np.array(q) * np.array([[1.0, -1.0], [-1.0, 1.0]]))
    rate_rad_s = rng.uniform(-1e-3, 1e-3, chains)  # any motion: the gyro cancels it
    theta = np.zeros(chains)
    drift_angle = np.zeros(chains)  # gyro angle - true angle
    bias = np.zeros(chains)  # errors start at zero and grow to the steady state
    g_hat = np.zeros(chains)  # estimate of (true angle - gyro readout + readout error)
    bias_hat = np.zeros(chains)
    for _ in range(steps):
        w = chol @ rng.standard_normal((2, chains))
        theta = theta + rate_rad_s * dt
        drift_angle = drift_angle + bias * dt + w[0]
        bias = bias + w[1]
        readout = theta + drift_angle + rng.normal(0.0, se, chains)  # counter 14/16/18
        sensor = theta + rng.normal(0.0, sn, chains)  # star tracker 105
        g_hat = g_hat - bias_hat * dt
        att_pre = readout + g_hat
        innovation = sensor - att_pre
        att_post = att_pre + acc.gain_attitude * innovation
        bias_pre = bias_hat
        g_hat = g_hat + acc.gain_attitude_propagated * innovation  # carried forward
        bias_hat = bias_hat + acc.gain_bias_per_s * innovation
    # The last step, long after the transient: one draw per chain. 20000
    # independent chains estimate a sigma to 0.5 % (1 sigma); allow 3 %.
    assert np.std(theta - att_pre) == pytest.approx(acc.attitude_pre_rad, rel=0.03)
    assert np.std(theta - att_post) == pytest.approx(acc.attitude_post_rad, rel=0.03)
    assert np.std(bias - bias_pre) == pytest.approx(acc.bias_pre_rad_s, rel=0.03)
    assert np.std(bias - bias_hat) == pytest.approx(acc.bias_post_rad_s, rel=0.03)
