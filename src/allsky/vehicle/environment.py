"""What the orbit does: the Earth's shadow and disk, and the torques of low orbit.

The orbit (:mod:`allsky.vehicle.orbit`) is sampled every ``orbit.sample_s``
before flight into :class:`OrbitParams`; the frame loop interpolates the
samples linearly (``at_frame``) and computes, frame by frame:

* **The Sun from the vehicle.** The mission's Sun (``Params.sun0_inertial``
  moving on its line) at its distance, less the vehicle's position: up to
  9.7 arcsec from the geocentric direction in low orbit.
* **The Earth's shadow** (conical: umbra and penumbra). Seen from the
  vehicle, the Sun's disk (angular radius ``a_s``) and the Earth's
  (``a_e = asin((R + h) / r)``, ``R`` the equatorial radius, ``h``
  ``orbit.atmosphere_height_km``) are circles ``c`` apart; the visible
  fraction of the Sun's disk is one less the area of their overlap over the
  Sun's, the overlap of two plane circles (Montenbruck and Gill 2000,
  eq. 3.87; :func:`visible_fraction`). Taking the Earth's limb as a plane
  circle across the Sun's 0.27 deg disk errs by under 1e-3 of the fraction.
  The limb is taken sharp at ``R + h``: refraction and the atmosphere's
  extinction (a few seconds of a setting Sun's light) are left out. The
  fraction scales sun sensor 104's signal; in the umbra (fraction 0) it
  sees no Sun.
* **The Earth's disk** occulting a star or the target: its direction within
  ``a_e`` of the Earth's centre. An occulted star is taken out of star
  tracker 105's view.
* **The sunlit Earth in star tracker 105's slit.** The slit is bounded by
  four great circles (pitch = +-``fov_long_half``, yaw = +-``fov_narrow_half``).
  The tracker is blinded while any sunlit point of the Earth's visible disk
  lies in it (:func:`earth_glare`): it finds no star and holds none. The
  decision is geometric, in closed form: the disk reaches into the slit where
  the largest cosine between the disk's centre and a point of the slit
  exceeds ``cos a_e`` (the slit's interior, its four edges and its corners,
  :func:`_disk_in_slit`); a point of the Earth's surface, unit normal ``n``,
  is sunlit where ``n . s > 0``, and the surface points seen in the slit are
  those meeting five linear constraints on ``n`` (in view from the vehicle,
  and inside each of the slit's four planes), whose largest ``n . s`` is found
  among the Sun's own point, each constraint circle's highest point and the
  circles' crossings (:func:`brightest_in_slit`). Why geometry and not a
  flux: a Lambertian Earth of albedo :data:`EARTH_ALBEDO` lit at incidence
  ``i`` is ``2.4 - 2.5 log10(cos i)`` mag/arcsec^2, so a sunlit area of
  1e-9 sr (a sliver 0.0004 arcsec wide along the slit) already outshines the
  bright end of a window at -1 mag, and the whole slit (0.153 sr) sunlit is
  about -22 mag. The Sun is taken as a point for the terminator (its
  0.27 deg disk softens it), and the direction to it from the vehicle for
  every point of the Earth (they differ by at most 4.3e-5 rad).
* **Torques** on the body, held over the frame (the frame loop adds them to
  the jets'): gravity gradient ``3 mu / r^3 n x (J n)`` (``n`` the unit
  vector to the Earth's centre, body axes, ``J`` the full inertia tensor);
  drag ``-1/2 rho C_D A abs(w) w`` through the centre of pressure (``w`` the
  velocity relative to an atmosphere turning with the Earth, ``rho`` the
  exponential atmosphere of :data:`DENSITY_TABLE`); solar radiation pressure
  ``-P C_r A f s`` through its own centre (``P`` = 4.56e-6 N/m^2 at 1 au,
  ``f`` the visible fraction, ``s`` the unit vector to the Sun). The areas
  are constant: the attitude's effect on them is left out.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from allsky import xarrays, xmath
from allsky.jit import njit, njit_alloc, njit_stage
from allsky.vehicle.orbit import MU_EARTH_M3_S2, R_EARTH_M

#: [m] the Sun's radius (IAU 2015 nominal)
R_SUN_M = 6.957e8
#: [m] the astronomical unit
AU_M = 1.495978707e11
#: [N/m^2] solar radiation pressure on a black surface at 1 au (1361 W/m^2 / c)
SOLAR_PRESSURE_N_M2 = 4.54e-6
#: [rad/s] the Earth's rotation (the atmosphere turns with it)
EARTH_RATE_RAD_S = 7.292115e-5
#: The exponential atmosphere (Vallado 2013, table 8-4): base altitude [km], density at
#: it [kg/m^3], scale height [km]; ``rho = rho0 exp(-(h - h0) / H)`` from the base below.
#: Its densities are a mean solar activity's: a solar maximum raises those at 300 km
#: fivefold, a minimum halves them.
DENSITY_TABLE = (
    (100.0, 5.297e-7, 5.877), (110.0, 9.661e-8, 7.263), (120.0, 2.438e-8, 9.473),
    (130.0, 8.484e-9, 12.636), (140.0, 3.845e-9, 16.149), (150.0, 2.070e-9, 22.523),
    (180.0, 5.464e-10, 29.740), (200.0, 2.789e-10, 37.105), (250.0, 7.248e-11, 45.546),
    (300.0, 2.418e-11, 53.628), (350.0, 9.518e-12, 53.298), (400.0, 3.725e-12, 58.515),
    (450.0, 1.585e-12, 60.828), (500.0, 6.967e-13, 63.822), (600.0, 1.454e-13, 71.835),
    (700.0, 3.614e-14, 88.667), (800.0, 1.170e-14, 124.64), (900.0, 5.245e-15, 181.05),
    (1000.0, 3.019e-15, 268.00),
)

# Columns of OrbitParams.scalars, one row per sample.
SEP = 0  #: [rad] angle between the Sun's centre and the Earth's, seen from the vehicle
EARTH_RADIUS = 1  #: [rad] the Earth's angular radius (with the atmosphere height)
SUN_RADIUS = 2  #: [rad] the Sun's angular radius
EARTH_COS = 3  #: [-] cosine of EARTH_RADIUS
GG = 4  #: [1/s^2] 3 mu / r^3
DRAG = 5  #: [N / (m/s)^2] 1/2 rho C_D A (0 with the aerodynamic torque off)
SRP = 6  #: [N] P (1 au / d)^2 C_r A (0 with the solar pressure torque off)
#: 1.0 where the Sun is whole at this sample and the next (the loop skips the shadow's
#: computation between them), 0.0 elsewhere
WHOLE = 7
#: 1.0 where the Earth's disk begins or ends hiding a window star between this sample and
#: the next (the loop tests the stars frame by frame only there), 0.0 elsewhere
CHANGES = 8
#: [-] cosine of the Earth's angular radius plus the slit's corner angle from the
#: boresight: with the boresight's cosine from the nadir below it (less
#: :data:`REACH_MARGIN`), no part of the Earth can be in star tracker 105's slit
SLIT_REACH = 9
#: 1.0 where the Sun is behind the Earth's disk by more than :data:`UMBRA_MARGIN` at this
#: sample and the next, 0.0 elsewhere: the frames between are in the umbra, the rounding
#: of their interpolated angles included (the loop skips the shadow's computation there)
UMBRA = 10
N_SCALARS = 11
#: [rad] margin of UMBRA: far above the rounding of the three interpolated angles
#: (about 1e-15 rad), far below a frame's motion of the shadow's edge (about 1e-5 rad)
UMBRA_MARGIN = 1e-9
#: [-] margin on SLIT_REACH: far above the error of interpolating it between samples
REACH_MARGIN = 1e-6
#: [-] the Earth's albedo, its surface taken as Lambertian (the Bond albedo, 0.30)
EARTH_ALBEDO = 0.30
#: [mag] the Sun's visual magnitude
SUN_MAGNITUDE = -26.74
#: [-] a candidate point of :func:`brightest_in_slit` meets a constraint within this
FEASIBLE_TOL = 1e-12

# Entries of OrbitParams.env, the frame's environment (written by at_frame and the loop).
E_SUNLIT = 0  #: [-] visible fraction of the Sun's disk
E_GG = 1  #: [N m] magnitude of the gravity-gradient torque this frame
E_AERO = 2  #: [N m] of the aerodynamic torque
E_SRP = 3  #: [N m] of the solar radiation pressure torque
N_ENV = 4
# Rows of OrbitParams.peak: the largest torque magnitude [N m] and the angular impulse
# [N m s] (abs summed per axis) of each torque since ejection.
PEAK, IMPULSE = 0, 1


class OrbitParams(NamedTuple):
    """The orbit's samples and the environment's constants, for the frame loop."""

    n: int  #: samples (0: no orbit)
    step_frames: int  #: [frames] between samples
    sun_i: np.ndarray  #: (n, 3) unit vector, vehicle to the Sun, inertial
    nadir_i: np.ndarray  #: (n, 3) unit vector, vehicle to the Earth's centre
    wind_i: np.ndarray  #: [m/s] (n, 3) velocity relative to the atmosphere
    scalars: np.ndarray  #: (n, N_SCALARS) the columns SEP ... UMBRA
    gravity_gradient: bool  #: the gravity-gradient torque acts
    pressure_offset_m: np.ndarray  #: [m] (3,) centre of pressure, body axes
    srp_offset_m: np.ndarray  #: [m] (3,) centre of solar pressure, body axes
    stars_inertial: np.ndarray  #: (m, 3) the window's stars (as the tracker's)
    tracker: object  #: star tracker 105 whose stars the frame loop hides while occulted
    env: np.ndarray  #: (N_ENV,) the frame's environment, written by the loop
    work: np.ndarray  #: (4, 3) the frame's nadir, wind, Sun (body) and a torque, written
    peak: np.ndarray  #: (2, 3) PEAK and IMPULSE per torque (gg, aero, srp), updated
    #: (n, b, 3) each moving body seen from the vehicle in each sample interval (b = 0: none
    #: flown; allsky.sim.sky_rows)
    bodies_i: np.ndarray
    body_rows: np.ndarray  #: (b,) int: each body's row of ``stars_inertial``, -1 if none
    gate_rows: np.ndarray  #: (b,) int: its row of the tracker's gate stars, -1 if none
    body_k: np.ndarray  #: (1,) int: the sample interval the bodies' rows hold (-1: none yet)
    #: (6, 3) star tracker 105's slit (:func:`slit_geometry`): its planes and corners
    slit: np.ndarray
    blind: object  #: the tracker while the sunlit Earth blinds it: no star, no gate star


def no_orbit(tracker) -> OrbitParams:
    """The :class:`OrbitParams` of ``kind = "none"`` (``tracker``; never read)."""
    z3 = np.zeros((0, 3))
    none = np.zeros(0, dtype=np.int64)
    return OrbitParams(0, 1, z3, z3.copy(), z3.copy(), np.zeros((0, N_SCALARS)), False,
                       np.zeros(3), np.zeros(3), z3.copy(), tracker, np.zeros(N_ENV),
                       np.zeros((4, 3)), np.zeros((2, 3)), np.zeros((0, 0, 3)), none,
                       none.copy(), np.full(1, -1, dtype=np.int64), np.zeros((6, 3)), tracker)


def slit_geometry(fov_long_half_rad, fov_narrow_half_rad) -> np.ndarray:
    """Star tracker 105's slit as :func:`earth_glare` reads it, (6, 3).

    ``fov_long_half_rad`` [rad] is the half field along the slit, ``P``;
    ``fov_narrow_half_rad`` [rad] the half field across it, ``Y``. Row 0: ``sin P, cos P, cos P tan Y`` and row 1: ``sin Y, cos Y, cos Y tan P``
    (``P`` the half field along the slit, the pitch output's; ``Y`` across,
    the yaw output's; the third entries are the tangents of each edge's half
    length seen from the boresight's plane). Rows 2-5: the four corners, unit
    vectors in body axes (+z the boresight).
    """
    p, y = float(fov_long_half_rad), float(fov_narrow_half_rad)
    sp, cp, sy, cy = xmath.sin(p), xmath.cos(p), xmath.sin(y), xmath.cos(y)
    tp, ty = sp / cp, sy / cy
    out = np.zeros((6, 3))
    out[0] = sp, cp, cp * ty
    out[1] = sy, cy, cy * tp
    n = math.sqrt(tp * tp + ty * ty + 1.0)
    for i, (a, b) in enumerate(((1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0))):
        out[2 + i] = a * tp / n, b * ty / n, 1.0 / n
    return out


def blind_tracker(tracker):
    """Star tracker 105 as the sunlit Earth leaves it: blind.

    ``tracker`` (the mission's tracker parameters) with no star in view and
    none for its bright gate.
    """
    z3 = np.zeros((0, 3))
    return tracker._replace(stars_inertial=z3, magnitudes=np.zeros(0),
                            gate_stars_inertial=z3.copy(), gate_magnitudes=np.zeros(0))


def density_kg_m3(altitude_m):
    """The exponential atmosphere's density [kg/m^3] at ``altitude_m`` (array) [m]."""
    h = np.asarray(altitude_m, dtype=float) / 1000.0
    base = np.array([row[0] for row in DENSITY_TABLE])
    k = np.clip(np.searchsorted(base, h, side="right") - 1, 0, len(base) - 1)
    h0 = base[k]
    rho0 = np.array([row[1] for row in DENSITY_TABLE])[k]
    scale = np.array([row[2] for row in DENSITY_TABLE])[k]
    x = -(h - h0) / scale
    return rho0 * np.array([xmath.exp(float(v)) for v in np.ravel(x)]).reshape(np.shape(x))


def _angle_rows(u, v):
    """Angle [rad] between the rows of ``u`` and ``v`` (atan2 of cross and dot)."""
    cr = np.cross(u, v)
    return xarrays.atan2_many(xarrays.norm_rows(cr), (u * v).sum(axis=1))


def samples(track, sun0, sun_rate, sun_distance_m, atmosphere_height_m,
            inertia_kg_m2=None, cfg_orbit=None):
    """The per-sample geometry of ``track`` (:class:`allsky.vehicle.orbit.Track`).

    ``sun0`` and ``sun_rate`` [1/s] are the mission's geocentric Sun on its
    line (``Params.sun0_inertial``, ``sun_rate_inertial``), ``sun_distance_m``
    its distance, ``atmosphere_height_m`` [m] the height added to the Earth's
    radius (``inertia_kg_m2`` is unused). Returns ``(sun_i, nadir_i, wind_i, scalars)`` as
    :class:`OrbitParams` holds them; with ``cfg_orbit`` (the ``[orbit]``
    section) the torques' factors are filled in, else they are zero.
    """
    t, r = track.t_s, track.r_m
    s = sun0[None, :] + sun_rate[None, :] * t[:, None]
    s = s / xarrays.norm_rows(s)[:, None] * sun_distance_m
    sun_vec = s - r
    d_sun = xarrays.norm_rows(sun_vec)
    rn = xarrays.norm_rows(r)
    nadir = -r / rn[:, None]
    sun_i = sun_vec / d_sun[:, None]
    sc = np.zeros((t.shape[0], N_SCALARS))
    sc[:, SEP] = _angle_rows(sun_i, nadir)
    re = R_EARTH_M + atmosphere_height_m
    sc[:, EARTH_RADIUS] = xarrays.atan2_many(re, np.sqrt(rn * rn - re * re))
    sc[:, SUN_RADIUS] = xarrays.atan2_many(R_SUN_M, np.sqrt(d_sun * d_sun - R_SUN_M * R_SUN_M))
    sc[:, EARTH_COS] = np.sqrt(rn * rn - re * re) / rn
    sc[:, GG] = 3.0 * MU_EARTH_M3_S2 / (rn * rn * rn)
    wind = track.v_m_s.copy()
    wind[:, 0] += EARTH_RATE_RAD_S * r[:, 1]  # v - omega x r, omega along +z
    wind[:, 1] -= EARTH_RATE_RAD_S * r[:, 0]
    if cfg_orbit is not None:
        o = cfg_orbit
        if o.aerodynamic:
            sc[:, DRAG] = (0.5 * float(o.drag_coefficient) * float(o.drag_area_m2)
                           * density_kg_m3(rn - R_EARTH_M))
        if o.solar_pressure:
            sc[:, SRP] = (SOLAR_PRESSURE_N_M2 * (AU_M / d_sun) ** 2
                          * float(o.srp_reflectivity) * float(o.srp_area_m2))
    return sun_i, nadir, wind, sc


def _flags(sc, nadir, stars, bodies_i=None):
    """Fill the WHOLE, UMBRA and CHANGES columns of ``sc`` from the samples' geometry.

    ``bodies_i`` (n, b, 3), the moving bodies' rows by sample, flag an
    interval as the stars do.
    """
    whole = sc[:, SEP] >= sc[:, EARTH_RADIUS] + sc[:, SUN_RADIUS]
    sc[:-1, WHOLE] = (whole[:-1] & whole[1:]).astype(float)
    # Each angle's interpolation is linear between the samples up to its rounding, so a margin
    # kept at both ends is kept between them
    umbra = sc[:, SEP] + sc[:, SUN_RADIUS] <= sc[:, EARTH_RADIUS] - UMBRA_MARGIN
    sc[:-1, UMBRA] = (umbra[:-1] & umbra[1:]).astype(float)
    if stars.shape[0]:
        # a star's angle from the nadir changes by at most the orbit's rate times the step:
        # flag an interval whose either end lies within that much of the limb, or whose ends
        # differ
        # each star's cosine from the nadir, summed in axis order (no BLAS: the same bits
        # on every machine)
        cos_nadir = (nadir[:, 0:1] * stars[None, :, 0] + nadir[:, 1:2] * stars[None, :, 1]
                     + nadir[:, 2:3] * stars[None, :, 2])
        hidden = cos_nadir > sc[:, EARTH_COS][:, None]
        if bodies_i is not None and bodies_i.shape[1]:
            cos_b = (nadir[:, 0:1] * bodies_i[:, :, 0] + nadir[:, 1:2] * bodies_i[:, :, 1]
                     + nadir[:, 2:3] * bodies_i[:, :, 2])
            hidden = np.hstack([hidden, cos_b > sc[:, EARTH_COS][:, None]])
        differ = (hidden[:-1] != hidden[1:]).any(axis=1)
        sc[:-1, CHANGES] = differ.astype(float)
    sc[-1, WHOLE] = sc[-2, WHOLE] if sc.shape[0] > 1 else 0.0
    sc[-1, UMBRA] = sc[-2, UMBRA] if sc.shape[0] > 1 else 0.0


def build(cfg, track, sun0, sun_rate, step_frames, tracker, bodies_i=None, body_rows=None,
          gate_rows=None) -> OrbitParams:
    """:class:`OrbitParams` of the scenario ``cfg`` for its ``track`` (None: no orbit).

    ``sun0``, ``sun_rate`` are the mission's Sun on its line, ``step_frames``
    the frames between samples, ``tracker`` star tracker 105's parameters; the loop's copy of it gets
    its own star array, whose rows of occulted stars it zeroes. ``bodies_i``,
    ``body_rows`` and ``gate_rows`` are the moving bodies' directions by sample
    interval and their rows of the tracker's stars and gate stars
    (:mod:`allsky.sim.sky_rows`; None: no bodies).
    """
    if track is None:
        return no_orbit(tracker)
    from allsky.vehicle import ephemeris

    o = cfg.orbit
    d_sun = float(xmath.norm3(ephemeris.sun_from_earth_km(
        ephemeris.tdb_jd(cfg.mission.date_utc)))) * 1000.0
    sun_i, nadir, wind, sc = samples(track, np.asarray(sun0, float), np.asarray(sun_rate, float),
                                     d_sun, o.atmosphere_height_km * 1000.0, cfg_orbit=o)
    stars = np.ascontiguousarray(tracker.stars_inertial.copy())
    none = np.zeros(0, dtype=np.int64)
    if bodies_i is None or not (np.any(body_rows >= 0) or np.any(gate_rows >= 0)):
        bodies_i, body_rows, gate_rows = np.zeros((sun_i.shape[0], 0, 3)), none, none.copy()
    _flags(sc, nadir, stars[np.setdiff1d(np.arange(stars.shape[0]), body_rows)], bodies_i)
    slit = slit_geometry(tracker.fov_long_half_rad, tracker.fov_narrow_half_rad)
    corner = xmath.acos(float(slit[2, 2]))  # [rad] a corner's angle from the boresight
    sc[:, SLIT_REACH] = [xmath.cos(min(a + corner, math.pi)) for a in sc[:, EARTH_RADIUS]]
    # the loop's tracker: its own star array, and its own gate array where bodies move in it
    own = tracker._replace(stars_inertial=stars.copy())
    if np.any(gate_rows >= 0):
        own = own._replace(gate_stars_inertial=np.ascontiguousarray(
            tracker.gate_stars_inertial.copy()))
    return OrbitParams(int(track.t_s.shape[0]), int(step_frames), np.ascontiguousarray(sun_i),
                       np.ascontiguousarray(nadir), np.ascontiguousarray(wind),
                       np.ascontiguousarray(sc), bool(o.gravity_gradient),
                       np.array(o.pressure_offset_m, dtype=float),
                       np.array(o.srp_offset_m, dtype=float), stars, own, np.zeros(N_ENV),
                       np.zeros((4, 3)), np.zeros((2, 3)), np.ascontiguousarray(bodies_i),
                       np.asarray(body_rows, dtype=np.int64),
                       np.asarray(gate_rows, dtype=np.int64), np.full(1, -1, dtype=np.int64),
                       slit, blind_tracker(own))


@njit
def visible_fraction(c, a_s, a_e):
    """Visible fraction of the Sun's disk (radius ``a_s``) beside the Earth's ``a_e``.

    ``c`` [rad] is the angle between their centres. Overlap of two plane
    circles (Montenbruck and Gill, eq. 3.87).
    """
    if c >= a_s + a_e:
        return 1.0
    if c <= a_e - a_s:
        return 0.0
    if c <= a_s - a_e:  # the Earth inside the Sun's disk (never in Earth orbit)
        return 1.0 - (a_e * a_e) / (a_s * a_s)
    x = (c * c + a_s * a_s - a_e * a_e) / (2.0 * c)
    y = np.sqrt(max(a_s * a_s - x * x, 0.0))
    area = (a_s * a_s * xmath.acos(min(max(x / a_s, -1.0), 1.0))
            + a_e * a_e * xmath.acos(min(max((c - x) / a_e, -1.0), 1.0)) - c * y)
    return 1.0 - area / (math.pi * a_s * a_s)


@njit_stage
def place(orbit, frame):
    """``(k, w)`` of ``frame`` in ``orbit``: ``w`` of the way from sample k to k + 1.

    Held at the last interval past the samples.
    """
    step = orbit.step_frames
    k = frame // step
    if k >= orbit.n - 1:
        return orbit.n - 2, 1.0
    return k, (frame - k * step) / step


@njit_stage
def start_place(orbit, frame):
    """``(k, j)``: ``frame`` is ``j`` frames after sample ``k`` of ``orbit``."""
    k = frame // orbit.step_frames
    return k, frame - k * orbit.step_frames


@njit_stage
def next_place(orbit, k, j):
    """``(k, j, w)`` of the frame after the one ``k``, ``j`` place in ``orbit``.

    Past the last interval the last sample is held (``k = n - 2``, ``w = 1``).
    """
    j += 1
    if j == orbit.step_frames:
        j = 0
        k += 1
    if k >= orbit.n - 1:
        return k, j, 1.0
    return k, j, j / orbit.step_frames


@njit_stage
def held(orbit, k, w):
    """``k``, ``w`` held at the last interval past the samples of ``orbit``."""
    if k >= orbit.n - 1:
        return orbit.n - 2, 1.0
    return k, w


@njit_stage
def _lerp_unit(a, k, w, out):
    """Row ``k`` of ``a`` moved ``w`` of the way to row ``k + 1``, renormalised, into ``out``."""
    n = 0.0
    for i in range(3):
        out[i] = a[k, i] + w * (a[k + 1, i] - a[k, i])
        n += out[i] * out[i]
    n = 1.0 / np.sqrt(n)
    for i in range(3):
        out[i] *= n


@njit_stage
def _lerp(a, k, w, j):
    return a[k, j] + w * (a[k + 1, j] - a[k, j])


@njit_stage
def sunlit_at(orbit, frame):
    """Visible fraction of the Sun's disk at ``frame`` of ``orbit`` (interpolated)."""
    k, w = place(orbit, frame)
    return _sun_fraction(orbit.scalars, k, w)


@njit_stage
def _sun_fraction(sc, k, w):
    """Visible fraction of the Sun ``w`` of the way through interval ``k`` of the samples ``sc``.

    The loop's rule and the journal's: whole where both ends are (``WHOLE``),
    none in the umbra (``UMBRA``, which :func:`visible_fraction` would give
    frame by frame), else the interpolated angles' overlap.
    """
    if sc[k, WHOLE] != 0.0:
        return 1.0
    if sc[k, UMBRA] != 0.0:
        return 0.0
    return visible_fraction(_lerp(sc, k, w, SEP), _lerp(sc, k, w, SUN_RADIUS),
                            _lerp(sc, k, w, EARTH_RADIUS))


@njit_stage
def sun_at(orbit, k, w, out):
    """Unit vector from the vehicle to the Sun, inertial, into ``out``.

    ``orbit``'s samples; ``k``, ``w`` place the frame between samples (:func:`place`).
    """
    _lerp_unit(orbit.sun_i, k, w, out)


@njit_stage
def occult_stars(orbit, k, w, force):
    """Hide the stars behind the Earth from the loop's tracker; the Sun's fraction.

    ``orbit``'s samples; ``k``, ``w`` place the frame between samples (:func:`place`). The stars
    are tested at each sample, in each interval where one of them is hidden
    or uncovered, and with ``force`` (a leg's first frame). Writes the
    frame's nadir into ``orbit.work[0]`` and its visible fraction of the Sun
    into ``orbit.env[E_SUNLIT]``.
    """
    nadir = orbit.work[0]
    _lerp_unit(orbit.nadir_i, k, w, nadir)
    sc = orbit.scalars
    if orbit.body_rows.shape[0] and orbit.body_k[0] != k:  # a new interval: the bodies move
        _move_bodies(orbit, k)
        force = True
    if force or w == 0.0 or sc[k, CHANGES] != 0.0:  # a sample, or where a star changes
        _occult(orbit, nadir, _lerp(sc, k, w, EARTH_COS))
    f = _sun_fraction(sc, k, w)
    orbit.env[E_SUNLIT] = f
    return f


@njit_stage
def _move_bodies(orbit, k):
    """The moving bodies' rows of the tracker's stars and gate stars: interval ``k``'s."""
    src = orbit.stars_inertial
    gate = orbit.tracker.gate_stars_inertial
    for j in range(orbit.body_rows.shape[0]):
        row = orbit.body_rows[j]
        if row >= 0:
            for i in range(3):
                src[row, i] = orbit.bodies_i[k, j, i]
        row = orbit.gate_rows[j]
        if row >= 0:
            for i in range(3):
                gate[row, i] = orbit.bodies_i[k, j, i]
    orbit.body_k[0] = k


@njit_stage
def _occult(orbit, nadir, cos_e):
    """Zero the loop tracker's rows of the stars within the Earth's disk (``cos_e``)."""
    src = orbit.stars_inertial
    dst = orbit.tracker.stars_inertial
    for j in range(src.shape[0]):
        d = src[j, 0] * nadir[0] + src[j, 1] * nadir[1] + src[j, 2] * nadir[2]
        if d > cos_e:  # behind the Earth's disk: seen nowhere
            dst[j, 0] = 0.0
            dst[j, 1] = 0.0
            dst[j, 2] = 0.0
        else:
            dst[j, 0] = src[j, 0]
            dst[j, 1] = src[j, 1]
            dst[j, 2] = src[j, 2]


@njit
def _disk_in_slit(sl, cx, cy, cz, ce):
    """Whether the Earth's disk reaches into star tracker 105's slit ``sl``.

    ``cx``, ``cy``, ``cz`` are the unit vector to the Earth's centre in body axes,
    ``ce`` the cosine of the disk's angular radius; ``sl`` is
    :func:`slit_geometry`'s. The largest cosine between the centre and a
    point of the slit is 1 with the centre inside; else it lies on an edge
    (a great circle's arc: ``A cos t + B sin t`` at its top, where that falls
    within the arc) or at a corner.
    """
    sp, cp, tp = sl[0, 0], sl[0, 1], sl[0, 2]
    sy, cy_, ty = sl[1, 0], sl[1, 1], sl[1, 2]
    if cz > 0.0 and abs(cx) * cp <= cz * sp and abs(cy) * cy_ <= cz * sy:
        return True
    ce2 = ce * ce
    for sgn in (1.0, -1.0):
        a = sgn * cx * sp + cz * cp  # the pitch edges, t measured along each
        if a > 0.0 and abs(cy) <= a * tp and a * a + cy * cy > ce2:
            return True
        a = sgn * cy * sy + cz * cy_  # the yaw edges
        if a > 0.0 and abs(cx) <= a * ty and a * a + cx * cx > ce2:
            return True
    for i in range(2, 6):
        if cx * sl[i, 0] + cy * sl[i, 1] + cz * sl[i, 2] > ce:
            return True
    return False


@njit
def _meets(caps, bs, px, py, pz, skip1, skip2):
    """Whether the point ``p`` meets every constraint ``caps[j] . p >= bs[j]`` but two."""
    for j in range(5):
        if j != skip1 and j != skip2:
            a = caps[j]
            if a[0] * px + a[1] * py + a[2] * pz < bs[j] - FEASIBLE_TOL:
                return False
    return True


#: [-] ``enough`` of :func:`brightest_in_slit` that no incidence cosine exceeds: the full search
FULL_SEARCH = 2.0


@njit
def brightest_in_slit(sl, cx, cy, cz, ce, ux, uy, uz, enough=FULL_SEARCH):
    """The Sun's incidence cosine at the slit's most directly lit point of Earth.

    ``cx``, ``cy``, ``cz`` are the unit vector to the Earth's centre and
    ``ux``, ``uy``, ``uz`` to the Sun, body axes; ``ce`` the cosine of the Earth's angular radius;
    ``sl`` the slit (:func:`slit_geometry`). Returns -2.0 where no point of
    the Earth is in the slit; a value at most 0 where only its night side is.

    In units of the Earth's radius (with the atmosphere height) the vehicle is
    at ``-c / sin a_e``. A surface point of unit normal ``n`` is in view where
    ``-c . n >= sin a_e``, and in the slit where it lies inside each of the
    slit's four planes through the vehicle, ``m . n >= -(m . c) / sin a_e``
    (``m`` a plane's inward normal): five constraints linear in ``n``. The
    largest ``n . u`` over the points meeting them is at the Sun's own point
    (``n = u``), or at the highest point of one constraint's circle, or where
    two circles cross; the candidates meeting every constraint are compared.
    A candidate is tested against the constraints only where it would be the
    largest so far. With ``enough`` below 1, the search stops at the first
    candidate above it and returns that value (not always the largest):
    :func:`earth_glare` asks only whether any point is sunlit (``enough =
    0``), and the night side's candidates, all at most 0, are then never
    tested against the constraints.
    """
    sa = np.sqrt(max(1.0 - ce * ce, 0.0))
    sp, cp = sl[0, 0], sl[0, 1]
    sy, cy_ = sl[1, 0], sl[1, 1]
    caps = ((-cx, -cy, -cz), (-cp, 0.0, sp), (cp, 0.0, sp), (0.0, -cy_, sy), (0.0, cy_, sy))
    bs = (sa, (cp * cx - sp * cz) / sa, -(cp * cx + sp * cz) / sa,
          (cy_ * cy - sy * cz) / sa, -(cy_ * cy + sy * cz) / sa)
    if _meets(caps, bs, ux, uy, uz, -1, -1):
        return 1.0
    best = -2.0
    for j in range(5):  # the highest point of each circle
        b = bs[j]
        if abs(b) >= 1.0:
            continue
        a = caps[j]
        t = a[0] * ux + a[1] * uy + a[2] * uz
        vx, vy, vz = ux - t * a[0], uy - t * a[1], uz - t * a[2]
        nv2 = vx * vx + vy * vy + vz * vz
        if nv2 < 1e-24:
            continue
        r = np.sqrt((1.0 - b * b) / nv2)
        v = b * t + r * nv2
        if v > best:
            px, py, pz = b * a[0] + r * vx, b * a[1] + r * vy, b * a[2] + r * vz
            if _meets(caps, bs, px, py, pz, j, -1):
                best = v
                if best > enough:
                    return best
    for j in range(5):  # where two circles cross
        for k in range(j + 1, 5):
            aj, ak = caps[j], caps[k]
            bj, bk = bs[j], bs[k]
            d = aj[0] * ak[0] + aj[1] * ak[1] + aj[2] * ak[2]
            den = 1.0 - d * d
            if den < 1e-15:
                continue
            al = (bj - d * bk) / den
            be = (bk - d * bj) / den
            g2 = (1.0 - (al * bj + be * bk)) / den
            if g2 < 0.0:
                continue
            g = np.sqrt(g2)
            wx = aj[1] * ak[2] - aj[2] * ak[1]
            wy = aj[2] * ak[0] - aj[0] * ak[2]
            wz = aj[0] * ak[1] - aj[1] * ak[0]
            for sgn in (1.0, -1.0):
                px = al * aj[0] + be * ak[0] + sgn * g * wx
                py = al * aj[1] + be * ak[1] + sgn * g * wy
                pz = al * aj[2] + be * ak[2] + sgn * g * wz
                v = px * ux + py * uy + pz * uz
                if v > best and _meets(caps, bs, px, py, pz, j, k):
                    best = v
                    if best > enough:
                        return best
    return best


@njit
def _body_rows(q):
    """The rows of the body-from-inertial matrix of ``q`` (quaternion.dcm_body_from_inertial)."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    r0 = (w * w + x * x - y * y - z * z, 2.0 * (x * y + w * z), 2.0 * (x * z - w * y))
    r1 = (2.0 * (x * y - w * z), w * w - x * x + y * y - z * z, 2.0 * (y * z + w * x))
    r2 = (2.0 * (x * z + w * y), 2.0 * (y * z - w * x), w * w - x * x - y * y + z * z)
    return r0, r1, r2


@njit_stage
def earth_glare(orbit, k, w, q, sun_i):
    """Whether sunlit Earth lies in star tracker 105's slit at attitude ``q``.

    ``orbit``'s samples; ``k``, ``w`` place the frame between samples
    (:func:`place`); ``sun_i`` is the unit vector to the Sun, inertial. Call
    :func:`occult_stars` first in the frame (it leaves the frame's nadir in
    ``orbit.work[0]``). Most frames end at the first test: the boresight too
    far from the nadir (``SLIT_REACH``) for any of the Earth to be in the
    slit. Where the disk is in it, a vehicle whose whole visible Earth is
    sunlit (or dark) is answered at once, and only near the terminator is the
    slit's brightest point found (:func:`brightest_in_slit`).
    """
    nadir = orbit.work[0]
    r0, r1, r2 = _body_rows(q)
    sc = orbit.scalars
    cz = r2[0] * nadir[0] + r2[1] * nadir[1] + r2[2] * nadir[2]
    if cz < _lerp(sc, k, w, SLIT_REACH) - REACH_MARGIN:
        return False
    cx = r0[0] * nadir[0] + r0[1] * nadir[1] + r0[2] * nadir[2]
    cy = r1[0] * nadir[0] + r1[1] * nadir[1] + r1[2] * nadir[2]
    ce = _lerp(sc, k, w, EARTH_COS)
    if not _disk_in_slit(orbit.slit, cx, cy, cz, ce):
        return False
    # The Sun's angle psi from the zenith against the visible cap's radius lam (cos lam =
    # sin a_e): all of it sunlit where psi + lam < 90 deg, all dark where psi - lam > 90 deg.
    cpsi = -(nadir[0] * sun_i[0] + nadir[1] * sun_i[1] + nadir[2] * sun_i[2])
    spsi = np.sqrt(max(1.0 - cpsi * cpsi, 0.0))
    sa = np.sqrt(max(1.0 - ce * ce, 0.0))
    if cpsi * sa - spsi * ce > 0.0:
        return True
    if cpsi * sa + spsi * ce < 0.0:
        return False
    return _brightest_at(orbit.slit, r0, r1, r2, cx, cy, cz, ce, sun_i, 0.0) > 0.0


@njit
def _brightest_at(sl, r0, r1, r2, cx, cy, cz, ce, sun_i, enough):
    ux = r0[0] * sun_i[0] + r0[1] * sun_i[1] + r0[2] * sun_i[2]
    uy = r1[0] * sun_i[0] + r1[1] * sun_i[1] + r1[2] * sun_i[2]
    uz = r2[0] * sun_i[0] + r2[1] * sun_i[1] + r2[2] * sun_i[2]
    return brightest_in_slit(sl, cx, cy, cz, ce, ux, uy, uz, enough)


@njit_stage
def glare_cos(orbit, k, w, q, sun_i):
    """:func:`brightest_in_slit` of the frame.

    ``orbit``, ``k``, ``w``, ``q`` and ``sun_i`` as :func:`earth_glare` takes them.
    """
    nadir = orbit.work[0]
    r0, r1, r2 = _body_rows(q)
    cx = r0[0] * nadir[0] + r0[1] * nadir[1] + r0[2] * nadir[2]
    cy = r1[0] * nadir[0] + r1[1] * nadir[1] + r1[2] * nadir[2]
    cz = r2[0] * nadir[0] + r2[1] * nadir[1] + r2[2] * nadir[2]
    return _brightest_at(orbit.slit, r0, r1, r2, cx, cy, cz,
                         _lerp(orbit.scalars, k, w, EARTH_COS), sun_i, FULL_SEARCH)


def surface_brightness(cos_incidence) -> float:
    """[mag/arcsec^2] the sunlit Earth's surface at incidence cosine ``cos_incidence``.

    A Lambertian surface of albedo :data:`EARTH_ALBEDO`: its radiance is
    ``albedo cos i / pi`` of the Sun's irradiance per steradian; +inf in the dark.
    """
    c = float(cos_incidence)
    if c <= 0.0:
        return math.inf
    arcsec2_sr = (math.pi / 648000.0) ** 2
    return SUN_MAGNITUDE - 2.5 * xmath.log10(EARTH_ALBEDO * c / math.pi * arcsec2_sr)


@njit_stage
def dim_sun(f, fine):
    """Sun sensor 104's outputs ``fine`` at the visible fraction ``f`` of the Sun.

    Its signal scales with the light: the pitch and yaw outputs by ``f``;
    in the umbra (``f`` = 0) it sees no Sun.
    """
    if f <= 0.0:
        fine[0] = 0.0
        fine[1] = 0.0
        fine[2] = 0.0
    elif f < 1.0:
        fine[0] *= f
        fine[1] *= f


@njit_stage
def _cross_add(r, f, out, scale):
    """``out += scale * (r x f)``; returns the magnitude of ``r x f`` times ``scale``."""
    tx = r[1] * f[2] - r[2] * f[1]
    ty = r[2] * f[0] - r[0] * f[2]
    tz = r[0] * f[1] - r[1] * f[0]
    out[0] += scale * tx
    out[1] += scale * ty
    out[2] += scale * tz
    return abs(scale) * np.sqrt(tx * tx + ty * ty + tz * tz)


@njit_stage
def gravity_gradient(gg, inertia, n_b, out):
    """Add ``gg * n x (J n)`` [N m] to ``out``; returns its magnitude.

    ``gg`` [1/s^2] is ``3 mu / r^3``, ``inertia`` the (3, 3) tensor [kg m^2],
    ``n_b`` the unit vector to the Earth's centre, body axes.
    """
    jn0 = inertia[0, 0] * n_b[0] + inertia[0, 1] * n_b[1] + inertia[0, 2] * n_b[2]
    jn1 = inertia[1, 0] * n_b[0] + inertia[1, 1] * n_b[1] + inertia[1, 2] * n_b[2]
    jn2 = inertia[2, 0] * n_b[0] + inertia[2, 1] * n_b[1] + inertia[2, 2] * n_b[2]
    tx = n_b[1] * jn2 - n_b[2] * jn1
    ty = n_b[2] * jn0 - n_b[0] * jn2
    tz = n_b[0] * jn1 - n_b[1] * jn0
    out[0] += gg * tx
    out[1] += gg * ty
    out[2] += gg * tz
    return abs(gg) * np.sqrt(tx * tx + ty * ty + tz * tz)


@njit_stage
def env_torque(orbit, k, w, dt_s, q, inertia, sun_b, torque):
    """Add the environment's torques at ``frame`` to ``torque`` [N m] (body axes).

    ``orbit`` holds the samples, ``dt_s`` [s] is the frame, ``inertia`` the
    (3, 3) tensor [kg m^2], ``q`` the attitude quaternion (inertial to body), ``sun_b`` the unit
    vector to the Sun in body axes; ``k``, ``w`` place the frame between
    samples (:func:`place`). Call :func:`occult_stars` first in the frame (it
    leaves the frame's nadir and visible fraction). The torques' magnitudes
    go to ``orbit.env``, their peaks and impulses to ``orbit.peak``.
    """
    sc = orbit.scalars
    nb = orbit.work[1]
    w_b = orbit.work[2]
    wind = orbit.work[3]
    w0, x, y, z = q[0], q[1], q[2], q[3]
    # The body-from-inertial matrix (quaternion.dcm_body_from_inertial), once
    m00, m01, m02 = w0 * w0 + x * x - y * y - z * z, 2.0 * (x * y + w0 * z), \
        2.0 * (x * z - w0 * y)
    m10, m11, m12 = 2.0 * (x * y - w0 * z), w0 * w0 - x * x + y * y - z * z, \
        2.0 * (y * z + w0 * x)
    m20, m21, m22 = 2.0 * (x * z + w0 * y), 2.0 * (y * z - w0 * x), \
        w0 * w0 - x * x - y * y + z * z
    t_gg = 0.0
    if orbit.gravity_gradient:
        v = orbit.work[0]  # the nadir occult_stars left
        nb[0] = m00 * v[0] + m01 * v[1] + m02 * v[2]
        nb[1] = m10 * v[0] + m11 * v[1] + m12 * v[2]
        nb[2] = m20 * v[0] + m21 * v[1] + m22 * v[2]
        t_gg = gravity_gradient(_lerp(sc, k, w, GG), inertia, nb, torque)
    drag = _lerp(sc, k, w, DRAG)
    t_aero = 0.0
    if drag > 0.0:
        for i in range(3):
            wind[i] = orbit.wind_i[k, i] + w * (orbit.wind_i[k + 1, i] - orbit.wind_i[k, i])
        w_b[0] = m00 * wind[0] + m01 * wind[1] + m02 * wind[2]
        w_b[1] = m10 * wind[0] + m11 * wind[1] + m12 * wind[2]
        w_b[2] = m20 * wind[0] + m21 * wind[1] + m22 * wind[2]
        speed = np.sqrt(w_b[0] * w_b[0] + w_b[1] * w_b[1] + w_b[2] * w_b[2])
        t_aero = _cross_add(orbit.pressure_offset_m, w_b, torque, -drag * speed)
    srp = _lerp(sc, k, w, SRP) * orbit.env[E_SUNLIT]
    t_srp = 0.0
    if srp > 0.0:
        t_srp = _cross_add(orbit.srp_offset_m, sun_b, torque, -srp)
    orbit.env[E_GG] = t_gg
    orbit.env[E_AERO] = t_aero
    orbit.env[E_SRP] = t_srp
    pk = orbit.peak
    pk[PEAK, 0] = max(pk[PEAK, 0], t_gg)
    pk[PEAK, 1] = max(pk[PEAK, 1], t_aero)
    pk[PEAK, 2] = max(pk[PEAK, 2], t_srp)
    pk[IMPULSE, 0] += t_gg * dt_s
    pk[IMPULSE, 1] += t_aero * dt_s
    pk[IMPULSE, 2] += t_srp * dt_s


def sun_seen(orbit, frame) -> np.ndarray:
    """Unit vector, vehicle to Sun, at ``frame`` of ``orbit``, as the loop has it."""
    out = np.empty(3)
    _sun_at_frame(orbit, int(frame), out)
    return out


@njit
def _sun_at_frame(orbit, frame, out):
    k, w = place(orbit, frame)
    _lerp_unit(orbit.sun_i, k, w, out)


# The scans over frames below do their work in kernels compiled without numba's runtime
# (allsky.jit.njit): with it on, every array of the orbit's tuple is reference-counted each
# time the tuple is handed to a helper, which made the journal's scans between legs take 36
# times as long. Their njit_alloc wrappers only allocate what the kernels fill.
@njit_alloc
def sunlit_series(orbit, first, last):
    """The Sun's visible fraction at frames ``first`` to ``last`` - 1 of ``orbit``.

    Each frame's value is :func:`sunlit_at`'s; an interval between samples
    that is sunlit at both ends and between (``WHOLE``) is filled with 1.0 at
    once, one in the umbra (``UMBRA``) with 0.0, as :func:`sunlit_at` gives
    them frame by frame.
    """
    out = np.empty(max(last - first, 0))
    _fill_sunlit(orbit, first, last, out)
    return out


@njit
def _fill_sunlit(orbit, first, last, out):
    """:func:`sunlit_series` into ``out``."""
    step = orbit.step_frames
    f = first
    while f < last:
        k = f // step
        if k < orbit.n - 1 and _one_fraction(orbit.scalars, k):
            end = min(last, (k + 1) * step)
            out[f - first:end - first] = _sun_fraction(orbit.scalars, k, 0.0)
            f = end
        else:
            out[f - first] = sunlit_at(orbit, f)
            f += 1


@njit_stage
def _one_fraction(sc, k):
    """Whether interval ``k`` of the samples ``sc`` has one visible fraction: 1 or 0 throughout."""
    return sc[k, WHOLE] != 0.0 or sc[k, UMBRA] != 0.0


@njit_alloc
def eclipse_steps(orbit, first, last, phase):
    """Where the shadow's phase changes, frames ``first`` to ``last`` - 1 of ``orbit``.

    The phase is 0 sunlit (the whole Sun), 1 penumbra, 2 umbra, of each
    frame's :func:`sunlit_series` value; ``phase`` is the phase before
    ``first``. Returns ``(frames, phases, fractions)`` of the frames whose
    phase differs from the frame's before (frame - ``first``, its phase, its
    visible fraction), and the phase at ``last`` - 1. Intervals sunlit at
    both ends and between (``WHOLE``), or in the umbra (``UMBRA``), are
    passed at once.
    """
    steps = np.empty((8, 2), dtype=np.int64)  # frame - first, phase
    fractions = np.empty(8)
    n, end_phase = _eclipse_scan(orbit, first, last, phase, steps, fractions)
    if n > steps.shape[0]:  # more than the buffer holds: scanned again into one that fits
        steps = np.empty((n, 2), dtype=np.int64)
        fractions = np.empty(n)
        _eclipse_scan(orbit, first, last, phase, steps, fractions)
    return steps[:n, 0].copy(), steps[:n, 1].copy(), fractions[:n].copy(), end_phase


@njit
def _eclipse_scan(orbit, first, last, phase, steps, fractions):
    """:func:`eclipse_steps` into ``steps`` and ``fractions``, as many as they hold.

    Returns ``(n, phase)``: the number of changes found (all counted, even
    those beyond the buffers) and the phase at ``last`` - 1.
    """
    n = 0
    step = orbit.step_frames
    f = first
    while f < last:
        k = f // step
        one = k < orbit.n - 1 and _one_fraction(orbit.scalars, k)
        x = sunlit_at(orbit, f)  # at once where it is one fraction
        now = 0 if x >= 1.0 else (2 if x <= 0.0 else 1)
        if now != phase:
            if n < steps.shape[0]:
                steps[n, 0] = f - first
                steps[n, 1] = now
                fractions[n] = x
            n += 1
            phase = now
        f = min(last, (k + 1) * step) if one else f + 1
    return n, phase


@njit
def first_dark(orbit, first, last):
    """The first frame of ``first`` to ``last`` - 1 whose Sun is not whole (-1: none).

    ``orbit`` holds the samples; the frames' fractions are :func:`sunlit_at`'s,
    as in :func:`sunlit_series`.
    """
    step = orbit.step_frames
    f = first
    while f < last:
        k = f // step
        if k < orbit.n - 1 and orbit.scalars[k, WHOLE] != 0.0:
            f = min(last, (k + 1) * step)
        elif sunlit_at(orbit, f) < 1.0:
            return f
        else:
            f += 1
    return -1


@njit_alloc
def occulted_series(orbit, directions, first, last):
    """Each of ``directions`` (m, 3) behind the Earth's disk, (frames, m) bool.

    At frames ``first`` to ``last`` - 1 of ``orbit``.
    """
    return _occulted(orbit, directions.reshape(1, directions.shape[0], 3), False, first, last)


@njit_alloc
def occulted_bodies_series(orbit, first, last):
    """Each moving body behind the Earth's disk, (frames, b) bool.

    At frames ``first`` to ``last`` - 1 of ``orbit``. A body's direction is
    its row of ``orbit.bodies_i`` for the frame's sample interval, as the
    frame loop holds it (:func:`occult_stars`).
    """
    return _occulted(orbit, orbit.bodies_i, True, first, last)


@njit_alloc
def _occulted(orbit, table, by_interval, first, last):
    """Rows of ``table`` (n, m, 3) behind the Earth's disk, (frames, m) bool.

    Row ``k`` of ``table`` for the frame's sample interval ``k`` with
    ``by_interval``, else its only row.
    """
    out = np.zeros((max(last - first, 0), table.shape[1]), dtype=np.bool_)
    _fill_occulted(orbit, table, by_interval, first, last, np.empty(3), out)
    return out


@njit
def _fill_occulted(orbit, table, by_interval, first, last, nadir, out):
    """:func:`_occulted` into ``out``; ``nadir`` (3,) is work space."""
    for f in range(first, last):
        k, w = place(orbit, f)
        _lerp_unit(orbit.nadir_i, k, w, nadir)
        cos_e = _lerp(orbit.scalars, k, w, EARTH_COS)
        r = k if by_interval else 0
        for j in range(table.shape[1]):
            d = table[r, j, 0] * nadir[0] + table[r, j, 1] * nadir[1] + table[r, j, 2] * nadir[2]
            out[f - first, j] = d > cos_e


#: [rad] what a bound of :func:`occultation_steps` allows for rounding: far above the ulps
#: of a unit vector's dot product, far below a frame's motion of the nadir (5e-5 rad at 300 km)
ROUNDING_RAD = 1e-9


@njit_stage
def _row_cos(orbit, fixed, moving, k, j, v):
    """Row ``j`` of :func:`occultation_steps` dotted with the unit vector ``v``.

    The fixed rows first, then the bodies' of interval ``k``; summed in the
    order of :func:`_occulted`, for the same bits.
    """
    if j < fixed.shape[0]:
        return fixed[j, 0] * v[0] + fixed[j, 1] * v[1] + fixed[j, 2] * v[2]
    col = moving[j - fixed.shape[0]]
    t = orbit.bodies_i
    return t[k, col, 0] * v[0] + t[k, col, 1] * v[1] + t[k, col, 2] * v[2]


@njit_alloc
def occultation_steps(orbit, fixed, moving, first, last, seen):
    """The frames where rows pass behind the Earth's disk, or out from behind it.

    Frames ``first`` to ``last`` - 1 of ``orbit``'s samples
    (:class:`OrbitParams`). The rows are ``fixed`` (m, 3), then the columns ``moving`` of
    ``orbit.bodies_i`` (each body's row for the frame's sample interval); a
    row is hidden at a frame exactly where :func:`occulted_series` (or
    :func:`occulted_bodies_series`) says so, and ``seen`` (rows,) bool is
    what each showed before ``first``. Returns ``(steps, hidden)``: the steps
    as (n, 3) int64 rows (frame - ``first``, row, 1 hidden / 0 shown), by frame
    then row, and each row's state at ``last`` - 1.

    An interval's frames are not evaluated one by one where a row cannot
    cross the limb in it: the interpolated nadir stays within the angle
    ``theta`` of the interval's first sample (the chord between the samples
    times pi/2, which bounds the arc, and :data:`ROUNDING_RAD`), and a cosine
    moves no more than its angle, so a row whose cosine from that sample
    clears both ends' ``EARTH_COS`` by ``theta`` keeps its side throughout.
    """
    rows = fixed.shape[0] + moving.shape[0]
    steps = np.empty((16, 3), dtype=np.int64)
    state = seen.copy()
    side = np.zeros(rows, dtype=np.int64)
    nadir = np.empty(3)
    n = _occultation_scan(orbit, fixed, moving, first, last, state, side, nadir, steps)
    if n > steps.shape[0]:  # more than the buffer holds: scanned again into one that fits
        steps = np.empty((n, 3), dtype=np.int64)
        state = seen.copy()
        _occultation_scan(orbit, fixed, moving, first, last, state, side, nadir, steps)
    return steps[:n].copy(), state


@njit
def _occultation_scan(orbit, fixed, moving, first, last, state, side, nadir, steps):
    """:func:`occultation_steps` into ``steps``, as many as it holds; ``state`` moves on.

    ``state`` (rows,) bool starts as what each row showed before ``first``
    and ends as its state at ``last`` - 1; ``side`` (rows,) int64 and
    ``nadir`` (3,) are work space. Returns the number of steps found (all
    counted, even those beyond the buffer).
    """
    rows = fixed.shape[0] + moving.shape[0]
    n_steps = 0
    sc = orbit.scalars
    step = orbit.step_frames
    f = first
    while f < last:
        k, w = place(orbit, f)
        end = last if k == orbit.n - 2 and w == 1.0 else min(last, (k + 1) * step)
        n0 = orbit.nadir_i[k]
        n1 = orbit.nadir_i[k + 1]
        chord = math.sqrt((n1[0] - n0[0]) ** 2 + (n1[1] - n0[1]) ** 2 + (n1[2] - n0[2]) ** 2)
        theta = 0.5 * math.pi * chord + ROUNDING_RAD
        c_lo = min(sc[k, EARTH_COS], sc[k + 1, EARTH_COS]) - ROUNDING_RAD
        c_hi = max(sc[k, EARTH_COS], sc[k + 1, EARTH_COS]) + ROUNDING_RAD
        mixed = False  # this interval's side of each row: 1 hidden, -1 shown, 0 frame by frame
        for j in range(rows):
            d0 = _row_cos(orbit, fixed, moving, k, j, n0)
            if d0 - theta > c_hi:
                side[j] = 1
            elif d0 + theta < c_lo:
                side[j] = -1
            else:
                side[j] = 0
                mixed = True
        for g in range(f, end if mixed else f + 1):
            if mixed:
                kg, wg = place(orbit, g)
                _lerp_unit(orbit.nadir_i, kg, wg, nadir)
                cos_e = _lerp(sc, kg, wg, EARTH_COS)
            for j in range(rows):
                if side[j] != 0:
                    h = side[j] > 0
                else:
                    h = _row_cos(orbit, fixed, moving, k, j, nadir) > cos_e
                if h != state[j]:
                    if n_steps < steps.shape[0]:
                        steps[n_steps, 0] = g - first
                        steps[n_steps, 1] = j
                        steps[n_steps, 2] = 1 if h else 0
                    n_steps += 1
                    state[j] = h
        f = end
    return n_steps


#: The columns of :func:`orbit_telemetry`, with their units.
ORBIT_COLUMNS = (("time", "s"), ("sunlit_fraction", "-"), ("eclipse", "-"),
                 ("earth_angle_x", "deg"), ("earth_angle_boresight", "deg"),
                 ("earth_glare", "-"))


@njit_alloc
def _orbit_rows(orbit, frames, q, times):
    out = np.empty((frames.shape[0], 5))
    _fill_orbit_rows(orbit, frames, q, times, np.empty(3), out)
    return out


@njit
def _fill_orbit_rows(orbit, frames, q, times, nadir, out):
    """:func:`orbit_telemetry`'s first five columns into ``out``; ``nadir`` (3,) is work space."""
    for i in range(frames.shape[0]):
        f = frames[i]
        k, w = place(orbit, f)
        _lerp_unit(orbit.nadir_i, k, w, nadir)
        w0, x, y, z = q[i, 0], q[i, 1], q[i, 2], q[i, 3]
        a, b, c = nadir[0], nadir[1], nadir[2]
        nx = (w0 * w0 + x * x - y * y - z * z) * a + 2.0 * (x * y + w0 * z) * b \
            + 2.0 * (x * z - w0 * y) * c
        ny = 2.0 * (x * y - w0 * z) * a + (w0 * w0 - x * x + y * y - z * z) * b \
            + 2.0 * (y * z + w0 * x) * c
        nz = 2.0 * (x * z + w0 * y) * a + 2.0 * (y * z - w0 * x) * b \
            + (w0 * w0 - x * x - y * y + z * z) * c
        s = sunlit_at(orbit, f)
        out[i, 0] = times[i]
        out[i, 1] = s
        out[i, 2] = 1.0 if s < 1.0 else 0.0
        out[i, 3] = xmath.atan2(np.sqrt(ny * ny + nz * nz), nx) * (180.0 / math.pi)
        out[i, 4] = xmath.atan2(np.sqrt(nx * nx + ny * ny), nz) * (180.0 / math.pi)


def orbit_telemetry(orbit, ck, table, glare=()) -> np.ndarray:
    """The orbit's columns (:data:`ORBIT_COLUMNS`) beside a telemetry ``table``.

    For each row (its ``time`` and attitude quaternion, the first six
    columns of :data:`allsky.sim.recorder.COLUMNS`): the visible fraction of
    the Sun, the eclipse flag (1 while any of it is hidden), and the angle
    [deg] of the Earth's centre from body +x (the sun sensor's axis) and from
    +z (star tracker 105's boresight), and the glare flag (1 while the
    sunlit Earth in the slit blinds the tracker, from ``glare``: the
    journal's ``earth_glare`` entries as ``(frame, active)`` in time order).
    ``orbit`` holds the samples, ``ck`` is the mission's clock.
    """
    from allsky import clock

    t = np.ascontiguousarray(table[:, 0], dtype=float)
    frames = np.array([clock.frame_at(ck, float(x)) for x in t], dtype=np.int64)
    q = np.ascontiguousarray(table[:, 2:6], dtype=float)
    rows = _orbit_rows(orbit, frames, q, t)
    flag = np.zeros(frames.shape[0])
    for frame, active in glare:  # each entry holds from its frame on
        flag[frames >= frame] = 1.0 if active else 0.0
    return np.column_stack([rows, flag])
