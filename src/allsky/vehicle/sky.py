"""The sky for the emulator: the Sun's direction and the bright-star catalog.

Everything comes from PyEphem: its Sun theory (VSOP87, good across
:data:`EPHEMERIS_YEARS`) and its bundled catalog of bright stars
(``ephem.stars``: Hipparcos positions and proper motions, visual magnitudes,
e.g. Canopus -0.62, Sirius -1.44). Nothing is downloaded; it works offline.

Frame
-----
The inertial frame (``_inertial``) is equatorial J2000: x toward the mean
equinox of J2000.0, z toward the mean north celestial pole of J2000.0. A
direction is the astrometric geocentric position, PyEphem's ``a_ra`` and
``a_dec`` after ``body.compute(date, epoch='2000')``: light-time is included;
precession and nutation to the date and aberration are not. The apparent
place of date differs from it by precession (about 50"/yr in longitude, so
up to ~0.5 deg over decades), nutation (< 20") and aberration (about 20").

Model limits
------------
* Positions are geocentric; the vehicle's position in its orbit is not
  modelled. For the stars the shift is negligible: from a 7000 km baseline
  even Rigil Kentaurus (parallax 0.75" per au) moves by
  ``0.75" * 7000 km / 1 au = 3.5e-5"``, far below 0.001". For the Sun it is
  not below 0.001": the solar horizontal parallax is 8.794" per Earth radius,
  so from a low orbit (r <= 7000 km) the Sun's direction differs from the
  geocentric one by up to ``atan(7000 km / 1 au) = 9.7"``. The emulator
  accepts this: its Sun is the geocentric Sun, used consistently by the
  sensors and the targeting.
* Annual stellar parallax is not in the catalog (at most 0.75", Rigil
  Kentaurus; Canopus 0.01"), and aberration (20.5" from the Earth's orbital
  velocity, about 5" more from the vehicle's) is not applied.

Dates
-----
Dates are ``datetime`` objects in UTC: naive ones are taken as UTC, aware
ones are converted to UTC. PyEphem applies Delta T (TT - UT) itself.
"""

from __future__ import annotations

import difflib
import functools
import math
from datetime import UTC, datetime
from typing import TYPE_CHECKING, NamedTuple

import ephem
import ephem.stars

from allsky.units import HOUR_S

if TYPE_CHECKING:  # NumPy is imported where it computes: checking a scenario needs none
    import numpy as np

#: First and last calendar years (inclusive, UTC) of accepted dates.
#: PyEphem's Sun theory is good across them.
EPHEMERIS_YEARS = (1900, 2100)


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


def _ephem_date(date_utc: datetime) -> float:
    """PyEphem date (Dublin Julian Day, UT) of a checked ``datetime``."""
    check_date(date_utc)
    d_utc = _naive_utc(date_utc)
    return float(ephem.Date((d_utc.year, d_utc.month, d_utc.day, d_utc.hour, d_utc.minute,
                             d_utc.second + d_utc.microsecond * 1e-6)))


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
    return np.array([math.cos(dec_rad) * math.cos(ra_rad),
                     math.cos(dec_rad) * math.sin(ra_rad),
                     math.sin(dec_rad)])


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
    ra_deg = math.degrees(math.atan2(y, x)) % 360.0
    if ra_deg >= 360.0:  # -tiny % 360 rounds to 360.0
        ra_deg = 0.0
    return ra_deg, math.degrees(math.atan2(z, math.hypot(x, y)))


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
    return math.degrees(math.atan2(float(np.linalg.norm(np.cross(u_arr, v_arr))),
                                   float(u_arr @ v_arr)))


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
    sun = ephem.Sun()
    sun.compute(_ephem_date(date_utc), epoch="2000")
    return radec_to_unit(math.degrees(sun.a_ra), math.degrees(sun.a_dec))


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
    from datetime import timedelta

    s0 = sun_direction_inertial(date_utc)
    s1 = sun_direction_inertial(date_utc + timedelta(hours=1))
    return s0, (s1 - s0) / HOUR_S


def star_names() -> tuple[str, ...]:
    """Names of all the catalog stars.

    Returns
    -------
    tuple of str
        Sorted. The catalog lists a few stars twice under variant names
        (e.g. Adara/Adhara, Alcaid/Alkaid).
    """
    return tuple(sorted(ephem.stars.stars))


@functools.cache
def _canonical(name: str) -> str:
    """The catalog spelling of a star name (case-insensitive, spaces trimmed).

    Raises
    ------
    KeyError
        If no catalog star has that name; the message (``args[0]``) names it
        and up to 3 nearest catalog names.
    """
    by_lower = {n.lower(): n for n in ephem.stars.stars}
    key = name.strip().lower()
    if key not in by_lower:
        near = difflib.get_close_matches(key, list(by_lower), n=3, cutoff=0.5)
        hint = (f"; nearest: {', '.join(by_lower[k] for k in near)}" if near
                else "; see allsky.vehicle.sky.star_names()")
        raise KeyError(f"no star named {name!r} in the catalog{hint}")
    return by_lower[key]


@functools.lru_cache(maxsize=8192)
def _star_at(name: str, date_ephem: float) -> Star:
    """A catalog star computed for a PyEphem date (cached; ``Star`` is immutable)."""
    body = ephem.star(name)
    body.compute(date_ephem, epoch="2000")
    return Star(name, math.degrees(body.a_ra), math.degrees(body.a_dec), float(body.mag))


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
    date_ephem = float(ephem.J2000) if date_utc is None else _ephem_date(date_utc)
    return _star_at(_canonical(name), date_ephem)


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
        if key in seen:  # Adara/Adhara, Alcaid/Alkaid: one star
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
