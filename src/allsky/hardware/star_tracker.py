"""Star tracker 105 on +z (yaw): a slit tracker that holds the star it locked.

The tracker reports, in arcsec, the rotations that would bring its boresight
(+z) onto the tracked star ``s`` (unit vector, body axes)::

    yaw output   = atan2(-s_y, s_z)   (rotation about +x: what a roll moves)
    pitch output = atan2( s_x, s_z)   (rotation about +y)

Its field of view is a slit: long (``fov_long_half``) in the pitch direction,
since the Sun-Canopus angle varies by about +-14 deg over a year, narrow
(``fov_narrow_half``) across. The pitch output is the star's *cone angle*,
its place along the slit: with the roll axis on the Sun it is 90 deg less
the star's angle from the Sun, whatever the roll (Canopus -9.95 deg on the
default date).

Only stars inside the magnitude window reach the kernel (the window is
applied once, before flight, by :func:`allsky.sim.mission.build_params`
from the catalog). The tracker has a memory, ``lock`` (:func:`new_lock`):

* **Lock and hold.** With nothing held, it searches: it locks the first
  window star found in the slit (of several found in the same frame, the
  one nearest the boresight) and then tracks that star, and no other,
  until the star leaves the field or the tracker loses it (a dropout, a
  glint, the bright gate: :mod:`allsky.sim.faults`); only then does it
  search again. A second window star entering the slit does not take the
  lock.
* **Cone-angle check** (``cone_check_rad`` > 0; beyond the patent, off by
  default). A star found in the search whose cone angle differs from the
  planned reference star's (``reference_cone_rad``) by more than the check
  is refused: the tracker does not lock it, remembers it (up to
  :data:`N_REFUSED` at once) and ignores it until it leaves the field, and
  the search goes on. Mariner 4's operators told Canopus from other objects
  by brightness and cone angle in the same way. The check is armed only
  while the roll axis is held on the Sun (``cone_armed``), where the pitch
  output is the cone angle. A star locked while the check was not armed (a
  star Mode 1 meets on its way to the Sun, carried into Mode 2) is judged
  the first frame the check is armed with the Sun on the roll axis (the sun
  sensor's pitch error under a tenth of the check, ``sun_pitch_arcsec``):
  before the loop uses it. Refused, it is dropped and remembered as any
  refusal, and the search goes on.

"Star present" flags a lock, and the tracker tells which star it holds
(its index in ``stars_inertial``): the programmed angles assume a planned
star, and a window that passes two stars can lock the other one.
"""

import math
from typing import NamedTuple

import numpy as np

from allsky import xmath
from allsky.gauss import standard_normal
from allsky.jit import njit, njit_stage
from allsky.units import RAD2ARCSEC
from allsky.vehicle.sky import check_to_pass_deg, cone_angle_deg, edge_pitch_deg  # noqa: F401

#: What the tracker holds when it holds no star of the catalog but a false target (a glint
#: of stray light): its index is neither a star's nor -1 (nothing in the slit).
FALSE_TARGET = -2
#: No target (nothing held, nothing refused, no event in ``lock``).
NONE = -1
#: Stars the cone-angle check remembers as refused at once (a slit +-16 x +-8 deg rarely
#: holds more than two window stars; a fifth refusal replaces the first).
N_REFUSED = 4
#: A lock carried into an armed check is judged once the sun sensor's pitch error is under
#: this fraction of the check: the roll axis on the Sun, where the pitch output is the cone
#: angle to within a tenth of the check.
SETTLED_FRACTION = 0.1
# Entries of the tracker's memory ``lock`` (State.tracker_lock), all float64.
HELD = 0  #: the target held: a star's index, NONE, or FALSE_TARGET (a glint)
REFUSED = 1  #: N_REFUSED slots: stars refused by the cone-angle check, still in the field
NEW_REFUSAL = REFUSED + N_REFUSED  #: the target refused in this frame (NONE: none)
REFUSED_CONE_ARCSEC = NEW_REFUSAL + 1  #: [arcsec] its cone angle (pitch output)
GATE = REFUSED_CONE_ARCSEC + 1  #: 1.0 while the light in the slit exceeds the bright gate
DROPPED = GATE + 1  #: the target the bright gate last took the lock from
NEW_DROP = DROPPED + 1  #: the target the bright gate took the lock from in this frame (NONE)
SEEN_MAG = NEW_DROP + 1  #: [mag] the light in the slit when the gate took the lock
#: 1.0 once the target held has been judged by an armed cone-angle check (0.0: locked while
#: the check was not armed, or no check); a lock not yet judged is judged when next armed
CHECKED = SEEN_MAG + 1
#: [-] the light of the catalog's stars in the slit this frame, in magnitude-0 stars (the
#: bright gate's; 0.0 without a gate)
SLIT_FLUX = CHECKED + 1
#: 1.0 while sunlit Earth in the slit blinds the tracker (in orbit:
#: :func:`allsky.vehicle.environment.earth_glare`), 0.0 otherwise
GLARE = SLIT_FLUX + 1
N_LOCK = GLARE + 1


class StarTrackerParams(NamedTuple):
    """Canopus tracker."""

    fov_long_half_rad: float  #: [rad] half field along the tracker pitch direction
    fov_narrow_half_rad: float  #: [rad] half field across (tracker yaw direction)
    noise_arcsec: float  #: [arcsec] 1-sigma white noise per output per frame
    stars_inertial: np.ndarray  #: [-] (n, 3) unit vectors of the stars inside the magnitude window
    magnitudes: np.ndarray  #: [mag] (n,) visual magnitude of each of those stars
    window_bright_mag: float  #: [mag] the magnitude window's bright end
    window_faint_mag: float  #: [mag] its faint end
    reference_cone_rad: float  #: [rad] cone angle of the planned reference star
    cone_check_rad: float  #: [rad] refuse a lock this far from it; 0 = no check
    #: [mag] the lock is dropped while the slit is brighter than this; -inf = no gate
    bright_gate_mag: float
    #: [-] (m, 3) unit vectors of every catalog star, one per star, whose light the gate
    #: counts in the slit ((0, 3) without a gate)
    gate_stars_inertial: np.ndarray
    gate_magnitudes: np.ndarray  #: [mag] (m,) their visual magnitudes


def make_params(fov_long_half_rad, fov_narrow_half_rad, noise_arcsec, stars_inertial,
                magnitudes=None, window_mag=(-math.inf, math.inf), reference_cone_rad=0.0,
                cone_check_rad=0.0, bright_gate=False, gate_stars_inertial=None,
                gate_magnitudes=None) -> StarTrackerParams:
    """:class:`StarTrackerParams` from the field, the noise and the stars.

    Parameters
    ----------
    fov_long_half_rad, fov_narrow_half_rad : float
        [rad] half fields along and across the slit.
    noise_arcsec : float
        [arcsec] white noise per output per frame (1 sigma).
    stars_inertial : array_like
        (n, 3) unit vectors of the stars the window passes.
    magnitudes : array_like, optional
        [mag] their visual magnitudes (default: all at the window's faint end, or 0).
    window_mag : tuple of float
        [mag] the magnitude window, (bright end, faint end).
    reference_cone_rad : float
        [rad] cone angle of the planned reference star (90 deg less its angle from the Sun).
    cone_check_rad : float
        [rad] refuse a lock whose cone angle is further than this from it; 0 = no check.
    bright_gate : bool
        Drop the lock while the light in the slit is brighter than the window's bright end.
    gate_stars_inertial, gate_magnitudes : array_like, optional
        (m, 3) unit vectors and (m,) [mag] magnitudes of every star whose light
        the gate counts in the slit, inside the window or not (default: the
        window's stars). Kept only with ``bright_gate``.
    """
    stars = np.ascontiguousarray(np.asarray(stars_inertial, dtype=float).reshape(-1, 3))
    bright, faint = float(window_mag[0]), float(window_mag[1])
    if magnitudes is None:
        magnitudes = np.full(stars.shape[0], faint if math.isfinite(faint) else 0.0)
    mags = np.ascontiguousarray(np.asarray(magnitudes, dtype=float).reshape(-1))
    if mags.shape[0] != stars.shape[0]:
        raise ValueError(f"{stars.shape[0]} stars but {mags.shape[0]} magnitudes")
    if gate_stars_inertial is None:
        gate_stars_inertial, gate_magnitudes = stars, mags
    gate_stars = np.ascontiguousarray(np.asarray(gate_stars_inertial, dtype=float).reshape(-1, 3))
    gate_mags = np.ascontiguousarray(np.asarray(gate_magnitudes, dtype=float).reshape(-1))
    if gate_mags.shape[0] != gate_stars.shape[0]:
        raise ValueError(f"{gate_stars.shape[0]} gate stars but {gate_mags.shape[0]} magnitudes")
    if not bright_gate:
        gate_stars, gate_mags = np.zeros((0, 3)), np.zeros(0)
    return StarTrackerParams(float(fov_long_half_rad), float(fov_narrow_half_rad),
                             float(noise_arcsec), stars, mags, bright, faint,
                             float(reference_cone_rad), float(cone_check_rad),
                             bright if bright_gate else -math.inf, gate_stars, gate_mags)


def new_lock() -> np.ndarray:
    """The tracker's memory before its first frame: nothing held, refused or seen."""
    lock = np.full(N_LOCK, float(NONE))
    lock[GATE] = 0.0
    lock[REFUSED_CONE_ARCSEC] = 0.0
    lock[SEEN_MAG] = 0.0
    lock[CHECKED] = 0.0
    lock[SLIT_FLUX] = 0.0
    lock[GLARE] = 0.0
    return lock


def seen_magnitude(magnitudes) -> float:
    """The magnitude of the light of several sources together (fluxes add).

    ``magnitudes`` are their visual magnitudes; with none the slit is dark
    (+inf).
    """
    flux = math.fsum(xmath.exp10(-0.4 * m) for m in magnitudes)
    return -2.5 * xmath.log10(flux) if flux > 0 else math.inf


@njit
def _sight(p, r0, r1, r2, k):
    """``(in_field, yaw, pitch)`` [rad] of star ``k`` for the body rows ``r0, r1, r2``."""
    a, b, c = p.stars_inertial[k, 0], p.stars_inertial[k, 1], p.stars_inertial[k, 2]
    sz = r2[0] * a + r2[1] * b + r2[2] * c
    if sz <= 0.0:
        return False, 0.0, 0.0
    sx = r0[0] * a + r0[1] * b + r0[2] * c
    sy = r1[0] * a + r1[1] * b + r1[2] * c
    yaw = xmath.atan2(-sy, sz)
    pitch = xmath.atan2(sx, sz)
    inside = abs(yaw) <= p.fov_narrow_half_rad and abs(pitch) <= p.fov_long_half_rad
    return inside, yaw, pitch


@njit_stage
def star_tracker(p, q, lock, out, rng, cone_armed=True, sun_pitch_arcsec=0.0):
    """Outputs of star tracker 105 for attitude ``q``, written into ``out``.

    The lock and its outputs as :func:`search_and_hold` makes them; with a
    bright gate (``p.bright_gate_mag`` finite) the light of every catalog
    star in the slit (``p.gate_stars_inertial``: the held star, the others,
    inside the window or not) is kept in ``lock[SLIT_FLUX]``, to which a
    fault's glints add theirs (:func:`allsky.sim.faults.fault_sense`) before
    the gate judges it (:func:`bright_gate`, after the faults). Returns the
    target held, as :func:`search_and_hold`. ``p`` is the tracker
    (:class:`StarTrackerParams`), ``lock`` its memory, ``rng`` the noise
    state; ``cone_armed`` and ``sun_pitch_arcsec`` [arcsec] say whether the
    cone-angle check is armed and how far the Sun is off the roll axis (a
    carried lock is judged once the Sun is on it).
    """
    star = search_and_hold(p, q, lock, out, rng, cone_armed, sun_pitch_arcsec)
    if p.bright_gate_mag > -np.inf:
        lock[SLIT_FLUX] = slit_flux(p, q)
    return star


@njit
def slit_flux(p, q) -> float:
    """The light [magnitude-0 stars] of the gate stars in the slit at attitude ``q``.

    ``p`` is the tracker (:class:`StarTrackerParams`); fluxes add (Pogson),
    a star of magnitude m giving ``10**(-0.4 m)``.
    """
    w, x, y, z = q[0], q[1], q[2], q[3]
    r0 = (w * w + x * x - y * y - z * z, 2.0 * (x * y + w * z), 2.0 * (x * z - w * y))
    r1 = (2.0 * (x * y - w * z), w * w - x * x + y * y - z * z, 2.0 * (y * z + w * x))
    r2 = (2.0 * (x * z + w * y), 2.0 * (y * z - w * x), w * w - x * x - y * y + z * z)
    flux = 0.0
    for k in range(p.gate_stars_inertial.shape[0]):
        a, b, c = (p.gate_stars_inertial[k, 0], p.gate_stars_inertial[k, 1],
                   p.gate_stars_inertial[k, 2])
        sz = r2[0] * a + r2[1] * b + r2[2] * c
        if sz <= 0.0:
            continue
        sx = r0[0] * a + r0[1] * b + r0[2] * c
        sy = r1[0] * a + r1[1] * b + r1[2] * c
        if abs(xmath.atan2(-sy, sz)) <= p.fov_narrow_half_rad \
                and abs(xmath.atan2(sx, sz)) <= p.fov_long_half_rad:
            flux += xmath.exp10(-0.4 * p.gate_magnitudes[k])
    return flux


@njit_stage
def bright_gate(p, lock, star, out):
    """Star tracker 105's bright gate: the lock is lost while the slit is too bright.

    The light is all the light in the slit, ``lock[SLIT_FLUX]``
    [magnitude-0 stars]: the stars' and the glints'. A lock the gate takes is flagged
    once in ``lock`` (for the journal), with the light seen; ``out`` (the
    outputs) is cleared. Returns the target held after the gate (-1 when it
    took it). ``p`` is the tracker (:class:`StarTrackerParams`), ``star``
    the target held before the gate.
    """
    flux = lock[SLIT_FLUX]
    over = flux > 0.0 and -2.5 * xmath.log10(flux) < p.bright_gate_mag
    if over:
        if star != -1 and (lock[GATE] == 0.0 or lock[DROPPED] != star):
            lock[NEW_DROP] = star
            lock[DROPPED] = star
            lock[SEEN_MAG] = -2.5 * xmath.log10(flux)
        out[0] = 0.0
        out[1] = 0.0
        out[2] = 0.0
        star = -1
        lock[HELD] = NONE
    lock[GATE] = 1.0 if over else 0.0
    return star


@njit_stage
def search_and_hold(p, q, lock, out, rng, cone_armed, sun_pitch_arcsec):
    """The lock of star tracker 105 for attitude ``q`` and its outputs, into ``out``.

    ``out = [yaw_arcsec, pitch_arcsec, present]``; ``lock`` is the tracker's
    memory (:func:`new_lock`), updated: the star it holds, the stars the
    cone-angle check refused, the refusal of this frame. The check acts only
    while ``cone_armed``: the pitch output is the cone angle only with the
    roll axis on the Sun (the frame loop arms it while S14 feeds the sun
    sensor's pitch to control amplifier 32). Returns the index of the
    tracked star in ``p.stars_inertial``, -1 when it holds none, and
    :data:`FALSE_TARGET` while it holds a glint (whose outputs the fault
    that makes it writes, :func:`allsky.sim.faults.fault_sense`). A held
    star the armed check has not judged (``lock[CHECKED]``) is judged once
    the sun sensor's pitch error ``sun_pitch_arcsec`` [arcsec] is under a
    tenth of the check (:data:`SETTLED_FRACTION`).

    ``p`` is the tracker (:class:`StarTrackerParams`: slit, noise, the window's
    stars); ``rng`` the (1,) uint64 noise generator state (``allsky.gauss``),
    advanced by the output noise draws.
    """
    check_rad = p.cone_check_rad if cone_armed else 0.0
    lock[NEW_REFUSAL] = NONE
    lock[NEW_DROP] = NONE
    n = p.stars_inertial.shape[0]
    w, x, y, z = q[0], q[1], q[2], q[3]
    # Rows of the body-from-inertial matrix (see quaternion.dcm_body_from_inertial).
    r0 = (w * w + x * x - y * y - z * z, 2.0 * (x * y + w * z), 2.0 * (x * z - w * y))
    r1 = (2.0 * (x * y - w * z), w * w - x * x + y * y - z * z, 2.0 * (y * z + w * x))
    r2 = (2.0 * (x * z + w * y), 2.0 * (y * z - w * x), w * w - x * x - y * y + z * z)
    # Refused stars are forgotten once they have left the field (a glint's, by its fault);
    # the cone-angle check refuses them, and the ground's step-on.
    for j in range(N_REFUSED):
        k = int(lock[REFUSED + j])
        if k >= 0 and (k >= n or not _sight(p, r0, r1, r2, k)[0]):
            lock[REFUSED + j] = NONE
    held = int(lock[HELD])
    if held == FALSE_TARGET:
        out[0] = 0.0
        out[1] = 0.0
        out[2] = 0.0
        return FALSE_TARGET
    if 0 <= held < n:
        inside, yaw, pitch = _sight(p, r0, r1, r2, held)
        if inside and check_rad > 0.0 and lock[CHECKED] == 0.0 \
                and abs(sun_pitch_arcsec) < SETTLED_FRACTION * check_rad * RAD2ARCSEC:
            # A lock made while the check was not armed, judged before the loop uses it.
            if abs(pitch - p.reference_cone_rad) > check_rad:
                refuse_now(lock, held, pitch * RAD2ARCSEC)
                inside = False
            else:
                lock[CHECKED] = 1.0
        if inside:  # held: no other star is looked at (the same noise as a star found)
            out[0] = yaw * RAD2ARCSEC + p.noise_arcsec * standard_normal(rng)
            out[1] = pitch * RAD2ARCSEC + p.noise_arcsec * standard_normal(rng)
            out[2] = 1.0
            return held
    # The search: the window star in the slit nearest the boresight that the check passes.
    k_best = -1
    yaw_best = 0.0
    pitch_best = 0.0
    best = 1e9
    refuse = -1
    refuse_d = 1e9
    refuse_pitch = 0.0
    for k in range(n):
        inside, yaw, pitch = _sight(p, r0, r1, r2, k)
        if not inside or refused(lock, k):
            continue
        d = yaw * yaw + pitch * pitch
        if check_rad > 0.0 and abs(pitch - p.reference_cone_rad) > check_rad:
            if d < refuse_d:
                refuse_d = d
                refuse = k
                refuse_pitch = pitch
            continue
        if d < best:
            best = d
            yaw_best = yaw
            pitch_best = pitch
            k_best = k
    if refuse >= 0 and lock[NEW_REFUSAL] == NONE:  # one refusal a frame, remembered, told
        refuse_now(lock, refuse, refuse_pitch * RAD2ARCSEC)
    lock[HELD] = k_best
    lock[CHECKED] = 1.0 if check_rad > 0.0 else 0.0
    if k_best < 0:
        out[0] = 0.0
        out[1] = 0.0
        out[2] = 0.0
        return -1
    out[0] = yaw_best * RAD2ARCSEC + p.noise_arcsec * standard_normal(rng)
    out[1] = pitch_best * RAD2ARCSEC + p.noise_arcsec * standard_normal(rng)
    out[2] = 1.0
    return k_best


@njit
def refuse_now(lock, target, cone_arcsec):
    """Remember ``target`` as refused by the cone-angle check; flag the refusal.

    ``lock`` is the tracker's memory (:func:`new_lock`), updated;
    ``cone_arcsec`` is its cone angle [arcsec]. A free slot of the memory
    takes it; with none free, the first slot.
    """
    slot = 0
    for j in range(N_REFUSED):
        if lock[REFUSED + j] == NONE:
            slot = j
            break
    lock[REFUSED + slot] = target
    lock[NEW_REFUSAL] = target
    lock[REFUSED_CONE_ARCSEC] = cone_arcsec


@njit
def refused(lock, target) -> bool:
    """Whether ``target`` is among the targets the cone-angle check refused.

    ``lock`` is the tracker's memory (:func:`new_lock`).
    """
    for j in range(N_REFUSED):
        if lock[REFUSED + j] == target:
            return True
    return False
