"""The sky for the emulator: the Sun's direction and the bright-star catalog.

The Sun comes from JPL's DE421 ephemeris (:mod:`allsky.vehicle.ephemeris`),
the stars from the bright-star catalog PyEphem carries (``ephem.stars``:
Hipparcos positions for J2000.0 and proper motions, visual magnitudes, e.g.
Canopus -0.62, Sirius -1.44), read as data. Every angle is computed with the
exact arithmetic of :mod:`allsky.xmath`, so that the sky is the same bits on
every machine. Nothing is downloaded; it works offline.

Frame
-----
The inertial frame (``_inertial``) is equatorial J2000 (the ICRF, to 0.02"):
x toward the mean equinox of J2000.0, z toward the mean north celestial pole
of J2000.0. A direction is the astrometric geocentric position: light-time is
included; precession and nutation to the date and aberration are not. The
apparent place of date differs from it by precession (about 50"/yr in
longitude, so up to ~0.5 deg over decades), nutation (< 20") and aberration
(about 20"). A star's place at a date is its J2000.0 place moved on by its
proper motion (linear in right ascension and declination, as PyEphem moves
it: within 0.2" of PyEphem's over a century).

Model limits
------------
* Positions here are geocentric. The vehicle's position in its orbit is
  modelled only with an ``[orbit]`` (:mod:`allsky.vehicle.orbit`), and then
  only for the Sun (:mod:`allsky.vehicle.environment`: the Sun seen from the
  vehicle, the Earth's shadow, the Earth's disk hiding stars and the
  target, the sunlit Earth blinding the star tracker); without one the Sun is the geocentric Sun, below. The Moon and
  the planets are :mod:`allsky.vehicle.bodies`', flown by the tracker as
  rows of its table (:mod:`allsky.sim.sky_rows`, with an orbit by default).
  For the stars the shift is negligible: from a 7000 km baseline
  even Rigil Kentaurus (parallax 0.75" per au) moves by
  ``0.75" * 7000 km / 1 au = 3.5e-5"``, far below 0.001". For the Sun it is
  not below 0.001": the solar horizontal parallax is 8.794" per Earth radius,
  so from a low orbit (r <= 7000 km) the Sun's direction differs from the
  geocentric one by up to ``atan(7000 km / 1 au) = 9.7"``. Without an
  orbit the emulator accepts this: its Sun is the geocentric Sun, used
  consistently by the sensors and the targeting. In orbit both use the Sun
  seen from the vehicle (programmed for the geocentric Sun, the packaged
  free flyer would point 2.3" worse).
* Annual stellar parallax is not in the catalog (at most 0.75", Rigil
  Kentaurus; Canopus 0.01"), and aberration (20.5" from the Earth's orbital
  velocity, about 5" more from the vehicle's) is not applied.

Dates
-----
Dates are ``datetime`` objects in UTC: naive ones are taken as UTC, aware
ones are converted to UTC. The time scales (leap seconds, Delta T before
1972) are :mod:`allsky.vehicle.ephemeris`'s.
"""

from __future__ import annotations

import difflib
import functools
import math
from datetime import UTC, datetime, timedelta
from typing import TYPE_CHECKING, NamedTuple

from allsky import xmath
from allsky.units import HOUR_S

if TYPE_CHECKING:  # NumPy is imported where it computes: checking a scenario needs none
    import numpy as np

#: First and last calendar years (inclusive, UTC) of accepted dates (DE421 spans
#: 1899-07-29 to 2199-06-22; the catalog's proper motions are linear).
EPHEMERIS_YEARS = (1900, 2100)
#: [s] A Julian year, the unit of the catalog's proper motions (mas/yr).
JULIAN_YEAR_S = 365.25 * 86400.0
#: J2000.0, the catalog's epoch, as a UTC calendar date.
J2000_UTC = datetime(2000, 1, 1, 12, 0, 0)
#: [rad] per milliarcsecond
MAS2RAD = math.pi / (180.0 * 3600.0 * 1000.0)


class Star(NamedTuple):
    """A catalog star at one date.

    Attributes
    ----------
    name : str
        Catalog name, as spelt in ``ephem.stars`` (e.g. ``"Canopus"``).
    ra_deg : float
        Right ascension in the J2000 frame [deg], in [0, 360).
    dec_deg : float
        Declination in the J2000 frame [deg].
    magnitude : float
        Catalog visual magnitude.
    """

    name: str
    ra_deg: float
    dec_deg: float
    magnitude: float


def _naive_utc(date_utc: datetime) -> datetime:
    """The date as a naive UTC datetime (naive input is taken as UTC already)."""
    if date_utc.tzinfo is None:
        return date_utc
    return date_utc.astimezone(UTC).replace(tzinfo=None)


def check_date(date_utc: datetime) -> None:
    """Reject a date outside :data:`EPHEMERIS_YEARS`.

    Parameters
    ----------
    date_utc : datetime
        The date; naive means UTC, aware is converted to UTC.

    Raises
    ------
    ValueError
        If the UTC year is outside ``EPHEMERIS_YEARS`` (inclusive). The message
        names the date and the range.
    """
    d_utc = _naive_utc(date_utc)
    lo_year, hi_year = EPHEMERIS_YEARS
    if not lo_year <= d_utc.year <= hi_year:
        raise ValueError(f"date {d_utc.isoformat()} UTC is outside the ephemeris range "
                         f"{lo_year}-{hi_year}")


def radec_to_unit(ra_deg: float, dec_deg: float) -> np.ndarray:
    """Unit vector of a right ascension and declination.

    Parameters
    ----------
    ra_deg, dec_deg : float
        Right ascension and declination [deg].

    Returns
    -------
    numpy.ndarray
        Shape (3,), ``[cos d cos a, cos d sin a, sin d]``.
    """
    import numpy as np  # here, not above: scenario checks use this module without NumPy

    ra_rad, dec_rad = math.radians(ra_deg), math.radians(dec_deg)
    cd = xmath.cos(dec_rad)
    return np.array([cd * xmath.cos(ra_rad), cd * xmath.sin(ra_rad), xmath.sin(dec_rad)])


def unit_to_radec(u) -> tuple[float, float]:
    """Right ascension and declination of a vector.

    Parameters
    ----------
    u : array_like
        Shape (3,); need not be normalised, must not be zero.

    Returns
    -------
    ra_deg : float
        Right ascension [deg] in [0, 360).
    dec_deg : float
        Declination [deg] in [-90, 90].
    """
    x, y, z = (float(c) for c in u)
    ra_deg = math.degrees(xmath.atan2(y, x)) % 360.0
    if ra_deg >= 360.0:  # -tiny % 360 rounds to 360.0
        ra_deg = 0.0
    return ra_deg, math.degrees(xmath.atan2(z, xmath.hypot(x, y)))


def separation_deg(u, v) -> float:
    """Angle between two vectors.

    Uses ``atan2(|u x v|, u . v)``, accurate near 0 and 180 deg where the
    ``acos`` form loses precision.

    Parameters
    ----------
    u, v : array_like
        Shape (3,); need not be normalised.

    Returns
    -------
    float
        The angle [deg], in [0, 180].
    """
    import numpy as np

    u_arr, v_arr = np.asarray(u, dtype=float), np.asarray(v, dtype=float)
    return math.degrees(xmath.atan2(xmath.norm3(np.cross(u_arr, v_arr)),
                                    xmath.dot3(u_arr, v_arr)))


def sun_direction_inertial(date_utc: datetime) -> np.ndarray:
    """Unit vector from the Earth's centre to the Sun, J2000 frame.

    Parameters
    ----------
    date_utc : datetime
        The date (naive means UTC).

    Returns
    -------
    numpy.ndarray
        Shape (3,), the astrometric geocentric direction of the Sun.

    Raises
    ------
    ValueError
        If the date is outside :data:`EPHEMERIS_YEARS`.
    """
    from allsky.vehicle import ephemeris

    check_date(date_utc)
    return ephemeris.sun_direction_icrf(date_utc)


def sun_motion(date_utc: datetime):
    """The Sun's direction at ``date_utc`` and its rate [1/s], over the next hour.

    The frame loop moves the Sun linearly from the first at the second
    (renormalised each frame): the mission's Sun. The rate is the finite
    difference over one hour, about 1 deg/day.

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        Shape (3,) each: the unit vector, and its derivative [1/s].
    """
    s0 = sun_direction_inertial(date_utc)
    s1 = sun_direction_inertial(date_utc + timedelta(seconds=HOUR_S))
    return s0, (s1 - s0) / HOUR_S


#: Names the catalog gives a second time for a star it already lists (the same place and
#: magnitude), each with the name kept: one star, one name. Any of them still finds the star.
VARIANT_NAMES = {"Adara": "Adhara", "Agena": "Hadar", "Albereo": "Albireo",
                 "Alcaid": "Alkaid", "Etamin": "Eltanin", "Formalhaut": "Fomalhaut",
                 "Gienah Corvi": "Gienah", "Sirrah": "Alpheratz"}


def star_names() -> tuple[str, ...]:
    """Names of all the catalog stars, one per star.

    Returns
    -------
    tuple of str
        Sorted. The catalog lists a few stars twice under variant names
        (:data:`VARIANT_NAMES`: Fomalhaut/Formalhaut, Hadar/Agena,
        Adhara/Adara...); each is named once here, and :func:`star` finds it
        under either name.
    """
    return tuple(sorted(n for n in _catalog() if n not in VARIANT_NAMES))


@functools.cache
def _canonical(name: str) -> str:
    """The catalog spelling of a star name (case-insensitive, spaces trimmed).

    A variant name (:data:`VARIANT_NAMES`) gives the name kept for its star.

    Raises
    ------
    KeyError
        If no catalog star has that name; the message (``args[0]``) names it
        and up to 3 nearest catalog names.
    """
    by_lower = {n.lower(): VARIANT_NAMES.get(n, n) for n in _catalog()}
    key = name.strip().lower()
    if key not in by_lower:
        near = difflib.get_close_matches(key, list(by_lower), n=3, cutoff=0.5)
        hint = (f"; nearest: {', '.join(by_lower[k] for k in near)}" if near
                else "; see allsky.vehicle.sky.star_names()")
        raise KeyError(f"no star named {name!r} in the catalog{hint}")
    return by_lower[key]


class CatalogEntry(NamedTuple):
    """A star as the catalog gives it: its J2000.0 place and proper motion."""

    ra_rad: float  #: [rad] right ascension at J2000.0
    dec_rad: float  #: [rad] declination at J2000.0
    pm_ra_mas_yr: float  #: [mas/yr] proper motion in right ascension, times cos(dec)
    pm_dec_mas_yr: float  #: [mas/yr] proper motion in declination
    magnitude: float  #: visual magnitude


@functools.cache
def _catalog() -> dict:
    """The bright-star catalog by name, read from PyEphem's database text.

    Each line is ``name,f|S|type,ra_h|pm_ra,dec_deg|pm_dec,mag``: right
    ascension in hours and declination in degrees at J2000.0, proper
    motions in mas/yr (the right ascension's times cos dec), and the visual
    magnitude.
    """
    import ephem.stars  # its database text only: the C library computes nothing here

    out = {}
    for line in ephem.stars.db.splitlines():
        if not line.strip():
            continue
        name, rest = line.split(",", 1)
        fields = rest.split(",")
        ra_h, pm_ra = fields[1].split("|")
        dec_deg, pm_dec = fields[2].split("|")
        out[name] = CatalogEntry(math.radians(float(ra_h) * 15.0), math.radians(float(dec_deg)),
                                 float(pm_ra), float(pm_dec), float(fields[3]))
    return out


@functools.lru_cache(maxsize=8192)
def _star_at(name: str, years: float) -> Star:
    """A catalog star ``years`` Julian years after J2000.0 (cached; ``Star`` is immutable)."""
    e = _catalog()[name]
    dec_rad = e.dec_rad + e.pm_dec_mas_yr * MAS2RAD * years
    ra_rad = e.ra_rad + e.pm_ra_mas_yr * MAS2RAD * years / xmath.cos(e.dec_rad)
    return Star(name, math.degrees(ra_rad) % 360.0, math.degrees(dec_rad), e.magnitude)


def _years_since_j2000(date_utc: datetime) -> float:
    """Julian years from J2000.0 to a checked ``datetime``."""
    check_date(date_utc)
    return (_naive_utc(date_utc) - J2000_UTC) / timedelta(seconds=JULIAN_YEAR_S)


def star(name: str, date_utc: datetime | None = None) -> Star:
    """A catalog star by name.

    Parameters
    ----------
    name : str
        Star name, case-insensitive (``"canopus"`` works).
    date_utc : datetime or None
        Date for the position (proper motion applied by PyEphem), naive means
        UTC; ``None`` means J2000.0 (2000-01-01 12:00).

    Returns
    -------
    Star
        With the catalog's spelling of the name.

    Raises
    ------
    KeyError
        Unknown name; the message names it and up to 3 nearest catalog names.
    ValueError
        If the date is outside :data:`EPHEMERIS_YEARS`.
    """
    years = 0.0 if date_utc is None else _years_since_j2000(date_utc)
    return _star_at(_canonical(name), years)


def stars_in_magnitude_window(mag_min: float, mag_max: float,
                              date_utc: datetime | None = None) -> list[Star]:
    """Catalog stars whose magnitude lies in a window.

    Parameters
    ----------
    mag_min, mag_max : float
        Brightest and faintest magnitude accepted (inclusive); ``mag_min``
        is the more negative.
    date_utc : datetime or None
        Date for the positions, as in :func:`star`.

    Returns
    -------
    list of Star
        Brightest first; equal magnitudes in name order.
    """
    # Magnitudes do not depend on the date: filter on the cached J2000 entries,
    # then compute positions for the date only for the stars kept.
    kept = [n for n in star_names() if mag_min <= star(n).magnitude <= mag_max]
    in_window = [star(n, date_utc) for n in kept]
    return sorted(in_window, key=lambda s: s.magnitude)


def star_direction_inertial(name: str, date_utc: datetime | None = None) -> np.ndarray:
    """Unit vector to a catalog star, J2000 frame.

    Parameters
    ----------
    name : str
        Star name, case-insensitive.
    date_utc : datetime or None
        Date for the position, as in :func:`star`.

    Returns
    -------
    numpy.ndarray
        Shape (3,).

    Raises
    ------
    KeyError
        Unknown name.
    ValueError
        If the date is outside :data:`EPHEMERIS_YEARS`.
    """
    s = star(name, date_utc)
    return radec_to_unit(s.ra_deg, s.dec_deg)


def catalog(date_utc: datetime | None = None, magnitude_window=None,
            reference_star: str | None = None) -> list[dict]:
    """The catalog stars at a date, brightest first, with the tracker's view of each.

    Parameters
    ----------
    date_utc : datetime or None
        Date for the positions, as in :func:`star`.
    magnitude_window : (float, float), optional
        The star tracker's magnitude window (brightest, faintest), inclusive.
    reference_star : str, optional
        The planned reference star (``star_tracker.reference_star``).

    Returns
    -------
    list of dict
        ``name``, ``magnitude``, ``ra_deg``, ``dec_deg`` (J2000 at the date),
        ``in_window`` (inside ``magnitude_window``; None without one) and
        ``reference`` (the planned reference star the programmed angles are
        computed for; the tracker itself locks the first star of the window
        its slit meets). Variant names of one star are listed once.
    """
    seen, out = set(), []
    for name in star_names():
        s = star(name, date_utc)
        key = (round(s.ra_deg, 6), round(s.dec_deg, 6), s.magnitude)
        if key in seen:  # one star under two names (VARIANT_NAMES has them all)
            continue
        seen.add(key)
        inside = (None if magnitude_window is None else
                  bool(magnitude_window[0] <= s.magnitude <= magnitude_window[1]))
        out.append({"name": s.name, "magnitude": float(s.magnitude),
                    "ra_deg": float(s.ra_deg), "dec_deg": float(s.dec_deg),
                    "in_window": inside,
                    "reference": s.name == reference_star})
    out.sort(key=lambda r: (r["magnitude"], r["name"]))
    return out


# -- the star tracker's slit, as geometry (allsky.hardware.star_tracker uses it) ------

def cone_angle_deg(sun_star_angle_deg) -> float:
    """The cone angle [deg] of a star this far from the Sun, the roll axis on the Sun.

    The pitch output ``atan2(s_x, s_z)`` of a star at zero yaw, ``s_x = cos
    theta`` along the roll axis and ``s_z = sin theta``: 90 deg - theta.
    ``sun_star_angle_deg`` is theta [deg].
    """
    return 90.0 - float(sun_star_angle_deg)


def edge_pitch_deg(cone_deg, narrow_half_deg) -> float:
    """The pitch output [deg] of a star of cone angle ``cone_deg`` at the slit's edge.

    A roll search brings a star into the slit across its narrow width: the
    tracker finds it at yaw ``narrow_half_deg``, where ``s = (sin c, -cos c
    sin psi, cos c cos psi)`` and the pitch output ``atan2(s_x, s_z)`` is
    ``atan(tan c / cos psi)``, further from zero than the cone angle c. The
    cone-angle check judges this output against the reference star's cone
    angle, so a check passes a star of cone angle c by the slit's own
    geometry, not by c alone.
    """
    c, psi = math.radians(cone_deg), math.radians(narrow_half_deg)
    return math.degrees(xmath.atan(xmath.tan(c) / xmath.cos(psi)))


def check_to_pass_deg(cone_deg, reference_cone_deg, narrow_half_deg) -> float:
    """The smallest cone-angle check [deg] that passes a star met at the slit's edge.

    A star of cone angle ``cone_deg`` found at the edge of a slit of half
    width ``narrow_half_deg`` [deg] is passed by a check larger than this
    (judged against the reference star's cone angle ``reference_cone_deg``),
    refused by one smaller; for the reference star itself
    (``cone_deg == reference_cone_deg``) it is the slit's own offset, which
    no check may be under.
    """
    return abs(edge_pitch_deg(cone_deg, narrow_half_deg) - reference_cone_deg)
