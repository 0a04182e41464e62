"""The orbit: SGP4 against the sgp4 package's published vectors, the circular orbit's closed form."""

import math
from datetime import datetime, timedelta
from importlib import resources

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from allsky.config.rules import ConfigError
from allsky.config.scenario import load_scenario
from allsky.vehicle import orbit


def _published_cases():
    """(line1, line2, [(minutes, r_km, v_km_s)]) of satellites 5 and 6251 (Vallado 2006)."""
    root = resources.files("sgp4")
    tle = [ln for ln in (root / "SGP4-VER.TLE").read_text().splitlines()
           if ln.startswith(("1 ", "2 "))]
    out = (root / "tcppver.out").read_text().splitlines()
    cases = {}
    sat = None
    for ln in out:
        f = ln.split()
        if len(f) == 2 and f[1] == "xx":
            sat = f[0]
            cases[sat] = []
        elif sat is not None and len(f) >= 7:
            cases[sat].append((float(f[0]), [float(x) for x in f[1:4]],
                               [float(x) for x in f[4:7]]))
    lines = {}
    for a, b in zip(tle[0::2], tle[1::2]):
        lines[a[2:7].strip().lstrip("0")] = (a[:69], b[:69])
    return [(*lines[k], cases[k]) for k in ("5", "6251")]


def _epoch(sat) -> datetime:
    jd = sat.jdsatepoch + sat.jdsatepochF
    return datetime(2000, 1, 1, 12) + timedelta(days=jd - 2451545.0)


@pytest.mark.parametrize("line1, line2, vectors", _published_cases())
def test_sgp4_positions_are_the_published_test_vectors(line1, line2, vectors):
    sat = orbit.parse_tle(line1, line2)
    date = _epoch(sat)
    minutes = np.array([m for m, _, _ in vectors])
    tr = orbit.tle_track(line1, line2, date, minutes * 60.0)
    from allsky.vehicle.ephemeris import tt_minus_utc_s

    jd0, fr0 = orbit._julian_date_utc(date)
    rot = orbit.precession_to_j2000(jd0 + fr0 + tt_minus_utc_s(date) / 86400.0)
    teme_km = tr.r_m @ rot / 1000.0  # back to TEME: rot is orthonormal
    teme_v = tr.v_m_s @ rot / 1000.0
    for k, (_, r, v) in enumerate(vectors):
        # the epoch as a datetime is good to 1 us: 8 mm along the track
        assert np.abs(teme_km[k] - r).max() < 1e-4, (minutes[k], teme_km[k], r)
        assert np.abs(teme_v[k] - v).max() < 1e-6


def test_the_precession_is_a_rotation_of_the_published_size():
    p = orbit.precession_to_j2000(2451545.0 + 36525.0)  # a century after J2000
    assert np.allclose(p @ p.T, np.eye(3), atol=1e-15)
    # general precession in longitude, 5029.0966"/century: the equinox moves along the ecliptic
    ang = math.degrees(math.acos((np.trace(p) - 1.0) / 2.0)) * 3600.0
    assert ang == pytest.approx(5029.0966, rel=2e-3)


@settings(max_examples=30, deadline=None)
@given(alt=st.floats(150, 1000), inc=st.floats(0, 180), raan=st.floats(0, 359.9),
       u0=st.floats(0, 359.9), t=st.floats(0, 86400))
def test_the_circular_orbit_is_its_closed_form(alt, inc, raan, u0, t):
    tr = orbit.circular_track(alt, inc, raan, u0, [t], j2=True)
    a = orbit.R_EARTH_M + alt * 1000.0
    n, dnode, du = orbit.circular_rates(alt, inc)
    assert n == pytest.approx(math.sqrt(orbit.MU_EARTH_M3_S2 / a**3), rel=1e-15)
    node, u, i = math.radians(raan) + dnode * t, math.radians(u0) + du * t, math.radians(inc)
    # r = Rz(node) Rx(i) [cos u, sin u, 0]
    rz = np.array([[math.cos(node), -math.sin(node), 0], [math.sin(node), math.cos(node), 0],
                   [0, 0, 1]])
    rx = np.array([[1, 0, 0], [0, math.cos(i), -math.sin(i)], [0, math.sin(i), math.cos(i)]])
    r = a * rz @ rx @ np.array([math.cos(u), math.sin(u), 0.0])
    assert np.abs(tr.r_m[0] - r).max() < 1e-9 * a * (1 + abs(du * t))
    # the velocity is the derivative of the position
    h = 1e-3
    tr2 = orbit.circular_track(alt, inc, raan, u0, [t - h, t + h], j2=True)
    dv = (tr2.r_m[1] - tr2.r_m[0]) / (2 * h)
    assert np.abs(tr.v_m_s[0] - dv).max() < 1e-4 * np.linalg.norm(dv)
    assert np.linalg.norm(tr.r_m[0]) == pytest.approx(a, rel=1e-14)


def test_j2_rates_are_the_textbook_values():
    # 300 km, 28.5 deg: -1.5 n J2 (R/a)^2 cos i by hand is -7.46 deg/day
    _, dnode, _ = orbit.circular_rates(300.0, 28.5)
    assert math.degrees(dnode) * 86400.0 == pytest.approx(-7.46, abs=0.01)
    # sun-synchronous: 98.2 deg at 700 km regresses +0.9856 deg/day
    _, dnode, _ = orbit.circular_rates(700.0, 98.19)
    assert math.degrees(dnode) * 86400.0 == pytest.approx(0.9856, abs=0.01)


@pytest.mark.parametrize("override, key", [
    ('orbit.kind="kepler"', "orbit.kind"),
    ("orbit.altitude_km=100.0", "orbit.altitude_km"),
    ("orbit.sample_s=0.0", "orbit.sample_s"),
    ('orbit.tle_line1="1 2"', "orbit.tle_line1"),
    ("orbit.inclination_deg=190.0", "orbit.inclination_deg"),
    ("orbit.srp_reflectivity=3.0", "orbit.srp_reflectivity"),
])
def test_a_bad_orbit_is_refused_naming_its_key(override, key):
    with pytest.raises(ConfigError) as e:
        load_scenario(overrides=[override])
    assert e.value.key == key


def test_a_tle_with_a_bad_checksum_is_refused():
    (l1, l2, _), _ = _published_cases()
    bad = l1[:68] + str((int(l1[68]) + 1) % 10)
    with pytest.raises(ConfigError, match="checksum"):
        load_scenario(overrides=['orbit.kind="tle"', f'orbit.tle_line1="{bad}"',
                                 f'orbit.tle_line2="{l2}"'])
    cfg = load_scenario(overrides=['orbit.kind="tle"', f'orbit.tle_line1="{l1}"',
                                   f'orbit.tle_line2="{l2}"',
                                   "mission.date_utc=2000-06-28T00:00:00Z"])
    assert cfg.orbit.kind == "tle"


def test_a_mission_far_from_the_element_sets_epoch_is_refused():
    (l1, l2, _), _ = _published_cases()  # satellite 5, epoch 2000-06-27
    with pytest.raises(ConfigError) as e:
        load_scenario(overrides=['orbit.kind="tle"', f'orbit.tle_line1="{l1}"',
                                 f'orbit.tle_line2="{l2}"'])
    assert e.value.key == "mission.date_utc" and "epoch" in str(e.value)
