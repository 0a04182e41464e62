"""The sky's moving bodies: the Moon and the planets Mercury to Saturn.

Positions come from JPL's DE421 (:mod:`allsky.vehicle.ephemeris`, the same
series as the Sun's, summed with the exact arithmetic of :mod:`allsky.xmath`,
so a place is the same bits on every machine, offline). A direction is
astrometric and geocentric, as the Sun's and the stars': where the body was
when the light now arriving left it, seen from the Earth's centre, in the
ICRF; aberration is not applied. DE421 is good to about 0.001" for the inner
planets and 0.1" for Jupiter and Saturn (Folkner et al. 2009); the planets'
series are of their systems' barycentres, within 0.002" of the planets'
centres seen from the Earth.

DE421 was chosen over PyEphem's theories (VSOP87 truncated to about 1", the
Moon to about 20") because the project already sums its series exactly for
the Sun: one ephemeris for the Sun and the bodies, bit-identical on every
machine. PyEphem stays the independent check in the tests.

Magnitudes
----------
The planets' visual magnitudes are Mallama and Hilton's (2018, *Astronomy
and Computing* 25, 10-24: the Astronomical Almanac's since 2019) as
functions of the distances Sun-body ``r`` and Earth-body ``Delta`` [au] and
the phase angle ``alpha`` [deg], the angle Sun-body-Earth. Left out: Mars'
orbital-longitude and rotation terms (up to about 0.1 mag), Saturn's rings
beyond a phase angle of 6.5 deg (never from the Earth). The Moon's is
Allen's law (Astrophysical Quantities): ``V = 0.21 + 5 log10(r Delta) +
0.026 alpha + 4e-9 alpha^4``, -12.7 when full at its mean distance, good to
about 0.1 mag away from the new Moon. ``phase`` is the illuminated fraction
of the disk, ``(1 + cos alpha) / 2``.
"""

from __future__ import annotations

import functools
import math
from datetime import datetime
from typing import NamedTuple

import numpy as np

from allsky import xmath
from allsky.vehicle import ephemeris

#: [km] the astronomical unit (IAU 2012)
AU_KM = 149597870.7
#: The moving bodies, by name: DE421's series.
BODIES = {"Moon": "moon", "Mercury": "mercury", "Venus": "venus", "Mars": "mars",
          "Jupiter": "jupiter", "Saturn": "saturn"}
#: [km] their mean radii (IAU 2015), for their apparent sizes
RADIUS_KM = {"Moon": 1737.4, "Mercury": 2439.4, "Venus": 6051.8, "Mars": 3389.5,
             "Jupiter": 69911.0, "Saturn": 58232.0}
#: [deg] Saturn's north pole (IAU 2015: RA, Dec at J2000; their rates are under 0.04 deg a
#: century), for the tilt of its rings toward the Earth
SATURN_POLE_DEG = (40.589, 83.537)
#: [s] the step of the geocentric places a flight interpolates (linearly, in km): the
#: Moon's curvature over it puts it 0.03 km (0.016") off
GRID_S = 300.0


class Body(NamedTuple):
    """A moving body at one date, seen from the Earth's centre.

    Attributes
    ----------
    name : str
        ``"Moon"``, ``"Mercury"`` ... ``"Saturn"``.
    ra_deg, dec_deg : float
        Right ascension in [0, 360) and declination [deg], ICRF.
    magnitude : float
        Visual magnitude.
    phase : float
        Illuminated fraction of the disk (0 new, 1 full).
    elongation_deg : float
        Angle from the Sun, seen from the Earth [deg].
    distance_au : float
        Distance from the Earth's centre [au].
    """

    name: str
    ra_deg: float
    dec_deg: float
    magnitude: float
    phase: float
    elongation_deg: float
    distance_au: float


def _polynomial(coefficients, x) -> float:
    """``c0 + c1 x + c2 x^2 + ...`` by Horner's rule, highest degree first."""
    out = 0.0
    for c in reversed(coefficients):
        out = out * x + c
    return out


#: Mallama and Hilton's phase curves [mag] by body: (alpha limit [deg], coefficients below
#: it, coefficients above it or None), the constant term first.
PHASE_CURVES = {
    "Mercury": (180.0, (-0.613, 6.3280e-2, -1.6336e-3, 3.3644e-5, -3.4265e-7, 1.6893e-9,
                        -3.0334e-12), None),
    "Venus": (163.7, (-4.384, -1.044e-3, 3.687e-4, -2.814e-6, 8.938e-9),
              (236.05828, -2.81914, 8.39034e-3)),
    "Mars": (50.0, (-1.601, 2.267e-2, -1.302e-4), (-0.367, -0.02573, 3.445e-4)),
    "Jupiter": (12.0, (-9.395, -3.7e-4, 6.16e-4), (-9.428, 0.0, 0.0)),
    "Moon": (180.0, (0.21, 0.026, 0.0, 0.0, 4.0e-9), None),
}


def magnitude(name: str, r_au: float, delta_au: float, alpha_deg: float,
              ring_sin: float = 0.0) -> float:
    """Visual magnitude of body ``name``: Mallama and Hilton's law, or Allen's.

    ``r_au`` and ``delta_au`` [au] are its distances from the Sun and the
    Earth, ``alpha_deg`` [deg] its phase angle; ``ring_sin`` is, for Saturn, the sine of its rings' tilt toward the Earth
    (the sub-Earth latitude); the magnitude is of the globe and the rings.
    """
    a = abs(float(alpha_deg))
    distance = 5.0 * xmath.log10(r_au * delta_au)
    if name == "Saturn":
        b = abs(float(ring_sin))
        return distance - 8.914 - 1.825 * b + 0.026 * a - 0.378 * b * xmath.exp(-2.25 * a)
    limit, below, above = PHASE_CURVES[name]
    return distance + _polynomial(below if a <= limit or above is None else above, a)


def _angle(u, v) -> float:
    """The angle [rad] between vectors ``u`` and ``v`` (atan2 of the cross and dot products)."""
    cx = u[1] * v[2] - u[2] * v[1]
    cy = u[2] * v[0] - u[0] * v[2]
    cz = u[0] * v[1] - u[1] * v[0]
    return xmath.atan2(math.sqrt(cx * cx + cy * cy + cz * cz), xmath.dot3(u, v))


def from_earth_km(name: str, date_utc: datetime, offset_s: float = 0.0) -> np.ndarray:
    """Astrometric geocentric place [km] of ``name`` at ``date_utc`` + ``offset_s``."""
    return ephemeris.from_earth_km(BODIES[name], ephemeris.tdb_jd(date_utc, offset_s))


def body(name: str, date_utc: datetime, offset_s: float = 0.0) -> Body:
    """Body ``name`` (a key of :data:`BODIES`) at ``date_utc`` + ``offset_s`` [s].

    Raises
    ------
    KeyError
        For a name that is not a moving body's.
    ValueError
        For a date outside DE421.
    """
    jd = ephemeris.tdb_jd(date_utc, offset_s)
    r = ephemeris.from_earth_km(BODIES[name], jd)
    sun = ephemeris.sun_from_earth_km(jd)
    delta = float(xmath.norm3(r))
    to_sun = sun - r
    alpha = _angle(to_sun, -r)
    ring = 0.0
    if name == "Saturn":
        ra0, dec0 = (math.radians(v) for v in SATURN_POLE_DEG)
        pole = np.array([xmath.cos(dec0) * xmath.cos(ra0), xmath.cos(dec0) * xmath.sin(ra0),
                         xmath.sin(dec0)])
        ring = -xmath.dot3(pole, r) / delta
    ra = math.degrees(xmath.atan2(float(r[1]), float(r[0]))) % 360.0
    dec = math.degrees(xmath.asin(float(r[2]) / delta))
    return Body(name, ra, dec,
                magnitude(name, float(xmath.norm3(to_sun)) / AU_KM, delta / AU_KM,
                          math.degrees(alpha), ring),
                0.5 * (1.0 + xmath.cos(alpha)), math.degrees(_angle(sun, r)), delta / AU_KM)


@functools.lru_cache(maxsize=64)
def _bodies_at(date_utc: datetime) -> tuple:
    return tuple(body(name, date_utc) for name in BODIES)


def bodies(date_utc: datetime) -> list[Body]:
    """Every moving body at ``date_utc``, in the order of :data:`BODIES`."""
    return list(_bodies_at(date_utc))


def geocentric_grid_km(names, date_utc: datetime, span_s: float):
    """``(t_s, km)``: geocentric places every :data:`GRID_S` over ``span_s``.

    ``names`` are the bodies'; ``km`` is (len(t_s), len(names), 3); the grid starts at ``date_utc`` and
    covers ``span_s`` [s] and one step more.
    """
    n = math.ceil(span_s / GRID_S) + 2
    t = np.arange(n) * GRID_S
    km = np.empty((n, len(names), 3))
    for i, ti in enumerate(t):
        for j, name in enumerate(names):
            km[i, j] = from_earth_km(name, date_utc, float(ti))
    return t, km


def directions_from(names, date_utc: datetime, t_s, position_km) -> np.ndarray:
    """Unit vectors (len(t_s), len(names), 3) from a vehicle to the bodies, ICRF.

    ``names`` are the bodies' (keys of :data:`BODIES`); ``position_km``
    (len(t_s), 3) is the vehicle's geocentric position [km]
    at mission times ``t_s`` [s] after ``date_utc``. The bodies' geocentric
    places are interpolated linearly in km from :func:`geocentric_grid_km`
    (0.016" for the Moon), each component in axis order.
    """
    t_s = np.asarray(t_s, dtype=float)
    out = np.empty((t_s.shape[0], len(names), 3))
    if not len(names) or not t_s.shape[0]:
        return out
    grid_t, grid_km = geocentric_grid_km(names, date_utc, float(t_s[-1]))
    pos = np.asarray(position_km, dtype=float)
    k = np.minimum((t_s // GRID_S).astype(np.int64), grid_t.shape[0] - 2)
    w = (t_s - grid_t[k]) / GRID_S
    for j in range(len(names)):
        a, b = grid_km[k, j], grid_km[k + 1, j]
        rel = a + w[:, None] * (b - a) - pos  # elementwise: the same bits on every machine
        norm = np.sqrt(rel[:, 0] * rel[:, 0] + rel[:, 1] * rel[:, 1] + rel[:, 2] * rel[:, 2])
        out[:, j] = rel / norm[:, None]
    return out
