"""The sky (allsky.vehicle.sky): the Sun and the bright stars against published values.

Sources, cited beside each number:

* Meeus, *Astronomical Algorithms*, 2nd ed. (Willmann-Bell, 1998):
  example 25.a (low-accuracy Sun, stated good to 0.01 deg), example 25.b
  (VSOP87 apparent Sun), example 26.b (VSOP87 Sun, rectangular, FK5 J2000),
  eq. 21.1 (annual precession m, n), eq. 22.2 (mean obliquity of J2000).
  All three examples are for 1992 October 13.0 TD = JDE 2448908.5.
* USNO / Astronomical Almanac, 2026 equinoxes and solstices (UTC):
  Mar 20 14:46, Jun 21 08:24, Sep 23 00:05, Dec 21 20:50.
* SIMBAD (ICRS, J2000, Hipparcos 2007 reduction): Canopus
  RA 06h23m57.10988s, Dec -52d41'44.3810"; proper motion of Sirius
  (-546.01, -1223.08) mas/yr (the same numbers as ephem's catalog line).
* PyEphem's bundled catalog ``ephem/stars.py`` for magnitudes: the test pins
  the catalog's values (Canopus -0.62, Sirius -1.44; SIMBAD's V magnitudes
  are -0.74 and -1.46), because the tracker's magnitude window selects on them.
"""

import math
from datetime import UTC, datetime, timedelta, timezone

import ephem
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from allsky.vehicle import sky

ARCSEC_PER_DEG = 3600.0

#: Meeus's examples are at 1992 Oct 13.0 TD; PyEphem takes UT. Delta T in 1992
#: was about 58 s (Meeus table 10.A); a 1 s error moves the Sun by 0.04".
MEEUS_1992_UTC = datetime(1992, 10, 13) - timedelta(seconds=58)

#: Mean obliquity of the ecliptic at J2000.0, 23d26'21.448" (Meeus eq. 22.2).
OBLIQUITY_J2000_DEG = 23.0 + 26.0 / 60.0 + 21.448 / 3600.0

#: Annual precession in RA (m = 3.07496 s/yr) and in Dec (n = 20.0431"/yr)
#: at J2000 (Meeus eq. 21.1), in degrees per Julian year.
PRECESSION_M_DEG_YR = 3.07496 * 15.0 / 3600.0
PRECESSION_N_DEG_YR = 20.0431 / 3600.0

J2000_UTC = datetime(2000, 1, 1, 12, 0)


def _hms_deg(h, m, s):
    return (h + m / 60.0 + s / 3600.0) * 15.0


def _dms_deg(sign, d, m, s):
    return sign * (d + m / 60.0 + s / 3600.0)


def _years_since_j2000(date_utc):
    return (date_utc - J2000_UTC).total_seconds() / (365.25 * 86400.0)


# --- the Sun ----------------------------------------------------------------


def test_sun_matches_meeus_26b_j2000_rectangular():
    # Meeus example 26.b (p. 176, full VSOP87, FK5 J2000, geometric):
    # X0 = -0.93739590, Y0 = -0.31316793, Z0 = -0.13577924 au.
    # The astrometric Sun differs from the geometric one by < 0.01" (the Sun
    # moves ~6 km about the barycentre in the 8 min of light-time); PyEphem's
    # VSOP87 is truncated to about 1". Measured: 0.23".
    meeus_au = np.array([-0.93739590, -0.31316793, -0.13577924])
    u = sky.sun_direction_inertial(MEEUS_1992_UTC)
    assert sky.separation_deg(u, meeus_au) * ARCSEC_PER_DEG < 1.0


def test_sun_j2000_differs_from_meeus_apparent_place_by_precession():
    # Meeus 25.a (low accuracy, 0.01 deg): apparent RA 13h13m31.4s, Dec -7d47'06".
    # Meeus 25.b (VSOP87):                  apparent RA 13h13m30.749s, Dec -7d47'01.74".
    # Those are of date; the J2000 direction is 7.21 yr of precession away:
    # 50.29"/yr * 7.21 yr = 363" = 0.101 deg, give or take nutation (15.9")
    # and aberration (20.5") and the ecliptic's own motion. Measured: 0.099 deg
    # (25.a) and 0.102 deg (25.b).
    u = sky.sun_direction_inertial(MEEUS_1992_UTC)
    for ra_deg, dec_deg in ((_hms_deg(13, 13, 31.4), _dms_deg(-1, 7, 47, 6.0)),
                            (_hms_deg(13, 13, 30.749), _dms_deg(-1, 7, 47, 1.74))):
        assert 0.09 < sky.separation_deg(u, sky.radec_to_unit(ra_deg, dec_deg)) < 0.112


def test_our_date_conversion_gives_meeus_julian_ephemeris_date():
    # Meeus's examples are at JDE 2448908.5 (1992 Oct 13.0 TD); the UTC date a
    # second or so either side of TD - 58 s maps there through our time scales.
    from allsky.vehicle import ephemeris

    assert ephemeris.tdb_jd(MEEUS_1992_UTC) == pytest.approx(2448908.5, abs=2.0 / 86400)


@pytest.mark.parametrize("when_utc, ra_of_date_deg, dec_sign", [
    (datetime(2026, 3, 20, 14, 46), 0.0, -1.0),   # USNO March equinox 2026
    (datetime(2026, 9, 23, 0, 5), 180.0, +1.0),   # USNO September equinox 2026
])
def test_sun_at_2026_equinoxes_is_the_precessed_equinox(when_utc, ra_of_date_deg, dec_sign):
    # At an equinox the Sun is at RA 0 / 180 of date. In J2000 coordinates that
    # point sits m*t west (RA) and n*t south/north (Dec) of the J2000 one,
    # t = 26.2 yr: RA 359.664 / 179.664 deg, Dec -0.146 / +0.146 deg (Meeus eq.
    # 21.1). Nutation (<= 17"), aberration (20.5") and the minute of rounding
    # of the published instant stay below 0.02 deg. Measured: RA 359.668 /
    # 179.660, Dec -0.144 / +0.147.
    t_yr = _years_since_j2000(when_utc)
    ra_deg, dec_deg = sky.unit_to_radec(sky.sun_direction_inertial(when_utc))
    expected_ra_deg = (ra_of_date_deg - PRECESSION_M_DEG_YR * t_yr) % 360.0
    assert abs((ra_deg - expected_ra_deg + 180.0) % 360.0 - 180.0) < 0.02
    assert dec_deg == pytest.approx(dec_sign * PRECESSION_N_DEG_YR * t_yr, abs=0.02)


@pytest.mark.parametrize("when_utc, sign", [
    (datetime(2026, 6, 21, 8, 24), +1.0),    # USNO June solstice 2026
    (datetime(2026, 12, 21, 20, 50), -1.0),  # USNO December solstice 2026
])
def test_sun_at_2026_solstices_is_at_the_obliquity(when_utc, sign):
    # Declination +-23.4393 deg (the J2000 obliquity, Meeus eq. 22.2). The
    # ecliptic of 2026 is tilted 12" from that of J2000 (47"/century), and the
    # J2000 RA is 0.34 deg short of 90/270 by precession. Measured: +-23.4353.
    ra_deg, dec_deg = sky.unit_to_radec(sky.sun_direction_inertial(when_utc))
    assert dec_deg == pytest.approx(sign * OBLIQUITY_J2000_DEG, abs=0.01)
    assert ra_deg == pytest.approx(90.0 if sign > 0 else 270.0, abs=0.5)


def test_sun_declination_extremes_over_2026():
    # Sampled daily, |Dec| peaks at the obliquity, 23.44 deg.
    decs_deg = [sky.unit_to_radec(sky.sun_direction_inertial(datetime(2026, 1, 1)
                                                              + timedelta(days=i)))[1]
                for i in range(365)]
    assert max(decs_deg) == pytest.approx(OBLIQUITY_J2000_DEG, abs=0.01)
    assert min(decs_deg) == pytest.approx(-OBLIQUITY_J2000_DEG, abs=0.01)


def test_sun_direction_is_a_unit_vector_and_timezones_are_honoured():
    naive = datetime(2026, 11, 22, 12, 0)
    u = sky.sun_direction_inertial(naive)
    assert u.shape == (3,) and np.linalg.norm(u) == pytest.approx(1.0, abs=1e-15)
    aware_utc = sky.sun_direction_inertial(naive.replace(tzinfo=UTC))
    aware_plus2 = sky.sun_direction_inertial(datetime(2026, 11, 22, 14, 0,
                                                      tzinfo=timezone(timedelta(hours=2))))
    np.testing.assert_array_equal(u, aware_utc)
    np.testing.assert_array_equal(u, aware_plus2)
    # One hour later the Sun has moved about 360 deg / 365.25 d / 24 = 0.041 deg.
    later = sky.sun_direction_inertial(naive + timedelta(hours=1))
    assert sky.separation_deg(u, later) == pytest.approx(0.041, abs=0.003)


# --- Canopus and the Sun ------------------------------------------------------


def _canopus_ecliptic_latitude_deg():
    """Canopus's J2000 ecliptic latitude from SIMBAD's position and Meeus eq. 13.4."""
    ra = math.radians(_hms_deg(6, 23, 57.10988))
    dec = math.radians(_dms_deg(-1, 52, 41, 44.3810))
    eps = math.radians(OBLIQUITY_J2000_DEG)
    return math.degrees(math.asin(math.sin(dec) * math.cos(eps)
                                  - math.cos(dec) * math.sin(eps) * math.sin(ra)))


def test_canopus_catalog_position_matches_simbad():
    # SIMBAD J2000: 06h23m57.10988s -52d41'44.3810". Measured: 0.003".
    simbad = sky.radec_to_unit(_hms_deg(6, 23, 57.10988), _dms_deg(-1, 52, 41, 44.3810))
    assert sky.separation_deg(sky.star_direction_inertial("Canopus"), simbad) * 3600 < 0.05


def test_sun_canopus_separation_over_2026():
    # Canopus lies 14.2 deg from the south ecliptic pole: ecliptic latitude
    # -75.82 deg from SIMBAD's position (computed above). The Sun runs along
    # the ecliptic, so over a year the separation swings 90 +- 14.2 deg:
    # min = |beta| = 75.8 deg, max = 180 - |beta| = 104.2 deg. Daily sampling
    # misses the extremes by < 0.002 deg (the separation is flat there); the
    # J2000 ecliptic vs that of 2026 and the Sun's ecliptic latitude add < 15".
    # Measured: min 75.821 deg (Jul 7), max 104.179 deg (Jan 6).
    beta_deg = _canopus_ecliptic_latitude_deg()
    assert beta_deg == pytest.approx(-75.82, abs=0.01)
    start = datetime(2026, 1, 1)
    seps_deg = []
    for i in range(365):
        day = start + timedelta(days=i)
        seps_deg.append(sky.separation_deg(sky.sun_direction_inertial(day),
                                           sky.star_direction_inertial("Canopus", day)))
    assert min(seps_deg) == pytest.approx(75.8, abs=0.3)
    assert max(seps_deg) == pytest.approx(104.2, abs=0.3)
    assert min(seps_deg) == pytest.approx(-beta_deg, abs=0.01)
    assert max(seps_deg) == pytest.approx(180.0 + beta_deg, abs=0.01)
    # The minimum comes when the Sun is at Canopus's ecliptic longitude
    # (105 deg, early July), the maximum half a year later (early January).
    assert start + timedelta(days=int(np.argmin(seps_deg))) == datetime(2026, 7, 7)
    assert start + timedelta(days=int(np.argmax(seps_deg))) == datetime(2026, 1, 6)


# --- the catalog ----------------------------------------------------------------


def test_catalog_magnitudes_of_canopus_and_sirius():
    assert sky.star("Canopus").magnitude == -0.62   # ephem/stars.py catalog line
    assert sky.star("Sirius").magnitude == -1.44    # ephem/stars.py catalog line


def test_magnitude_window_selects_canopus_alone():
    # In ephem's catalog the brightest stars are Sirius -1.44, Canopus -0.62,
    # Arcturus -0.05, Rigil Kentaurus -0.01, Vega 0.03. So [-1.0, -0.3]
    # holds Canopus only: Sirius is too bright, Arcturus too faint. That gap
    # (0.82 mag on the bright side, 0.57 on the faint) is what lets the
    # tracker's window pick Canopus.
    names = [s.name for s in sky.stars_in_magnitude_window(-1.0, -0.3)]
    assert names == ["Canopus"]
    brightest = sky.stars_in_magnitude_window(-5.0, 0.03)
    assert [(s.name, s.magnitude) for s in brightest] == [
        ("Sirius", -1.44), ("Canopus", -0.62), ("Arcturus", -0.05),
        ("Rigil Kentaurus", -0.01), ("Vega", 0.03)]
    # Inclusive at both ends.
    assert [s.name for s in sky.stars_in_magnitude_window(-0.62, -0.62)] == ["Canopus"]
    assert sky.stars_in_magnitude_window(-5.0, -2.0) == []


def test_magnitude_window_is_sorted_and_consistent_with_star():
    window = sky.stars_in_magnitude_window(-2.0, 2.0, datetime(2026, 1, 1))
    mags = [s.magnitude for s in window]
    assert mags == sorted(mags) and all(-2.0 <= m <= 2.0 for m in mags)
    for s in window:
        assert sky.star(s.name, datetime(2026, 1, 1)) == s


def test_star_names_sorted_and_complete():
    names = sky.star_names()
    assert list(names) == sorted(names)
    # PyEphem's names, each star once: its variant spellings resolve to the name kept.
    assert set(names) | set(sky.VARIANT_NAMES) == set(ephem.stars.stars)
    assert {"Canopus", "Sirius", "Rigil Kentaurus"} <= set(names)


def test_star_lookup_is_case_insensitive_and_returns_catalog_spelling():
    assert sky.star("canopus") == sky.star("CANOPUS") == sky.star(" Canopus ")
    assert sky.star("rigil kentaurus").name == "Rigil Kentaurus"


def test_unknown_star_suggests_nearest_names():
    with pytest.raises(KeyError) as exc:
        sky.star("Canopis")
    msg = exc.value.args[0]
    assert "Canopis" in msg and "Canopus" in msg
    with pytest.raises(KeyError, match="Xyzzy"):
        sky.star_direction_inertial("Xyzzy")


def test_star_default_date_is_j2000_and_proper_motion_is_applied():
    assert sky.star("Sirius") == sky.star("Sirius", J2000_UTC)
    # Sirius: (-546.01, -1223.08) mas/yr (SIMBAD), i.e. 1.3394"/yr; 2000.0 to
    # 2026.0 is 26.0 yr: 34.83". Measured: 34.82".
    moved_arcsec = sky.separation_deg(
        sky.star_direction_inertial("Sirius"),
        sky.star_direction_inertial("Sirius", datetime(2026, 1, 1, 12))) * ARCSEC_PER_DEG
    expected_arcsec = _years_since_j2000(datetime(2026, 1, 1, 12)) * math.hypot(0.54601, 1.22308)
    assert moved_arcsec == pytest.approx(expected_arcsec, abs=0.05)


# --- dates --------------------------------------------------------------------


def test_check_date_range():
    assert sky.EPHEMERIS_YEARS == (1900, 2100)
    sky.check_date(datetime(2026, 11, 22, 12))
    sky.check_date(datetime(1900, 1, 1))
    sky.check_date(datetime(2100, 12, 31, 23, 59))
    for year in (1800, 2200, 1899, 2101):
        with pytest.raises(ValueError) as exc:
            sky.check_date(datetime(year, 6, 1))
        msg = str(exc.value)
        assert f"{year}-06-01" in msg and "1900" in msg and "2100" in msg


def test_check_date_converts_aware_dates_to_utc():
    # 2101-01-01 00:30 at UTC+1 is 2100-12-31 23:30 UTC: accepted.
    sky.check_date(datetime(2101, 1, 1, 0, 30, tzinfo=timezone(timedelta(hours=1))))
    # 1900-01-01 00:30 at UTC+1 is 1899-12-31 23:30 UTC: rejected.
    with pytest.raises(ValueError, match="1899-12-31"):
        sky.check_date(datetime(1900, 1, 1, 0, 30, tzinfo=timezone(timedelta(hours=1))))


def test_functions_taking_dates_reject_out_of_range():
    with pytest.raises(ValueError):
        sky.sun_direction_inertial(datetime(1800, 1, 1))
    with pytest.raises(ValueError):
        sky.star("Canopus", datetime(2200, 1, 1))


# --- vectors -------------------------------------------------------------------

finite = st.floats(-1e3, 1e3, allow_nan=False, allow_infinity=False)


@given(ra_deg=st.floats(0.0, 360.0, exclude_max=True),
       dec_deg=st.floats(-89.999, 89.999))
def test_radec_round_trip(ra_deg, dec_deg):
    u = sky.radec_to_unit(ra_deg, dec_deg)
    assert np.linalg.norm(u) == pytest.approx(1.0, abs=1e-15)
    ra2_deg, dec2_deg = sky.unit_to_radec(u)
    assert 0.0 <= ra2_deg < 360.0
    assert dec2_deg == pytest.approx(dec_deg, abs=1e-9)
    # RA wraps at 360 and its error grows as 1 / cos(dec) toward the poles.
    d_ra_deg = (ra2_deg - ra_deg + 180.0) % 360.0 - 180.0
    assert abs(d_ra_deg) * math.cos(math.radians(dec_deg)) < 1e-9


@given(x=finite, y=finite, z=finite)
def test_unit_round_trip(x, y, z):
    v = np.array([x, y, z])
    n = np.linalg.norm(v)
    if n < 1e-6:
        return
    ra_deg, dec_deg = sky.unit_to_radec(v)
    assert 0.0 <= ra_deg < 360.0 and -90.0 <= dec_deg <= 90.0
    np.testing.assert_allclose(sky.radec_to_unit(ra_deg, dec_deg), v / n, atol=1e-12)


@given(u=st.tuples(finite, finite, finite), v=st.tuples(finite, finite, finite))
def test_separation_symmetric_and_in_range(u, v):
    if np.linalg.norm(u) < 1e-6 or np.linalg.norm(v) < 1e-6:
        return
    s = sky.separation_deg(u, v)
    assert 0.0 <= s <= 180.0
    assert s == sky.separation_deg(v, u)
    assert sky.separation_deg(u, -np.asarray(v)) == pytest.approx(180.0 - s, abs=1e-9)


def test_separation_exact_cases_and_small_angles():
    x = np.array([1.0, 0.0, 0.0])
    assert sky.separation_deg(x, x) == 0.0
    assert sky.separation_deg(x, -x) == 180.0
    assert sky.separation_deg(x, [0.0, 2.0, 0.0]) == 90.0
    # 1 nanoradian: acos(cos) would round to 0; the atan2 form keeps it.
    tiny_rad = 1e-9
    y = np.array([math.cos(tiny_rad), math.sin(tiny_rad), 0.0])
    assert sky.separation_deg(x, y) == pytest.approx(math.degrees(tiny_rad), rel=1e-6)
    assert sky.separation_deg(x, -y) == pytest.approx(180.0 - math.degrees(tiny_rad),
                                                      abs=1e-12)


def test_each_star_has_one_name():
    """No two names of the catalog share a place: variants resolve to the name kept."""
    names = sky.star_names()
    dirs = np.array([sky.star_direction_inertial(n) for n in names])
    close = np.argwhere(np.triu(dirs @ dirs.T, 1) > np.cos(np.radians(0.01)))
    assert close.size == 0, [(names[i], names[j]) for i, j in close]
    for variant, kept in sky.VARIANT_NAMES.items():
        assert variant not in names and kept in names
        assert sky.star(variant).name == kept
        assert sky.separation_deg(sky.star_direction_inertial(variant),
                                  sky.star_direction_inertial(kept)) < 0.01
