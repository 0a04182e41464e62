"""Checkers of the scenario's particular kinds of value.

Dates, inertia tensors, misalignment matrices, attitudes, mode timeouts,
magnitude windows and star names, built on the vocabulary of
:mod:`allsky.config.rules`: each takes ``(key, value as read from TOML)``,
returns the frozen value or raises :class:`~allsky.config.rules.ConfigError`,
and carries ``allowed``, its rule in words.
"""

import difflib
import functools
import math
from datetime import UTC, date, datetime, time

from allsky import xmath
from allsky.config.rules import (
    EPHEMERIS_END_UTC,
    EPHEMERIS_START_UTC,
    MISALIGNMENT_MAX_ARCSEC,
    MODE_KEYS,
    Cond,
    ConfigError,
    number,
    real_array,
    shown_number,
    type_name,
)


def boolean(key, v):
    """``true`` or ``false``: ``v``, the value of ``key`` as read from TOML."""
    if not isinstance(v, bool):
        raise ConfigError(key, v, f"must be true or false, not {type_name(v)}")
    return v


def utc_datetime(key, v):
    """A date-time in the ephemeris range, returned timezone-aware in UTC.

    ``v`` is the value of ``key`` as read from TOML: a date-time (naive ones
    taken as UTC), a date (its midnight) or an ISO-8601 string.
    """
    shown = v
    if isinstance(v, str):
        try:
            v = datetime.fromisoformat(v.strip())
        except ValueError:
            raise ConfigError(key, shown, "must be an ISO-8601 date-time such as "
                              "2026-11-22T12:00:00Z") from None
    elif isinstance(v, date) and not isinstance(v, datetime):
        v = datetime.combine(v, time(0, 0))
    elif not isinstance(v, datetime):
        raise ConfigError(key, v, f"must be a TOML date-time or an ISO-8601 string, "
                          f"not {type_name(v)}")
    rule = (f"must be within the ephemeris range {EPHEMERIS_START_UTC.date()}.."
            f"{EPHEMERIS_END_UTC.date()} (UTC)")
    try:
        v = v.replace(tzinfo=UTC) if v.tzinfo is None else v.astimezone(UTC)
    except OverflowError:  # year 1 or 9999 moved across midnight by its offset
        raise ConfigError(key, shown, rule) from None
    if not EPHEMERIS_START_UTC <= v <= EPHEMERIS_END_UTC:
        raise ConfigError(key, shown, rule)
    return v


def symmetric_eigenvalues(m) -> tuple:
    """Eigenvalues of the symmetric 3x3 matrix ``m`` (nested sequences), ascending.

    The closed form of Smith (Commun. ACM 4(4), 168, 1961): the eigenvalues
    are ``q + 2 p cos(phi + 2 pi k / 3)`` with ``q`` the mean of the
    diagonal, ``p`` the RMS of ``(m - q I)`` over six, and ``phi`` from the
    determinant of ``(m - q I) / p``. Pure Python, so validating a scenario
    needs no NumPy; accurate to a few units in 1e-16 of the largest
    magnitude, which is all the checks that use it need.
    """
    off = m[0][1] ** 2 + m[0][2] ** 2 + m[1][2] ** 2
    if off == 0.0:
        return tuple(sorted(float(m[i][i]) for i in range(3)))
    q = (m[0][0] + m[1][1] + m[2][2]) / 3.0
    p = math.sqrt(((m[0][0] - q) ** 2 + (m[1][1] - q) ** 2 + (m[2][2] - q) ** 2
                   + 2.0 * off) / 6.0)
    b = [[(m[r][k] - (q if r == k else 0.0)) / p for k in range(3)] for r in range(3)]
    det = (b[0][0] * (b[1][1] * b[2][2] - b[1][2] * b[2][1])
           - b[0][1] * (b[1][0] * b[2][2] - b[1][2] * b[2][0])
           + b[0][2] * (b[1][0] * b[2][1] - b[1][1] * b[2][0]))
    phi = xmath.acos(min(1.0, max(-1.0, det / 2.0))) / 3.0
    largest = q + 2.0 * p * xmath.cos(phi)
    smallest = q + 2.0 * p * xmath.cos(phi + 2.0 * math.pi / 3.0)
    return smallest, 3.0 * q - largest - smallest, largest


def inertia_tensor(key, v):
    """Rigid-body inertia tensor: symmetric, positive definite, triangle inequalities.

    ``v`` is the value of ``key`` as read from TOML, a 3x3 array [kg m^2];
    the upper triangle, mirrored, is returned.
    """
    j = real_array(key, v, (3, 3))
    scale = max(abs(x) for row in j for x in row)
    if scale == 0.0:
        raise ConfigError(key, v, "must be positive definite (all elements are 0)")
    js = [[x / scale for x in row] for row in j]  # dimensionless: no overflow for finite input
    if any(abs(js[r][k] - js[k][r]) > 1e-9 for r in range(3) for k in range(3)):
        raise ConfigError(key, v, "must be symmetric (to a relative 1e-9)")
    # The upper triangle, mirrored: the matrix that is returned.
    a, b, c = symmetric_eigenvalues([[js[min(r, k)][max(r, k)] for k in range(3)]
                                     for r in range(3)])
    moments = ", ".join(f"{m * scale:.6g}" for m in (a, b, c))
    if a <= 1e-12 * c:
        raise ConfigError(key, v, f"must be positive definite (principal moments {moments})")
    if a + b < c * (1 - 1e-9):
        raise ConfigError(key, v, f"principal moments {moments} break the triangle inequality"
                          " (each must be <= the sum of the other two)")
    # Mirror the upper triangle: exactly symmetric, and unchanged when loaded again.
    return tuple(tuple(float(j[min(r, k)][max(r, k)]) for k in range(3)) for r in range(3))


def misalignment_matrix(key, v):
    """Gyro input-axis misalignments: 3x3, zero diagonal, each within 1 degree.

    ``v`` is the value of ``key`` as read from TOML, a 3x3 array [arcsec].
    """
    m = real_array(key, v, (3, 3))
    if any(m[i][i] != 0.0 for i in range(3)):
        raise ConfigError(key, v, "diagonal must be 0: scale-factor error is set by "
                          "gyro.scale_factor_error_ppm")
    if any(abs(x) > MISALIGNMENT_MAX_ARCSEC for row in m for x in row):
        raise ConfigError(key, v, f"every element's magnitude must be <= "
                          f"{shown_number(MISALIGNMENT_MAX_ARCSEC)} arcsec")
    return m


def attitude(key, v):
    """``"random"``, or a quaternion [w, x, y, z] (inertial -> body).

    ``v`` is the value of ``key`` as read from TOML. A quaternion is returned
    normalised (one already of unit length, bit for bit).
    """
    if v == "random":
        return "random"
    if not isinstance(v, list):
        raise ConfigError(key, v, 'must be "random" or a quaternion [w, x, y, z] '
                          "(inertial -> body)")
    given = real_array(key, v, (4,))
    big = max(abs(x) for x in given)
    if big == 0.0:
        raise ConfigError(key, v, "quaternion [w, x, y, z] must not be all zero")
    if abs(math.fsum(x * x for x in given) - 1.0) <= 4e-16:
        return given  # already unit: kept bit for bit, so a saved scenario loads unchanged
    import numpy as np  # only here: validating a scenario otherwise needs no NumPy

    q = np.array(given) / big  # scaled first so that 1e-320 or 1e308 normalise too
    return tuple(float(x) for x in q / math.sqrt(xmath.dot(q, q)))


def mode_timeouts(*conds: Cond):
    """Checker of a table of the ``MODE_KEYS``, each a time [s] obeying all ``*conds``."""
    each = number(*conds)

    def check(key, v):
        if not isinstance(v, dict):
            raise ConfigError(key, v, f"must be a table of the modes {', '.join(MODE_KEYS)}")
        missing = [m for m in MODE_KEYS if m not in v]
        extra = [m for m in v if m not in MODE_KEYS]
        if missing or extra:
            raise ConfigError(key, v, f"must have exactly the modes {', '.join(MODE_KEYS)}")
        return {m: each(f"{key}.{m}", v[m]) for m in MODE_KEYS}
    check.allowed = (f"a table of the modes {', '.join(MODE_KEYS)}, each "
                     + each.allowed.removeprefix("a number, "))
    return check


def magnitude_window(key, v):
    """[brightest, faintest] visual magnitudes, brightest < faintest.

    ``v`` is the value of ``key`` as read from TOML, an array of two numbers.
    """
    lo, hi = real_array(key, v, (2,))
    if not lo < hi:
        raise ConfigError(key, v, "must be [brightest, faintest] with brightest < faintest")
    return (lo, hi)


@functools.cache
def _catalog() -> dict:
    """Lower-case name -> catalog spelling, for every name of the sky's catalog.

    A variant name gives the one its star is kept under (``sky.VARIANT_NAMES``).
    """
    from allsky.vehicle.sky import VARIANT_NAMES, star_names  # PyEphem loads when named

    names = {name.lower(): name for name in star_names()}
    return {**names, **{v.lower(): kept for v, kept in VARIANT_NAMES.items()}}


def star_name(key, v):
    """A star of PyEphem's catalog (any case), returned with its catalog spelling.

    ``v`` is the value of ``key`` as read from TOML, a string.
    """
    if not isinstance(v, str):
        raise ConfigError(key, v, f"must be a star name (a string), not {type_name(v)}")
    found = _catalog().get(v.strip().lower())
    if found is None:
        near = difflib.get_close_matches(v.strip().lower(), list(_catalog()), n=3, cutoff=0.5)
        hint = ("; nearest: " + ", ".join(_catalog()[n] for n in near)) if near else ""
        raise ConfigError(key, v, f"not in the PyEphem star catalog{hint}")
    return found


# Words for the configuration reference (see allsky.config.schema.allowed).
boolean.allowed = "true or false"
utc_datetime.allowed = (f"a date-time (TOML or ISO-8601 string), UTC, within "
                        f"{EPHEMERIS_START_UTC.date()}..{EPHEMERIS_END_UTC.date()}, the "
                        "years allsky.vehicle.sky takes from PyEphem; the whole mission must "
                        "end by then (rules between keys)")
inertia_tensor.allowed = ("a 3x3 array: symmetric, positive definite, principal moments "
                          "obeying the triangle inequality")
misalignment_matrix.allowed = (f"a 3x3 array, diagonal 0, each element within "
                               f"+-{shown_number(MISALIGNMENT_MAX_ARCSEC)}")
attitude.allowed = '"random", or a quaternion [w, x, y, z] (inertial to body; normalised)'
magnitude_window.allowed = "[brightest, faintest], brightest < faintest"
star_name.allowed = "a star name of the PyEphem catalog (any case)"
