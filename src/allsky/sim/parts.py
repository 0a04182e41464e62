"""The frame loop's optional parts: faults, reaction wheels, an orbit.

Each part is handed to :func:`allsky.sim.frame_loop._run_frames` as its
parameters or as None (the patent's vehicle, without faults, far from any
body). Every stage here is the part's step at one place in the frame, paired
with doing nothing: its body is one test of ``is None`` (or ``is not None``)
on the part, which numba decides when the loop compiles, before typing
(:func:`allsky.sim.frame_loop.leg_entry` chooses the loop once a leg). The
loop without a part therefore compiles, and runs, as if the part did not
exist; the loop with it pays only the part's own work.

A test of ``is None`` that numba can decide stands alone in its ``if``:
``if faults is not None and x:`` would be typed whole, and fail to compile
without faults.
"""

from allsky.hardware import star_tracker as trk
from allsky.hardware.jets import thrust_fraction
from allsky.jit import njit_stage
from allsky.sim.faults import (
    ONSET,
    fault_actuate,
    fault_release,
    fault_sense,
    fault_tracker,
    fault_upset,
)
from allsky.sim.journal import note_clip, note_faults, note_glare, note_wheels
from allsky.vehicle.environment import (
    dim_sun,
    earth_glare,
    env_torque,
    glare_cos,
    held,
    next_place,
    occult_stars,
    start_place,
    sun_at,
)
from allsky.vehicle.wheels import body_vector


# -- the orbit (allsky.vehicle.environment) ---------------------------------------------------
@njit_stage
def orbit_start(orbit, frame, sun_i):
    """The leg's first frame between the orbit's samples; its Sun into ``sun_i``.

    Returns ``(k, j, w)`` (:func:`allsky.vehicle.environment.start_place`, ``w``
    the fraction of the interval); ``(0, 0, 0.0)`` without an orbit, whose
    Sun the loop computes itself.

    ``orbit`` is the orbit's samples (:class:`allsky.vehicle.environment.OrbitParams`) or
    None. The other arguments (``frame``) are those of
    :func:`allsky.vehicle.environment.start_place`.
    """
    k, j, w = 0, 0, 0.0
    if orbit is not None:
        k, j = start_place(orbit, frame)
        w = j / orbit.step_frames
        kh, wh = held(orbit, k, w)
        sun_at(orbit, kh, wh, sun_i)
    return k, j, w


@njit_stage
def orbit_sky(orbit, k, w, first, tracker_p):
    """The frame's sky: the stars behind the Earth hidden, the Sun's fraction.

    Returns ``(tracker, kh, wh, sunlit)``: the tracker whose stars the Earth
    has not hidden, the frame's place held at the last interval, and the
    visible fraction of the Sun (:func:`allsky.vehicle.environment.occult_stars`);
    without an orbit ``tracker_p`` as it is, the place ``(0, 0.0)`` and 1.0.
    ``first`` is True in the leg's first frame.

    ``orbit`` is the orbit's samples (:class:`allsky.vehicle.environment.OrbitParams`) or
    None. The other arguments (``k``, ``w``) are those of
    :func:`allsky.vehicle.environment.occult_stars`.
    """
    kh, wh, sunlit = 0, 0.0, 1.0
    if orbit is not None:
        kh, wh = held(orbit, k, w)
        sunlit = occult_stars(orbit, kh, wh, first)
        return orbit.tracker, kh, wh, sunlit
    return tracker_p, kh, wh, sunlit


@njit_stage
def orbit_glare(orbit, kh, wh, x, sun_i, tracker_p, lock, journal, journal_n, frame,
                star_in_use):
    """Star tracker 105 this frame: blind while sunlit Earth is in its slit.

    Returns ``tracker_p``, or while the sunlit Earth is in the slit
    (:func:`allsky.vehicle.environment.earth_glare`) the tracker that sees no
    star (``orbit.blind``). Its onset and end are journal entries (the
    target held as it was blinded, the slit's most directly lit point), and
    ``lock[GLARE]`` remembers it. ``kh``, ``wh`` place the frame between the
    orbit's samples (:func:`orbit_sky` returns them); ``x`` is the state (its attitude first),
    ``sun_i`` the Sun's direction, inertial; ``star_in_use``: S12 or S13 closed.

    ``orbit`` is the orbit's samples (:class:`allsky.vehicle.environment.OrbitParams`) or
    None. The other arguments (``lock``, ``journal``, ``journal_n``, ``frame``) are those
    of :func:`allsky.sim.journal.note_glare`.
    """
    if orbit is not None:
        lit = earth_glare(orbit, kh, wh, x, sun_i)
        if lit != (lock[trk.GLARE] != 0.0):
            note_glare(journal, journal_n, frame, lit, lock[trk.HELD],
                       glare_cos(orbit, kh, wh, x, sun_i) if lit else 0.0, star_in_use)
            lock[trk.GLARE] = 1.0 if lit else 0.0
        if lit:
            return orbit.blind
    return tracker_p


@njit_stage
def orbit_blind(orbit, lock, star, trk_out):
    """After the faults: a blinded tracker holds nothing, a glint's outputs included.

    Returns the target held (-1 while blinded, else ``star``); ``trk_out`` are
    star tracker 105's outputs, cleared while blinded; ``lock`` its memory.

    ``orbit`` is the orbit's samples (:class:`allsky.vehicle.environment.OrbitParams`) or
    None.
    """
    if orbit is not None:  # noqa: SIM102 - numba decides this test alone (module docstring)
        if lock[trk.GLARE] != 0.0:
            trk_out[0] = 0.0
            trk_out[1] = 0.0
            trk_out[2] = 0.0
            lock[trk.HELD] = trk.NONE
            return -1
    return star


@njit_stage
def orbit_shadow(orbit, sunlit, fine):
    """Sun sensor 104's outputs ``fine`` in the Earth's shadow (``sunlit`` of the Sun).

    ``orbit`` is the orbit's samples (:class:`allsky.vehicle.environment.OrbitParams`) or
    None.
    """
    if orbit is not None:
        dim_sun(sunlit, fine)


@njit_stage
def orbit_torque(orbit, kh, wh, dt_s, x, inertia, sun_b, torque):
    """Gravity gradient, drag and solar pressure added to ``torque`` [N m] (body axes).

    ``orbit`` is the orbit's samples (:class:`allsky.vehicle.environment.OrbitParams`) or
    None. The other arguments (``kh``, ``wh``, ``dt_s``, ``x``, ``inertia``, ``sun_b``) are
    those of :func:`allsky.vehicle.environment.env_torque`.
    """
    if orbit is not None:
        env_torque(orbit, kh, wh, dt_s, x, inertia, sun_b, torque)


@njit_stage
def orbit_next(orbit, k, j, w, sun_i):
    """The next frame's place ``(k, j, w)`` between samples; its Sun into ``sun_i``.

    ``orbit`` is the orbit's samples (:class:`allsky.vehicle.environment.OrbitParams`) or
    None. The other arguments (``k``, ``j``, ``w``) are those of
    :func:`allsky.vehicle.environment.next_place`.
    """
    if orbit is not None:
        k, j, w = next_place(orbit, k, j)
        kh, wh = held(orbit, k, w)
        sun_at(orbit, kh, wh, sun_i)
    return k, j, w


# -- the faults (allsky.sim.faults) -----------------------------------------------------------
@njit_stage
def faults_tracker(faults, fault_state, frame, tracker_p, lock):
    """Star tracker 105 this frame: the wrong stars while such a fault acts.

    A glint no longer acting is forgotten (``lock``).

    ``tracker_p`` is the tracker without a fault (the orbit's, its hidden
    stars included); returned as it is without faults.

    ``faults`` is the scenario's faults (:class:`allsky.sim.faults.FaultParams`) or None.
    The other arguments (``fault_state``, ``frame``) are those of
    :func:`allsky.sim.faults.fault_tracker`.
    """
    if faults is not None:
        tracker_p = fault_tracker(faults, tracker_p, fault_state, frame)
        fault_release(faults, fault_state, frame, lock)
    return tracker_p


@njit_stage
def faults_sense(faults, tracker_p, fault_state, frame, dt_s, dtheta_rad, fine, trk, gyro, lock,
                 star, cone_armed):
    """The sensor faults on the sensors' outputs; the star held after them.

    ``faults`` is the scenario's faults (:class:`allsky.sim.faults.FaultParams`) or None.
    The other arguments (``tracker_p``, ``fault_state``, ``frame``, ``dt_s``,
    ``dtheta_rad``, ``fine``, ``trk``, ``gyro``, ``lock``, ``star``, ``cone_armed``) are
    those of :func:`allsky.sim.faults.fault_sense`.
    """
    if faults is not None:
        return fault_sense(faults, tracker_p, fault_state, frame, dt_s, dtheta_rad, fine, trk,
                           gyro, lock, star, cone_armed)
    return star


@njit_stage
def faults_upset(faults, fault_state, frame, drift_counters, counters, registers, journal,
                 journal_n, seen, drift_gate, dac_hi, dac_lo):
    """Counter and register upsets; a drift DAC clip they change, journalled.

    ``faults`` is the scenario's faults (:class:`allsky.sim.faults.FaultParams`) or None.
    The other arguments (``fault_state``, ``frame``, ``drift_counters``, ``counters``,
    ``registers``, ``journal``, ``journal_n``, ``seen``, ``drift_gate``, ``dac_hi``,
    ``dac_lo``) are those of :func:`allsky.sim.faults.fault_upset`.
    """
    if faults is not None:  # noqa: SIM102 - alone, so numba decides it before typing
        if fault_upset(faults, fault_state, frame, drift_counters, counters, registers):
            note_clip(journal, journal_n, seen, frame, drift_counters, drift_gate, dac_hi,
                      dac_lo)


@njit_stage
def faults_feed(faults, jets_p, propellant_kg):
    """The jets' thrust over its full-pressure value (a blow-down feed).

    1.0 without faults (the feed is modelled with the faults that starve it).

    ``faults`` is the scenario's faults (:class:`allsky.sim.faults.FaultParams`) or None.
    The other arguments (``jets_p``, ``propellant_kg``) are those of
    :func:`allsky.hardware.jets.thrust_fraction`.
    """
    if faults is not None:
        return thrust_fraction(jets_p, propellant_kg[0])
    return 1.0


@njit_stage
def faults_actuate(faults, fault_state, frame, jets_p, dt_s, valve, propellant_kg, torque,
                   tank_ok, feed):
    """The jet faults on the torque and the tank; whether the tank still feeds.

    ``faults`` is the scenario's faults (:class:`allsky.sim.faults.FaultParams`) or None.
    The other arguments (``fault_state``, ``frame``, ``jets_p``, ``dt_s``, ``valve``,
    ``propellant_kg``, ``torque``, ``tank_ok``, ``feed``) are those of
    :func:`allsky.sim.faults.fault_actuate`.
    """
    if faults is not None:
        return fault_actuate(faults, fault_state, frame, jets_p, dt_s, valve, propellant_kg,
                             torque, tank_ok, feed)
    return tank_ok


@njit_stage
def faults_note(faults, journal, journal_n, seen, first, frame, fault_state):
    """A fault's onset or end, told to the journal.

    ``faults`` is the scenario's faults (:class:`allsky.sim.faults.FaultParams`) or None.
    The other arguments (``journal``, ``journal_n``, ``seen``, ``first``, ``frame``,
    ``fault_state``) are those of :func:`allsky.sim.journal.note_faults`.
    """
    if faults is not None:
        note_faults(journal, journal_n, seen, first, frame, faults.n, fault_state, ONSET,
                    faults.duration_frames)


# -- the reaction wheels (allsky.vehicle.wheels) ---------------------------------------------
@njit_stage
def wheels_row(wheels_p, every_frames, frame, wheel_h, wheel_hb):
    """The wheels' momentum in body axes into ``wheel_hb`` at a telemetry row.

    A row is written every ``every_frames`` frames (0: none), at the frame
    ``frame`` the clock shows after the plant's step.

    ``wheels_p`` is the wheel array (:class:`allsky.vehicle.wheels.WheelParams`) or None.
    The other arguments (``wheel_h``) are those of
    :func:`allsky.vehicle.wheels.body_vector`.
    """
    if wheels_p is not None:  # noqa: SIM102 - alone, so numba decides it before typing
        if every_frames > 0 and frame % every_frames == 0:
            body_vector(wheels_p.axes, wheel_h, wheel_hb)


@njit_stage
def wheels_last_row(wheels_p, every_frames, wheel_h, wheel_hb):
    """The wheels' momentum in body axes into ``wheel_hb`` for the row a leg ends on.

    ``wheels_p`` is the wheel array (:class:`allsky.vehicle.wheels.WheelParams`) or None.
    The other arguments (``every_frames``, ``wheel_h``) are those of
    :func:`allsky.vehicle.wheels.body_vector`.
    """
    if wheels_p is not None:  # noqa: SIM102 - alone, so numba decides it before typing
        if every_frames > 0:
            body_vector(wheels_p.axes, wheel_h, wheel_hb)


@njit_stage
def wheels_note(wheels_p, journal, journal_n, seen, frame, unloading, wheel_h):
    """The unloader starting or stopping, a wheel reaching or leaving its limit.

    ``wheels_p`` is the wheel array (:class:`allsky.vehicle.wheels.WheelParams`) or None.
    The other arguments (``journal``, ``journal_n``, ``seen``, ``frame``, ``unloading``,
    ``wheel_h``) are those of :func:`allsky.sim.journal.note_wheels`.
    """
    if wheels_p is not None:
        note_wheels(journal, journal_n, seen, frame, unloading, wheel_h,
                    wheels_p.max_momentum_n_m_s)
