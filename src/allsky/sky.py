"""The sky: the Sun's direction and the bright-star catalog, from PyEphem.

Directions are unit vectors in the equatorial J2000 frame (astrometric
geocentric positions: PyEphem's ``a_ra``/``a_dec`` computed with
``epoch='2000'``). The parallax of the Sun between the Earth's centre and a
low orbit is below 0.001 arcsec and is ignored. Star magnitudes are the
catalog's visual magnitudes (Canopus -0.62, Sirius -1.44).
"""

import difflib
import functools
import math
from datetime import UTC, datetime
from typing import NamedTuple

import ephem
import ephem.stars
import numpy as np

#: Years over which dates are accepted (PyEphem's Sun theory is good across them).
EPHEMERIS_YEARS = (1900, 2100)


class Star(NamedTuple):
    """A catalog star."""

    name: str
    ra_deg: float  #: [deg] J2000 right ascension
    dec_deg: float  #: [deg] J2000 declination
    magnitude: float  #: visual magnitude


def _utc(date_utc: datetime) -> datetime:
    if date_utc.tzinfo is None:
        return date_utc
    return date_utc.astimezone(UTC).replace(tzinfo=None)


def check_date(date_utc: datetime) -> None:
    """Raise ``ValueError`` if the date is outside :data:`EPHEMERIS_YEARS`."""
    d = _utc(date_utc)
    lo, hi = EPHEMERIS_YEARS
    if not lo <= d.year <= hi:
        raise ValueError(f"date {d.isoformat()} is outside the ephemeris range {lo}-{hi}")


def _ephem_date(date_utc: datetime) -> ephem.Date:
    d = _utc(date_utc)
    return ephem.Date((d.year, d.month, d.day, d.hour, d.minute,
                       d.second + d.microsecond * 1e-6))


def radec_to_unit(ra_deg: float, dec_deg: float) -> np.ndarray:
    """Unit vector of a right ascension and declination [deg]."""
    ra, dec = math.radians(ra_deg), math.radians(dec_deg)
    return np.array([math.cos(dec) * math.cos(ra), math.cos(dec) * math.sin(ra), math.sin(dec)])


def unit_to_radec(u) -> tuple:
    """(ra_deg in [0, 360), dec_deg) of a vector."""
    x, y, z = (float(c) for c in u)
    ra = math.degrees(math.atan2(y, x)) % 360.0
    return ra, math.degrees(math.atan2(z, math.hypot(x, y)))


def separation_deg(u, v) -> float:
    """Angle between two vectors [deg] (atan2 form, accurate at 0 and 180 deg)."""
    u, v = np.asarray(u, dtype=float), np.asarray(v, dtype=float)
    return math.degrees(math.atan2(np.linalg.norm(np.cross(u, v)), float(u @ v)))


def sun_direction_inertial(date_utc: datetime) -> np.ndarray:
    """Unit vector from the Earth to the Sun at ``date_utc``."""
    check_date(date_utc)
    s = ephem.Sun()
    s.compute(_ephem_date(date_utc), epoch="2000")
    return radec_to_unit(math.degrees(s.a_ra), math.degrees(s.a_dec))


def star_names() -> tuple:
    """Sorted names of the catalog stars."""
    return tuple(sorted(ephem.stars.stars))


@functools.cache
def _canonical(name: str) -> str:
    by_lower = {n.lower(): n for n in ephem.stars.stars}
    key = name.strip().lower()
    if key not in by_lower:
        near = difflib.get_close_matches(name.strip(), star_names(), n=3, cutoff=0.5)
        hint = f"; nearest: {', '.join(near)}" if near else ""
        raise KeyError(f"no star named {name!r} in the catalog{hint}")
    return by_lower[key]


def star(name: str, date_utc: datetime | None = None) -> Star:
    """A catalog star, its position for ``date_utc`` (proper motion applied) or J2000.0."""
    canon = _canonical(name)
    body = ephem.star(canon)
    body.compute(_ephem_date(date_utc) if date_utc is not None else ephem.J2000, epoch="2000")
    return Star(canon, math.degrees(body.a_ra), math.degrees(body.a_dec), float(body.mag))


def stars_in_magnitude_window(mag_min: float, mag_max: float, date_utc=None) -> list:
    """Catalog stars with ``mag_min <= magnitude <= mag_max``, brightest first."""
    out = [star(n, date_utc) for n in star_names()]
    return sorted((s for s in out if mag_min <= s.magnitude <= mag_max),
                  key=lambda s: s.magnitude)


def star_direction_inertial(name: str, date_utc=None) -> np.ndarray:
    """Unit vector to a catalog star."""
    s = star(name, date_utc)
    return radec_to_unit(s.ra_deg, s.dec_deg)
