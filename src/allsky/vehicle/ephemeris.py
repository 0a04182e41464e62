"""Where the Sun is: JPL's DE421 ephemeris, the same bits on every machine.

DE421 (Folkner, Williams and Boggs 2009, JPL IPN Progress Report 42-178)
gives each body's position as Chebyshev series over fixed intervals of days;
the ``de421`` package carries its coefficients as arrays (km, barycentric
ICRF; the Moon geocentric). Nothing is downloaded. The series are summed
here by Clenshaw's recurrence in a fixed order, with the exact arithmetic of
:mod:`allsky.xmath`, so a position is the same bits on every machine (a
library's evaluation through NumPy's BLAS or the C library would not be).

Time scales: a date is UTC; TT = UTC + (TAI - UTC) + 32.184 s, with the
leap seconds of IERS Bulletin C since 1972 (:data:`LEAP_SECONDS`; none
after 2017 is assumed) and, before 1972, TT - UT from the historical table
:data:`DELTA_T_S`. TDB - TT (at most 1.7 ms) is the first two periodic
terms of the usual series. The Sun moves 0.04 arcsec in a second of time,
so a second's error in these is 0.04 arcsec.

Frame and place: the inertial frame is the ICRF (equatorial J2000 to 0.02
arcsec). A direction is astrometric and geocentric: the body where it was
when the light now arriving left it (light-time iterated), seen from the
Earth's centre; aberration (20.5 arcsec) is not applied, as for the stars.
"""

import functools
import itertools
import math
import os
from datetime import UTC, datetime, timedelta

import numpy as np

from allsky import xmath

#: [km/s] speed of light (DE421's CLIGHT)
C_KM_S = 299792.458
DAY_S = 86400.0
#: Julian date of J2000.0 (TT)
J2000_JD = 2451545.0
#: The bodies of DE421 this module reads, by name: the ``de421`` package's file stem. The
#: planets' series are of their systems' barycentres (Jupiter's is within 0.002" of the
#: planet's centre as seen from the Earth: its moons' masses are 2e-4 of its own).
FILES = {"sun": "jpl-sun", "earthmoon": "jpl-earthmoon", "moon": "jpl-moon",
         "mercury": "jpl-mercury", "venus": "jpl-venus", "mars": "jpl-mars",
         "jupiter": "jpl-jupiter", "saturn": "jpl-saturn"}

#: (first day in UTC, TAI - UTC [s]) of each leap second since 1972 (IERS Bulletin C).
LEAP_SECONDS = (
    ((1972, 1, 1), 10), ((1972, 7, 1), 11), ((1973, 1, 1), 12), ((1974, 1, 1), 13),
    ((1975, 1, 1), 14), ((1976, 1, 1), 15), ((1977, 1, 1), 16), ((1978, 1, 1), 17),
    ((1979, 1, 1), 18), ((1980, 1, 1), 19), ((1981, 7, 1), 20), ((1982, 7, 1), 21),
    ((1983, 7, 1), 22), ((1985, 7, 1), 23), ((1988, 1, 1), 24), ((1990, 1, 1), 25),
    ((1991, 1, 1), 26), ((1992, 7, 1), 27), ((1993, 7, 1), 28), ((1994, 7, 1), 29),
    ((1996, 1, 1), 30), ((1997, 7, 1), 31), ((1999, 1, 1), 32), ((2006, 1, 1), 33),
    ((2009, 1, 1), 34), ((2012, 7, 1), 35), ((2015, 7, 1), 36), ((2017, 1, 1), 37),
)
#: [s] TT - UT at the start of years before 1972, every five years (historical Delta T,
#: the IERS and USNO tables, to 0.1 s); linear in between.
DELTA_T_S = ((1900, -2.8), (1905, 3.9), (1910, 10.5), (1915, 17.2), (1920, 21.2),
             (1925, 23.6), (1930, 24.0), (1935, 23.9), (1940, 24.3), (1945, 26.8),
             (1950, 29.2), (1955, 31.1), (1960, 33.2), (1965, 35.7), (1970, 40.2),
             (1972, 42.2))
#: [s] TT - TAI
TT_MINUS_TAI_S = 32.184

_EPOCH = datetime(2000, 1, 1, 12, 0, 0)  # J2000.0 as a UTC calendar date (JD 2451545.0)


def _naive_utc(date_utc: datetime) -> datetime:
    if date_utc.tzinfo is None:
        return date_utc
    return date_utc.astimezone(UTC).replace(tzinfo=None)


def tt_minus_utc_s(date_utc: datetime) -> float:
    """TT - UTC [s] at ``date_utc`` (naive: UTC); leap seconds, Delta T before 1972."""
    d = _naive_utc(date_utc)
    if d < datetime(1972, 1, 1):
        year = d.year + (d - datetime(d.year, 1, 1)) / timedelta(days=365.25)
        if year <= DELTA_T_S[0][0]:
            return DELTA_T_S[0][1]
        for (y0, t0), (y1, t1) in itertools.pairwise(DELTA_T_S):
            if year < y1:
                return t0 + (t1 - t0) * (year - y0) / (y1 - y0)
        return DELTA_T_S[-1][1]
    tai = 10
    for (y, m, day), value in LEAP_SECONDS:
        if d >= datetime(y, m, day):
            tai = value
    return tai + TT_MINUS_TAI_S


def tdb_jd(date_utc: datetime, offset_s: float = 0.0) -> float:
    """Julian date on the TDB scale of ``date_utc`` plus ``offset_s`` [s].

    TDB - TT = 0.001657 sin g + 0.000014 sin 2g [s], g the Earth's mean
    anomaly (the Astronomical Almanac's two-term series, good to 30 us).
    """
    d = _naive_utc(date_utc)
    delta = d - _EPOCH  # exact: days, seconds, microseconds
    seconds = (delta.days * DAY_S + delta.seconds + delta.microseconds * 1e-6
               + tt_minus_utc_s(d) + offset_s)
    jd_tt = J2000_JD + seconds / DAY_S
    g = (357.53 + 0.98560028 * (jd_tt - J2000_JD)) * (math.pi / 180.0)
    return jd_tt + (0.001657 * xmath.sin(g) + 0.000014 * xmath.sin(2.0 * g)) / DAY_S


@functools.cache
def _tables():
    """DE421's constants and coefficient arrays, by body (memory-mapped)."""
    import de421

    folder = os.path.dirname(de421.__file__)
    constants = {name.decode(): float(value)
                 for name, value in np.load(os.path.join(folder, "constants.npy"))}
    arrays = {body: np.load(os.path.join(folder, stem + ".npy"), mmap_mode="r")
              for body, stem in FILES.items()}
    return constants, arrays


def coverage_jd() -> tuple[float, float]:
    """First and last Julian dates (TDB) of the coefficients."""
    constants, _ = _tables()
    return constants["jalpha"], constants["jomega"]


def chebyshev_km(body: str, jd: float) -> np.ndarray:
    """``body``'s position [km] at TDB Julian date ``jd`` from its Chebyshev series.

    Barycentric for the Sun and the Earth-Moon barycentre, geocentric for
    the Moon (DE421's own centres). The series of the interval holding
    ``jd`` is summed by Clenshaw's recurrence in a fixed order.

    Raises
    ------
    ValueError
        ``jd`` outside the ephemeris (:func:`coverage_jd`).
    """
    constants, arrays = _tables()
    coefficients = arrays[body]
    first, last = constants["jalpha"], constants["jomega"]
    if not first <= jd <= last:
        raise ValueError(f"Julian date {jd} is outside DE421 ({first}..{last})")
    n = coefficients.shape[0]
    days = (last - first) / n
    k = min(math.floor((jd - first) / days), n - 1)
    return series_km(coefficients[k], 2.0 * ((jd - first) - k * days) / days - 1.0)


def series_km(c, s) -> np.ndarray:
    """One interval's Chebyshev series, coefficients ``c`` (3, m), at ``s`` in [-1, 1].

    Clenshaw's recurrence, highest degree first, the same operations in the
    same order every time.
    """
    out = np.empty(3)
    two_s = s + s
    for axis in range(3):
        b1 = b2 = 0.0
        for j in range(c.shape[1] - 1, 0, -1):
            b1, b2 = two_s * b1 - b2 + float(c[axis, j]), b1
        out[axis] = s * b1 - b2 + float(c[axis, 0])
    return out


def earth_km(jd: float) -> np.ndarray:
    """The Earth's centre [km], barycentric, at TDB Julian date ``jd``."""
    constants, _ = _tables()
    moon = chebyshev_km("moon", jd)
    return chebyshev_km("earthmoon", jd) - moon / (1.0 + constants["EMRAT"])


def barycentric_km(body: str, jd: float) -> np.ndarray:
    """``body``'s position [km] from the barycentre at TDB Julian date ``jd``.

    ``body`` is a name of :data:`FILES` other than ``"earthmoon"``, or
    ``"earth"``; the Moon is the Earth's centre plus its geocentric series.
    """
    if body == "earth":
        return earth_km(jd)
    if body == "moon":
        return earth_km(jd) + chebyshev_km("moon", jd)
    return chebyshev_km(body, jd)


def from_earth_km(body: str, jd: float) -> np.ndarray:
    """Astrometric geocentric position [km] of ``body`` at TDB Julian date ``jd``.

    The body where it was when the light now reaching the Earth's centre
    left it, less where the Earth's centre is now (both barycentric): two
    iterations of the light time (a body moving 50 km/s about the
    barycentre is then placed to 5 m). ``body`` as in :func:`barycentric_km`.
    """
    earth = earth_km(jd)
    there = barycentric_km(body, jd)
    for _ in range(2):
        r = there - earth
        light_days = xmath.norm3(r) / C_KM_S / DAY_S
        there = barycentric_km(body, jd - light_days)
    return there - earth


def sun_from_earth_km(jd: float) -> np.ndarray:
    """Astrometric geocentric Sun [km] at TDB Julian date ``jd``: light-time included.

    :func:`from_earth_km` of the Sun (the Sun moves about 13 m/s about the
    barycentre, so the second iteration changes the direction by under
    1e-10 rad).
    """
    return from_earth_km("sun", jd)


def sun_direction_icrf(date_utc: datetime, offset_s: float = 0.0) -> np.ndarray:
    """Unit vector, Earth's centre to the Sun (ICRF), at ``date_utc`` + ``offset_s``."""
    r = sun_from_earth_km(tdb_jd(date_utc, offset_s))
    return r / xmath.norm3(r)
