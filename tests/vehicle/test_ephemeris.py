"""The DE421 Sun (allsky.vehicle.ephemeris) against an independent theory and physics.

Truth:

* PyEphem's Sun (VSOP87, Bretagnon and Francou 1988, through libastro): an
  independent theory; it and DE421 agree to a fraction of an arcsecond.
* The Earth's orbit: perihelion a(1 - e) = 0.98329 au in early January,
  aphelion a(1 + e) = 1.01671 au in early July (e = 0.0167; the Moon moves the
  Earth's centre by 3e-5 au about the barycentre).
* IERS Bulletin C: TAI - UTC = 37 s since 2017 January 1, 19 s in 1980.
"""

import math
from datetime import datetime, timedelta

import ephem
import numpy as np
import pytest

from allsky import xmath
from allsky.vehicle import ephemeris, sky

AU_KM = 149597870.700


def _ephem_sun(date_utc):
    sun = ephem.Sun()
    sun.compute(ephem.Date(date_utc), epoch="2000")
    return sky.radec_to_unit(math.degrees(sun.a_ra), math.degrees(sun.a_dec))


@pytest.mark.parametrize("year", range(1900, 2021, 10))
def test_the_sun_agrees_with_vsop87_to_a_third_of_an_arcsecond(year):
    """1900-2020, where PyEphem's Delta T is the observed one (later it extrapolates)."""
    for month in (1, 4, 7, 10):
        d = datetime(year, month, 11, 6, 30)
        assert sky.separation_deg(ephemeris.sun_direction_icrf(d), _ephem_sun(d)) * 3600 < 0.33


def test_the_earth_sun_distance_follows_the_orbit():
    days = [datetime(2026, 1, 1) + timedelta(days=k) for k in range(366)]
    r_au = [xmath.norm3(ephemeris.sun_from_earth_km(ephemeris.tdb_jd(d))) / AU_KM
            for d in days]
    assert min(r_au) == pytest.approx(0.98329, abs=1e-4)
    assert max(r_au) == pytest.approx(1.01671, abs=1e-4)
    assert days[int(np.argmin(r_au))].month == 1 and days[int(np.argmax(r_au))].month == 7


def test_the_series_join_at_their_interval_ends():
    """Each body's series meet within a metre where one interval hands over to the next."""
    _, arrays = ephemeris._tables()
    for body in ephemeris.FILES:
        for k in (100, 3000, arrays[body].shape[0] - 1):
            end = ephemeris.series_km(arrays[body][k - 1], 1.0)
            start = ephemeris.series_km(arrays[body][k], -1.0)
            assert xmath.norm3(end - start) < 1e-3, body


def test_time_scales_follow_the_leap_seconds():
    assert ephemeris.tt_minus_utc_s(datetime(2026, 11, 28)) == 69.184
    assert ephemeris.tt_minus_utc_s(datetime(2016, 12, 31, 23, 59)) == 68.184
    assert ephemeris.tt_minus_utc_s(datetime(1980, 6, 1)) == 19 + 32.184
    assert ephemeris.tt_minus_utc_s(datetime(1964, 11, 28)) == pytest.approx(35.5, abs=0.5)
    # TDB - TT stays within 1.7 ms
    d = datetime(2026, 3, 1)
    jd_tt = ephemeris.J2000_JD + ((d - datetime(2000, 1, 1, 12)).total_seconds() + 69.184) / 86400
    assert abs(ephemeris.tdb_jd(d) - jd_tt) * 86400 < 1.7e-3


def test_dates_beyond_the_coefficients_are_refused():
    first, last = ephemeris.coverage_jd()
    for jd in (first - 1.0, last + 1.0):
        with pytest.raises(ValueError, match="outside DE421"):
            ephemeris.chebyshev_km("sun", jd)


@pytest.mark.parametrize("when", [datetime(1900, 3, 1), datetime(1964, 11, 28),
                                  datetime(2026, 11, 28), datetime(2100, 6, 1)])
def test_star_places_follow_pyephems_proper_motion(when):
    """The catalog's places at a date agree with PyEphem's within 0.25" (its single-precision
    proper motions), for the stars that move fastest and for Canopus."""
    for name in ("Rigil Kentaurus", "Arcturus", "Sirius", "Canopus", "Procyon"):
        body = ephem.star(name)
        body.compute(ephem.Date(when), epoch="2000")
        theirs = sky.radec_to_unit(math.degrees(body.a_ra), math.degrees(body.a_dec))
        assert sky.separation_deg(sky.star_direction_inertial(name, when), theirs) * 3600 < 0.25
