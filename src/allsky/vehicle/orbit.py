"""The vehicle's orbit: a circular orbit with J2, or a two-line element set (SGP4).

``[orbit] kind`` chooses (:data:`KINDS`):

``"none"``
    No orbit: the vehicle flies far from any body, the Sun is the
    geocentric Sun, nothing is eclipsed or occulted and no environment
    torque acts (every result as before the orbit was modelled).
``"circular"``
    A circular orbit of ``altitude_km`` above :data:`R_EARTH_M`, inclined
    ``inclination_deg`` to the J2000 equator, its ascending node at right
    ascension ``raan_deg``, the vehicle at argument of latitude
    ``arg_latitude_deg`` at ejection (mission time 0). The elements are mean
    elements in the J2000 frame; with ``j2`` the node and the argument of
    latitude precess at the secular J2 rates (:func:`circular_rates`):
    about -7 deg/day for the node at 300 km and 28.5 deg.
``"tle"``
    A two-line element set (``tle_line1``, ``tle_line2``) propagated by
    SGP4 (the ``sgp4`` package, the standard implementation of Vallado et
    al. 2006). SGP4 gives TEME coordinates; they are turned to J2000 by the
    IAU 1976 precession from the date's mean equator and equinox (nutation,
    below 20 arcsec, is left out: 0.6 km at the vehicle's radius). SGP4's
    own arithmetic is the package's compiled code, not :mod:`allsky.xmath`:
    its positions may differ in the last bits between machines.

Positions are sampled every ``sample_s`` of mission time (on the mission's
frames: sample ``k`` is at ``k * sample_s``) and the frame loop interpolates
linearly between samples. For a circular orbit of radius ``r`` and rate
``n`` the chord's largest distance from the arc is ``r (n dt)^2 / 8``:
1.1 m, 1.7e-7 rad (0.035 arcsec) of the Earth's direction, at 300 km and
1 s; a unit vector interpolated is renormalised.
"""

from __future__ import annotations

import math
from datetime import UTC, datetime, timedelta
from typing import NamedTuple

import numpy as np

from allsky import xarrays, xmath

#: The kinds of ``[orbit]``.
KINDS = ("none", "circular", "tle")
#: [m^3/s^2] the Earth's gravitational parameter (WGS 84, EGM96)
MU_EARTH_M3_S2 = 3.986004418e14
#: [m] the Earth's equatorial radius (WGS 84)
R_EARTH_M = 6378137.0
#: [-] the Earth's second zonal harmonic (EGM96)
J2 = 1.08262668e-3
#: Lowest and highest altitude [km] of a circular orbit (below 150 km a vehicle reenters
#: within a day; the exponential atmosphere's table ends at 1000 km).
ALTITUDE_KM = (150.0, 1000.0)
#: [s] the longest sample interval accepted (the interpolation error grows as its square:
#: 60 s is 4 km, 0.13 deg of the Earth's direction at 300 km).
SAMPLE_MAX_S = 60.0


class Track(NamedTuple):
    """The vehicle's place over mission time, in the J2000 frame (the ICRF)."""

    t_s: np.ndarray  #: [s] (n,) mission time of each sample
    r_m: np.ndarray  #: [m] (n, 3) position, from the Earth's centre
    v_m_s: np.ndarray  #: [m/s] (n, 3) velocity, inertial


def circular_rates(altitude_km: float, inclination_deg: float, j2: bool = True):
    """Mean motion, node rate and argument-of-latitude rate [rad/s], circular orbit.

    ``altitude_km`` [km] above the equatorial radius, ``inclination_deg`` [deg];
    ``j2`` adds the secular J2 rates.

    Secular J2 rates for eccentricity 0 and semi-major axis ``a``::

        n      = sqrt(mu / a^3)
        dRAAN  = -1.5 n J2 (R/a)^2 cos i
        du     = n (1 + 1.5 J2 (R/a)^2 (4 cos^2 i - 1))

    (the argument of perigee's and the mean anomaly's secular rates added).
    Without ``j2`` the node is fixed and ``du = n``.

    Returns
    -------
    (float, float, float)
        ``n``, ``dRAAN``, ``du`` [rad/s].
    """
    a = R_EARTH_M + altitude_km * 1000.0
    n = math.sqrt(MU_EARTH_M3_S2 / (a * a * a))
    if not j2:
        return n, 0.0, n
    c = xmath.cos(math.radians(inclination_deg))
    k = J2 * (R_EARTH_M / a) ** 2
    return n, -1.5 * n * k * c, n * (1.0 + 1.5 * k * (4.0 * c * c - 1.0))


def circular_track(altitude_km, inclination_deg, raan_deg, arg_latitude_deg, t_s,
                   j2=True) -> Track:
    """The vehicle on a circular orbit at mission times ``t_s`` [s] (array).

    ``altitude_km``, ``inclination_deg``, ``raan_deg`` and ``arg_latitude_deg``
    are the elements at time 0 [km, deg]; ``j2``: the secular J2 rates.

    The node and the argument of latitude move on at :func:`circular_rates`;
    the velocity includes the node's motion. See the module's text for the
    elements.
    """
    t = np.asarray(t_s, dtype=float)
    a = R_EARTH_M + float(altitude_km) * 1000.0
    _, draan, du = circular_rates(altitude_km, inclination_deg, j2)
    inc = math.radians(inclination_deg)
    ci, si = xmath.cos(inc), xmath.sin(inc)
    node = math.radians(raan_deg) + draan * t
    u = math.radians(arg_latitude_deg) + du * t
    cn, sn = xarrays.cos_many(node), xarrays.sin_many(node)
    cu, su = xarrays.cos_many(u), xarrays.sin_many(u)
    r = a * np.stack([cn * cu - sn * su * ci, sn * cu + cn * su * ci, su * si], axis=1)
    v = a * du * np.stack([-cn * su - sn * cu * ci, -sn * su + cn * cu * ci, cu * si], axis=1)
    v[:, 0] -= draan * r[:, 1]  # the node's rotation about z
    v[:, 1] += draan * r[:, 0]
    return Track(t, r, v)


def _julian_date_utc(d: datetime) -> tuple[float, float]:
    """(whole, fraction) Julian date of the UTC datetime ``d`` (naive: UTC)."""
    if d.tzinfo is not None:
        d = d.astimezone(UTC).replace(tzinfo=None)
    days = (d - datetime(2000, 1, 1, 12)) / timedelta(days=1)
    whole = math.floor(days)
    return 2451545.0 + whole, days - whole


def precession_to_j2000(jd_tt: float) -> np.ndarray:
    """Rotation from the mean equator and equinox of ``jd_tt`` (TT) to J2000.

    The IAU 1976 precession, Lieske et al. (1977): ``zeta``, ``z``, ``theta`` as cubics in Julian
    centuries from J2000.0. Returns the (3, 3) matrix ``P^T`` that takes
    mean-of-date coordinates to J2000.
    """
    t = (jd_tt - 2451545.0) / 36525.0
    as2r = math.pi / (180.0 * 3600.0)
    zeta = (2306.2181 * t + 0.30188 * t * t + 0.017998 * t ** 3) * as2r
    z = (2306.2181 * t + 1.09468 * t * t + 0.018203 * t ** 3) * as2r
    theta = (2004.3109 * t - 0.42665 * t * t - 0.041833 * t ** 3) * as2r
    cz, sz = xmath.cos(zeta), xmath.sin(zeta)
    cZ, sZ = xmath.cos(z), xmath.sin(z)
    ct, st = xmath.cos(theta), xmath.sin(theta)
    p = np.array([  # J2000 -> mean of date
        [cz * ct * cZ - sz * sZ, -sz * ct * cZ - cz * sZ, -st * cZ],
        [cz * ct * sZ + sz * cZ, -sz * ct * sZ + cz * cZ, -st * sZ],
        [cz * st, -sz * st, ct],
    ])
    return p.T


def parse_tle(line1: str, line2: str):
    """The ``sgp4`` satellite record of a two-line element set ``line1``, ``line2``.

    Raises
    ------
    ValueError
        If the lines are not a valid element set (the message says why).
    """
    from sgp4.api import Satrec

    l1, l2 = line1.rstrip(), line2.rstrip()
    if not l1.startswith("1 ") or not l2.startswith("2 "):
        raise ValueError("line 1 must begin with '1 ' and line 2 with '2 '")
    if len(l1) != 69 or len(l2) != 69:
        raise ValueError(f"each line must have 69 characters (they have {len(l1)} and "
                         f"{len(l2)})")
    for i, line in ((1, l1), (2, l2)):
        digits = sum(int(c) for c in line[:68] if c.isdigit()) + line[:68].count("-")
        if str(digits % 10) != line[68]:
            raise ValueError(f"line {i}'s checksum is {line[68]}, its characters give "
                             f"{digits % 10}")
    try:
        sat = Satrec.twoline2rv(l1, l2)
    except (ValueError, RuntimeError, IndexError) as exc:  # the parser's own words
        raise ValueError(f"not a two-line element set: {exc}") from None
    if sat.error:
        raise ValueError(f"SGP4 cannot initialise these elements (error {sat.error})")
    return sat


def tle_track(line1, line2, date_utc: datetime, t_s) -> Track:
    """The vehicle of ``line1``, ``line2`` at ``date_utc`` + ``t_s`` [s], by SGP4.

    TEME to J2000 by :func:`precession_to_j2000` at the mission's date (the
    precession over a day, 0.14 arcsec, is left out).

    Raises
    ------
    ValueError
        If SGP4 fails at a sample (decayed orbit, eccentricity out of range).
    """
    from allsky.vehicle.ephemeris import tt_minus_utc_s

    sat = parse_tle(line1, line2)
    t = np.asarray(t_s, dtype=float)
    jd0, fr0 = _julian_date_utc(date_utc)
    fr = fr0 + t / 86400.0
    err, r_km, v_km_s = sat.sgp4_array(np.full(t.shape, jd0), fr)
    bad = np.nonzero(err)[0]
    if bad.size:
        raise ValueError(f"SGP4 fails {t[bad[0]]:g} s after ejection (error {err[bad[0]]}): "
                         "the element set does not reach the mission's date")
    rot = precession_to_j2000(jd0 + fr0 + tt_minus_utc_s(date_utc) / 86400.0)
    r = xarrays.matvec_rows(rot, np.asarray(r_km) * 1000.0)
    v = xarrays.matvec_rows(rot, np.asarray(v_km_s) * 1000.0)
    return Track(t, r, v)


def track(cfg, ck, duration_s: float):
    """The orbit of ``cfg``, sampled every ``orbit.sample_s`` over ``duration_s`` [s].

    The interval is taken up to a whole number of frames of the clock ``ck``
    (:func:`allsky.clock.frames_for`), so that sample ``k`` is at the start
    of frame ``k * step``. Returns ``(Track, step_frames)``, or ``(None, 1)``
    for ``kind = "none"``. The samples cover ``[0, duration_s]`` and one
    interval more.
    """
    from allsky import clock

    o = cfg.orbit
    if o.kind == "none":
        return None, 1
    step = max(1, clock.frames_for(ck, o.sample_s))
    interval = clock.time_s(ck, step)
    n = math.ceil(duration_s / interval) + 2
    t = np.array([clock.time_s(ck, k * step) for k in range(n)])
    if o.kind == "circular":
        return circular_track(o.altitude_km, o.inclination_deg, o.raan_deg,
                              o.arg_latitude_deg, t, o.j2), step
    return tle_track(o.tle_line1, o.tle_line2, cfg.mission.date_utc, t), step
