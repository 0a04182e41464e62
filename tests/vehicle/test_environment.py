"""The orbit's environment against closed forms: the shadow, the Earth's disk, the torques."""

import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from allsky import clock
from allsky.config.scenario import load_scenario
from allsky.sim.mission import build_params
from allsky.vehicle import environment as env
from allsky.vehicle import orbit, sky

ORBIT = ['orbit.kind="circular"', "orbit.j2=false", "orbit.altitude_km=300.0",
         "orbit.inclination_deg=28.5", "orbit.raan_deg=40.0", "orbit.arg_latitude_deg=10.0"]


@pytest.fixture(scope="module")
def flown():
    cfg = load_scenario(overrides=ORBIT)
    return cfg, build_params(cfg)


def _plane(cfg):
    """(p, q, h): the node, the in-plane normal to it, the orbit normal (unit vectors)."""
    o = cfg.orbit
    node, inc = math.radians(o.raan_deg), math.radians(o.inclination_deg)
    p = np.array([math.cos(node), math.sin(node), 0.0])
    h = np.array([math.sin(inc) * math.sin(node), -math.sin(inc) * math.cos(node),
                  math.cos(inc)])
    return p, np.cross(h, p), h


def _crossings(cfg, direction_at, theta_of, t_max):
    """Times [s] where the angle between the nadir and ``direction_at(t)`` passes
    ``theta_of(t)``, entering (angle falling) and leaving, from the orbit's plane alone."""
    p, q, h = _plane(cfg)
    a = orbit.R_EARTH_M + cfg.orbit.altitude_km * 1000.0
    n = math.sqrt(orbit.MU_EARTH_M3_S2 / a**3)
    u0 = math.radians(cfg.orbit.arg_latitude_deg)
    period = 2 * math.pi / n
    out = []
    for sign in (+1, -1):  # entry at u - u_s = phi, exit at 2 pi - phi
        for rev in range(int(t_max / period) + 2):
            t = 0.0
            for _ in range(4):  # the direction moves (the Sun): iterate on the time
                s = direction_at(t)
                beta = math.asin(float(s @ h))
                u_s = math.atan2(float(s @ q), float(s @ p))
                phi = math.acos(-math.cos(theta_of(t)) / math.cos(beta))
                du = (phi if sign > 0 else 2 * math.pi - phi) + u_s - u0
                t = (du % (2 * math.pi)) / n + (rev - 1) * period
            if 0.0 <= t <= t_max:
                out.append((round(t, 6), "in" if sign > 0 else "out"))
    return sorted(set(out))


def _first_frames(mask):
    """Frames where a boolean series turns true and turns false."""
    d = np.diff(mask.astype(np.int8))
    return np.nonzero(d > 0)[0] + 1, np.nonzero(d < 0)[0] + 1


def test_eclipse_entry_and_exit_are_the_conical_shadows_closed_form(flown):
    cfg, p = flown
    o = p.orbit
    ck = p.clock
    t_max = 7000.0
    frames = clock.frame_at(ck, t_max)
    f = env.sunlit_series(o, 0, frames)
    dt = p.frame_s
    a = orbit.R_EARTH_M + cfg.orbit.altitude_km * 1000.0
    a_e = math.asin((orbit.R_EARTH_M + cfg.orbit.atmosphere_height_km * 1000.0) / a)
    a_s = float(o.scalars[0, env.SUN_RADIUS])

    def sun_at(t):
        s = p.sun0_inertial + p.sun_rate_inertial * t
        return s / np.linalg.norm(s)

    checked = 0
    for theta, mask in ((a_e + a_s, f < 1.0), (a_e - a_s, f <= 0.0), (a_e, f < 0.5)):
        expected = _crossings(cfg, sun_at, lambda t, th=theta: th, t_max - 1.0)
        on, off = _first_frames(mask)
        got = sorted([(k * dt, "in") for k in on] + [(k * dt, "out") for k in off])
        assert len(got) == len(expected) >= 3, (got, expected)
        for (tg, kg), (te, ke) in zip(got, expected):
            assert kg == ke
            # the frame after the crossing; the Sun from the vehicle, not the Earth's centre,
            # moves it by 9.7" / (0.066 deg/s) = 0.04 s
            assert abs(tg - te) <= 0.1, (tg, te)
            checked += 1
    assert checked >= 9


def test_the_earth_occults_canopus_at_the_geometric_time(flown):
    cfg, p = flown
    o = p.orbit
    canopus = sky.star_direction_inertial("Canopus", cfg.mission.date_utc)
    a = orbit.R_EARTH_M + cfg.orbit.altitude_km * 1000.0
    a_e = math.asin((orbit.R_EARTH_M + cfg.orbit.atmosphere_height_km * 1000.0) / a)
    t_max = 7000.0
    frames = clock.frame_at(p.clock, t_max)
    hidden = env.occulted_series(o, canopus[None, :].copy(), 0, frames)[:, 0]
    on, off = _first_frames(hidden)
    got = sorted([(k * p.frame_s, "in") for k in on] + [(k * p.frame_s, "out") for k in off])
    expected = _crossings(cfg, lambda t: canopus, lambda t: a_e, t_max - 1.0)
    assert len(got) == len(expected) >= 2
    for (tg, kg), (te, ke) in zip(got, expected):
        assert kg == ke and abs(tg - te) <= 0.02, (tg, te)


def test_the_earth_occults_jupiter_at_the_geometric_time():
    """A moving body's row, held per sample interval, is hidden when the closed form says.

    Jupiter on 2026-11-28, inside a window that passes it; from 6678 km its
    parallax is 0.002", so its direction from the Earth's centre is the
    closed form's.
    """
    from allsky.sim import sky_rows
    from allsky.vehicle import bodies

    date = ["mission.date_utc=2026-11-28T00:00:00Z",
            "star_tracker.magnitude_window=[-2.5,-0.3]"]
    cfg = load_scenario(overrides=[*ORBIT[:-1], "orbit.arg_latitude_deg=210.0", *date])
    p = build_params(cfg)
    o = p.orbit
    j = sky_rows.sky_rows(cfg).body_names.index("Jupiter")
    t_max = 7000.0
    hidden = env.occulted_bodies_series(o, 0, clock.frame_at(p.clock, t_max))[:, j]
    on, off = _first_frames(hidden)
    got = sorted([(k * p.frame_s, "in") for k in on] + [(k * p.frame_s, "out") for k in off])

    def jupiter_at(t):
        r = bodies.from_earth_km("Jupiter", cfg.mission.date_utc, t)
        return r / np.linalg.norm(r)
    a = orbit.R_EARTH_M + cfg.orbit.altitude_km * 1000.0
    a_e = math.asin((orbit.R_EARTH_M + cfg.orbit.atmosphere_height_km * 1000.0) / a)
    expected = _crossings(cfg, jupiter_at, lambda t: a_e, t_max - 1.0)
    assert len(got) == len(expected) >= 2
    for (tg, kg), (te, ke) in zip(got, expected):
        assert kg == ke and abs(tg - te) <= 0.02, (tg, te)


def test_the_visible_fraction_is_the_overlap_of_two_disks():
    a_s, a_e = 0.00465, 1.2
    assert env.visible_fraction(a_e + a_s + 1e-9, a_s, a_e) == 1.0
    assert env.visible_fraction(a_e - a_s - 1e-9, a_s, a_e) == 0.0
    # the Sun's centre on the limb: half its disk, to the limb's curvature over it
    assert env.visible_fraction(a_e, a_s, a_e) == pytest.approx(0.5, abs=2e-3)
    # monotonic across the penumbra
    cs = np.linspace(a_e - a_s, a_e + a_s, 101)
    fs = [env.visible_fraction(c, a_s, a_e) for c in cs]
    assert all(b >= a for a, b in itertools.pairwise(fs))


def _random_inertia(rnd):
    d = np.diag(rnd.uniform(50, 800, 3))
    q, _ = np.linalg.qr(rnd.standard_normal((3, 3)))
    return q, d, q @ d @ q.T


@settings(max_examples=50, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), alt=st.floats(150, 1000))
def test_gravity_gradient_is_its_closed_form_on_the_principal_axes(seed, alt):
    rnd = np.random.default_rng(seed)
    q, d, j = _random_inertia(rnd)
    n_b = rnd.standard_normal(3)
    n_b /= np.linalg.norm(n_b)
    r = orbit.R_EARTH_M + alt * 1000.0
    gg = 3.0 * orbit.MU_EARTH_M3_S2 / r**3
    out = np.zeros(3)
    mag = env.gravity_gradient(gg, np.ascontiguousarray(j), n_b, out)
    # the principal axes: 3 mu / r^3 [(Iz - Iy) ny nz, (Ix - Iz) nz nx, (Iy - Ix) nx ny]
    nx, ny, nz = q.T @ n_b
    ix, iy, iz = np.diag(d)
    closed = gg * np.array([(iz - iy) * ny * nz, (ix - iz) * nz * nx, (iy - ix) * nx * ny])
    expected = q @ closed
    scale = gg * (np.diag(d).max() - np.diag(d).min())
    assert np.abs(out - expected).max() <= 1e-9 * scale
    assert mag == pytest.approx(np.linalg.norm(expected), rel=1e-9, abs=1e-9 * scale)


def test_the_issues_gravity_gradient_figure():
    # Iz - Ix = 580 kg m^2 at 300 km, the Earth 45 deg off both: 1.2e-3 N m about pitch
    r = orbit.R_EARTH_M + 300e3
    gg = 3.0 * orbit.MU_EARTH_M3_S2 / r**3
    j = np.diag([100.0, 650.0, 680.0])
    n_b = np.array([1.0, 0.0, 1.0]) / math.sqrt(2.0)
    out = np.zeros(3)
    env.gravity_gradient(gg, j, n_b, out)
    assert out[1] == pytest.approx(-gg * 580.0 / 2.0, rel=1e-12)
    assert abs(out[1]) == pytest.approx(1.16e-3, rel=0.01)


def test_the_atmosphere_is_its_table():
    assert env.density_kg_m3(300e3) == pytest.approx(2.418e-11, rel=1e-12)
    # one scale height above the base: 1/e
    assert env.density_kg_m3(353.628e3 - 3.628e3 + 0.0) == pytest.approx(9.518e-12, rel=1e-12)
    h = 320e3
    assert env.density_kg_m3(h) == pytest.approx(2.418e-11 * math.exp(-20 / 53.628), rel=1e-12)


@pytest.fixture(scope="module")
def with_jupiter():
    """The orbit of the Jupiter occultation above, with its moving bodies' rows."""
    date = ["mission.date_utc=2026-11-28T00:00:00Z",
            "star_tracker.magnitude_window=[-2.5,-0.3]"]
    cfg = load_scenario(overrides=[*ORBIT[:-1], "orbit.arg_latitude_deg=210.0", *date])
    return build_params(cfg).orbit


def _steps_frame_by_frame(o, dirs, cols, first, last, seen):
    """The steps of occultation_steps from the frame-by-frame series, as the journal took them."""
    hidden = env.occulted_series(o, dirs, first, last)
    hidden = np.hstack([hidden, env.occulted_bodies_series(o, first, last)[:, cols]])
    steps = np.diff(np.vstack([seen[None, :], hidden]).astype(np.int8), axis=0)
    k, j = np.nonzero(steps)
    return np.stack([k, j, (steps[k, j] > 0).astype(np.int64)], axis=1), hidden[-1]


@settings(max_examples=40, deadline=None)
@given(first=st.integers(0, 600_000), length=st.integers(1, 60_000),
       grazing=st.lists(st.tuples(st.integers(0, 700_000), st.floats(-2e-4, 2e-4),
                                  st.floats(0.0, 2 * math.pi)), max_size=4),
       free=st.lists(st.tuples(st.floats(-1, 1), st.floats(0, 2 * math.pi)), max_size=2),
       seen_bits=st.integers(0, 255))
def test_the_journal_s_occultation_steps_are_the_frame_by_frame_series(
        with_jupiter, first, length, grazing, free, seen_bits):
    """occultation_steps skips only frames where no row can cross the limb: the same steps.

    Directions are drawn at random and on the Earth's limb at random frames
    (``grazing``: within 2e-4 rad of it, where a frame's 5e-5 rad of motion
    decides), ranges run past the last sample (the place held), and the rows
    start hidden or not at random.
    """
    o = with_jupiter
    a_e = float(np.arccos(o.scalars[0, env.EARTH_COS]))
    dirs = []
    for f, delta, turn in grazing:
        k, w = env.place(o, f)
        n = np.empty(3)
        env._lerp_unit(o.nadir_i, k, w, n)
        u = np.cross(n, [0.0, 0.0, 1.0])
        u /= np.linalg.norm(u)
        v = np.cross(n, u)
        side = math.cos(turn) * u + math.sin(turn) * v
        dirs.append(math.cos(a_e + delta) * n + math.sin(a_e + delta) * side)
    for z, lon in free:
        r = math.sqrt(1 - z * z)
        dirs.append([r * math.cos(lon), r * math.sin(lon), z])
    dirs = np.ascontiguousarray(np.array(dirs, dtype=float).reshape(-1, 3))
    cols = np.nonzero(o.body_rows >= 0)[0]
    assert cols.shape[0] >= 1  # Jupiter moves in this window
    rows = dirs.shape[0] + cols.shape[0]
    seen = np.array([(seen_bits >> i) & 1 for i in range(rows)], dtype=bool)
    last = first + length
    got, state = env.occultation_steps(o, dirs, cols, first, last, seen)
    want, want_state = _steps_frame_by_frame(o, dirs, cols, first, last, seen)
    np.testing.assert_array_equal(got, want)
    np.testing.assert_array_equal(state, want_state)


def test_the_umbra_flag_is_a_bound_every_frame_between_is_dark(flown):
    """UMBRA only skips work: every frame of a flagged interval has visible_fraction 0.

    The frames' angles are interpolated as the loop interpolates them
    (``a + w (b - a)``, ``w = j / step``); visible_fraction is 0 exactly where
    the Sun's disk lies within the Earth's (``c <= a_e - a_s``).
    """
    o = flown[1].orbit
    sc = o.scalars
    ks = np.nonzero(sc[:-1, env.UMBRA])[0]
    assert ks.shape[0] > 1000  # the orbit passes the umbra, interval after interval
    w = np.arange(o.step_frames + 1) / o.step_frames

    def lerp(col):
        a, b = sc[ks, col][:, None], sc[ks + 1, col][:, None]
        return a + w * (b - a)

    c, a_e, a_s = lerp(env.SEP), lerp(env.EARTH_RADIUS), lerp(env.SUN_RADIUS)
    assert np.all(c < a_s + a_e) and np.all(c <= a_e - a_s)
    for k in ks[:: max(1, ks.shape[0] // 20)]:  # and the compiled formula says so
        for j in (0, o.step_frames // 2, o.step_frames):
            assert env.visible_fraction(float(c[ks == k, j][0]), float(a_s[ks == k, j][0]),
                                        float(a_e[ks == k, j][0])) == 0.0
    # and only the shadow's edges are left to the frames: the penumbra, a few seconds
    edge = np.nonzero((sc[:-1, env.UMBRA] == 0.0) & (sc[:-1, env.WHOLE] == 0.0))[0]
    assert edge.shape[0] < ks.shape[0] // 10


@settings(max_examples=30, deadline=None)
@given(first=st.integers(0, 600_000), length=st.integers(1, 200_000), phase=st.integers(0, 2))
def test_the_journal_s_eclipse_steps_are_the_frame_by_frame_fractions(flown, first, length,
                                                                      phase):
    """eclipse_steps passes sunlit intervals at once: the phases of sunlit_series, frame by frame."""
    o = flown[1].orbit
    assert env.eclipse_steps(o, 0, 700_000, 0)[0].shape[0] >= 4  # the draws pass the shadow
    last = first + length
    f = env.sunlit_series(o, first, last)
    phases = np.where(f >= 1.0, 0, np.where(f <= 0.0, 2, 1))
    k = np.nonzero(np.diff(np.concatenate([[phase], phases])))[0]
    at, got, fractions, end = env.eclipse_steps(o, first, last, phase)
    np.testing.assert_array_equal(at, k)
    np.testing.assert_array_equal(got, phases[k])
    np.testing.assert_array_equal(fractions, f[k])
    assert end == phases[-1]
