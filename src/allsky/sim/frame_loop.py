"""The per-frame loop: compiled stages that run the vehicle frame by frame.

:func:`_run_frames` calls one stage after another, in the order the signal
flows through the patent's block diagram::

    sense          sun sensor 104, star tracker 105, gyros 1-3
    sum_and_count  summing amplifiers 4-6 (drift DACs 7/9/11 via S1-S3, rate
                   commands 120/128 via S16/S17) -> converters 8/10/12 ->
                   counters 14/16/18 (and drift counters 13/15/17 via S4-S6)
    compute        computer 111: sequencer 21 steps S7/S8, CPU 22 -> registers 25-27
    route          DACs 28-30 and optical outputs through S9-S15 -> position
                   inputs of control amplifiers 31-33; lines 130/131 -> rate inputs
    acquire_sun    (instead of route, when the leg runs Mode 1's controller)
    control        control amplifiers 31-33 (and the dither command with its feed-forward)
    actuate_vehicle  PWPF modulators 34-36 -> jets 39-41 (or the reaction wheels,
                   with the jets unloading them: allsky.vehicle.wheels)
    advance_vehicle  rigid-body plant (the gyrostat on the wheel vehicle), mission clock
    record         telemetry row and dither record (allsky.sim.recorder)
    watch          master sequencer 20's watch (allsky.sequencer.watch)

The faults, the reaction wheels and the orbit add their stages among these
(:mod:`allsky.sim.parts`), each compiled only for a mission that has them.

The on/off switches are read through the wiring table's index arrays
(:data:`allsky.hardware.wiring.ROUTING`, carried in ``Params.routing``), once
a leg (:func:`wire_leg`): the master sequencer operates them between legs.
Each stage is compiled by :func:`allsky.jit.njit_stage`, which has numba
inline it into the loop: a frame makes no calls to the stages themselves.

The master sequencer itself (switch actions, mode rules) is Python
(:mod:`allsky.sequencer.master_sequencer`): it sets the switches, then calls
:func:`run_leg` with a *leg* (:mod:`allsky.sequencer.legs`), the condition
that ends the current step of a mode. The loop returns when that condition
is met, at the leg's timeout, or on an abort (propellant gone, Sun or star
lost). All state lives in the arrays of :class:`allsky.sim.state.State`, so a
mission can be saved and resumed between legs.
"""

from typing import NamedTuple

import numpy as np

from allsky import xmath
from allsky.clock import frame_time
from allsky.compiles import compiling, needs_compiling
from allsky.computer.computer_sequencer import sequencer_step
from allsky.computer.cpu import target_step
from allsky.gauss import seed as gauss_seed
from allsky.hardware.control_amp import control_amp
from allsky.hardware.dac import dac
from allsky.hardware.gyro import RRW_STEP_S, gyro_output
from allsky.hardware.jets import jets
from allsky.hardware.pwpf import pwpf_step
from allsky.hardware.rate_command import rate_command
from allsky.hardware.star_tracker import bright_gate, star_tracker
from allsky.hardware.storage_register import store
from allsky.hardware.summing_amp import summing_amp
from allsky.hardware.sun_acquisition import sun_acquisition
from allsky.hardware.sun_sensor import coarse_sun, sun_sensor
from allsky.hardware.updown_counter import count
from allsky.hardware.vfc import vfc
from allsky.hardware.wiring import (
    N_POSITION_SOURCES,
    NONE,
    SRC_DAC,
    SRC_SUN_PITCH,
    SRC_SUN_YAW,
    SRC_TRACKER_PITCH,
    SRC_TRACKER_YAW,
)
from allsky.jit import CompiledFunction, njit_alloc, njit_noalias, njit_stage
from allsky.sequencer.dither import dither_command
from allsky.sequencer.legs import (
    CLOCK_FRAMES,
    CLOCK_SETTLE,
    CLOCK_STAR_GONE,
    CLOCK_SUN_GONE,
    EXIT_PAUSE,
    EXIT_TIMEOUT,
    N_SIGNALS,
    PROGRAM_DITHER,
    PROGRAM_MODE1,
    PROGRAM_TARGET,
    PROGRAM_TARGET_DITHER,
    PROGRAM_TARGET_ROLL,
)
from allsky.sequencer.watch import EXIT_NONE, sensors_in_use, watch
from allsky.sim.journal import SEEN_WHEEL, note_clip, note_frame
from allsky.sim.parts import (
    faults_actuate,
    faults_feed,
    faults_note,
    faults_sense,
    faults_tracker,
    faults_upset,
    orbit_blind,
    orbit_glare,
    orbit_next,
    orbit_shadow,
    orbit_sky,
    orbit_start,
    orbit_torque,
    wheels_last_row,
    wheels_note,
    wheels_row,
)
from allsky.sim.recorder import N_REC, N_TLM, record_dither, record_last_row, record_telemetry  # noqa: F401
from allsky.vehicle.plant import rk4_step, rk4_step_gyrostat
from allsky.vehicle.quaternion import rotate_to_body
from allsky.vehicle.wheels import (
    ACTUATOR_JETS,
    ACTUATOR_WHEELS,
    ALLOCATION_DIRECT,
    advance_momentum,
    body_vector,
    distribute,
    distribute_direct,
    unload_valves,
)

# Rows of the per-leg ``gates`` (wire_leg), one column per axis.
GATE_DRIFT = 0  #: S1-S3: drift DAC 7/9/11 into summing amplifier 4/5/6
GATE_DRIFT_COUNT = 1  #: S4-S6: converter 8/10/12 into drift counter 13/15/17
GATE_COMMAND = 2  #: S16/S17: rate-command module 120/128 into summing amplifier 4/6
COMMAND_ARCSEC_S = 3  #: [arcsec/s] that module's command (0 on pitch, which has none)
GATE_RATE_MODE = 4  #: S18/S19: control amplifier 31/33 follows the rate command
N_GATES = 5


def run_leg(p, s, leg, tlm, tlm_rows, rec, rec_rows):
    """Run frames until the leg's condition, timeout or an abort.

    ``tlm`` is a preallocated (rows, N_TLM) telemetry buffer and
    ``tlm_rows`` (1,) its fill count. ``rec`` (rows, N_REC) receives the
    dither record of a PROGRAM_DITHER leg (:func:`allsky.sim.recorder.record_dither`):
    every ``dither_sample_frames`` frames, time, counters 14/16/18 [arcsec]
    and the attitude the optics see [arcsec] per axis.
    A leg may pause at the mission's frame ``leg.pause_at_frame``: the loop
    returns EXIT_PAUSE with its progress in ``s.leg_clock``, and the same leg
    run again with ``resume=1`` carries on as if it had never stopped (the
    noise generator is not reseeded). A leg ends with its settle count in
    ``s.leg_clock``, where a next leg with ``carry_settle=1`` starts from it.
    A leg whose loop must compile first (nothing in numba's cache) compiles
    under the machine's lock, said to :data:`allsky.compiles.ON_COMPILE`.
    Returns ``(exit_code, frames_flown_in_the_leg)``.

    Parameters
    ----------
    p : allsky.sim.state.Params
        The frame loop's parameters (:func:`allsky.sim.mission.build_params`).
    s : allsky.sim.state.State
        The mission state, advanced in place.
    leg : allsky.sequencer.legs.Leg
        What the computer runs, what ends the leg, its timeout [s].
    rec_rows : numpy.ndarray
        (1,) int64 fill count of ``rec``.
    """
    args = (p, s, leg, tlm, tlm_rows, rec, rec_rows)
    entry = leg_entry(p)
    if entry not in _LOADED:  # the first leg of this entry in this process
        if needs_compiling((entry,)):  # nothing in the cache: it compiles now
            with compiling(entry):
                out = entry(*args)
        else:
            out = entry(*args)
        _LOADED.add(entry)
        return out
    return _resolved(entry, args)(*args)


#: The entries this process has called (compiled, loaded from the cache or built ahead of
#: time): only the first call of each may compile.
_LOADED = set()


#: The compiled entries resolved for recent (entry, params, state): the call
#: :func:`_resolved` found for the small arguments' fingerprints, by fingerprint.
_RESOLVED = {}
#: The entries kept in :data:`_RESOLVED` (a Monte Carlo flies many missions in a process).
RESOLVED_KEPT = 8
#: numba's type of an argument, by its fingerprint (the Params of a scenario's shape).
_TYPES = {}
#: (entry, the compiled code) by the entry and its arguments' fingerprints
_CALLS = {}
#: The entries kept in :data:`_CALLS`.
CALLS_KEPT = 256


def _resolved(entry, args):
    """What to call ``entry`` (a compiled entry) with ``args`` through: its compiled code.

    numba's dispatcher types every argument at each call: for ``Params``, a
    tuple of about a hundred arrays, that is 13 us, and some 20 us a call in
    all. A mission flies its legs with the same ``Params`` and ``State``
    objects, whose fields' types cannot change (the tuples are immutable), so
    the compiled code is looked up once for them and called directly; the
    small arguments (the leg, the buffers) are told apart by their numba
    fingerprints. Anything not yet compiled, or not a numba dispatcher (the
    loop built ahead of time, :mod:`allsky.aot`), goes through ``entry``.
    """
    if isinstance(entry, CompiledFunction) or not hasattr(entry, "overloads"):
        return entry
    from numba._dispatcher import compute_fingerprint  # numba is loaded: entry is its own

    p, s = args[0], args[1]
    key = (id(entry), id(p), id(s))
    known = _RESOLVED.get(key)
    if known is None or known[0] is not entry or known[1] is not p or known[2] is not s:
        if len(_RESOLVED) >= RESOLVED_KEPT:
            _RESOLVED.clear()
        try:  # once for these objects: the shape of the scenario's Params and State
            shapes = (compute_fingerprint(p), compute_fingerprint(s))
        except (TypeError, ValueError):
            return entry
        known = (entry, p, s, shapes)
        _RESOLVED[key] = known
    try:
        small = compute_fingerprint(args[2:])
    except (TypeError, ValueError):  # numba could not fingerprint it: its dispatcher types it
        return entry
    # By fingerprints, so that the next mission of the same shape (a Monte Carlo's) finds
    # its code without hashing the Params' numba type again (a few hundred hashes)
    by_shape = (id(entry), known[3], small)
    found = _CALLS.get(by_shape)
    if found is not None and found[0] is entry:
        return found[1]
    try:
        sig = (_type_of(p), _type_of(s)) + tuple(_type_of(a) for a in args[2:])
    except (TypeError, ValueError):
        return entry
    cres = entry.overloads.get(sig)
    if cres is None:  # not compiled yet: the dispatcher compiles it; resolved next time
        return entry
    if len(_CALLS) >= CALLS_KEPT:
        _CALLS.clear()
    _CALLS[by_shape] = (entry, cres.entry_point)
    return cres.entry_point


def _type_of(value):
    """numba's type of the argument ``value``, looked up by its fingerprint."""
    from numba._dispatcher import compute_fingerprint
    from numba.core.typing.typeof import Purpose, typeof

    fp = compute_fingerprint(value)
    t = _TYPES.get(fp)
    if t is None:
        t = _TYPES[fp] = typeof(value, Purpose.argument)
    return t


def entries() -> dict:
    """The frame loop's compiled entries by name: "plain", "any" (:func:`leg_entry`)."""
    return {"plain": _run_leg_plain, "any": _run_leg_any, "orbit": _run_leg_orbit,
            "any_orbit": _run_leg_any_orbit}


def leg_entry(p):
    """The compiled entry :func:`run_leg` flies a mission of parameters ``p`` with.

    A mission in orbit (``p.orbit.n`` > 0) flies the entries that hand the
    loop the orbit, so that the loop without one compiles without its code.

    The patent's vehicle without faults hands the loop None for the wheels
    and the faults: numba drops the branches that test them before typing
    them, so that loop compiles and runs as if neither existed (the general
    loop's per-frame tests cost it a fifth of its time, and typing their
    code lengthens the first compile). Each entry compiles on first use.
    """
    if p.actuator == ACTUATOR_JETS and p.faults.n == 0:
        return _run_leg_orbit if p.orbit.n > 0 else _run_leg_plain
    return _run_leg_any_orbit if p.orbit.n > 0 else _run_leg_any


class Work(NamedTuple):
    """The loop's work arrays, allocated once a leg (:func:`new_work`), each apart.

    The frame's signals as they pass from block to block, and what
    :func:`wire_leg` reads of the switches. Each is its own array, so that
    the compiler knows that writing one changes no other
    (:func:`allsky.jit.njit_noalias`).
    """

    sun_i: np.ndarray  #: (3,) [-] unit vector to the Sun, inertial axes
    sun_b: np.ndarray  #: (3,) [-] the same in body axes
    coarse: np.ndarray  #: (3,) the coarse sun eyes (Mode 1)
    fine: np.ndarray  #: (3,) sun sensor 104: pitch, yaw [arcsec], present
    trk: np.ndarray  #: (3,) star tracker 105: yaw, pitch [arcsec], present
    gyro: np.ndarray  #: (3,) [arcsec/s] gyros 1-3
    comp: np.ndarray  #: (3,) [arcsec/s] summing amplifiers 4-6, drift-compensated
    line: np.ndarray  #: (3,) [arcsec/s] the loop rates of lines 130/131
    pos: np.ndarray  #: (3,) [arcsec] control amplifiers 31-33's position inputs
    rate: np.ndarray  #: (3,) [arcsec/s] their rate inputs
    volts: np.ndarray  #: (3,) [V] their outputs
    torque: np.ndarray  #: (3,) [N m] on the body, body axes
    dith: np.ndarray  #: (3,) [arcsec] the dither command
    ff: np.ndarray  #: (3,) [V] its feed-forward
    wheel_hb: np.ndarray  #: (3,) [N m s] the wheels' momentum, body axes
    wheel_hdot: np.ndarray  #: (3,) [N m] its rate over the frame, body axes
    wheel_u: np.ndarray  #: (wheels,) [N m] the wheels' motor torques
    gates: np.ndarray  #: (N_GATES, 3) the on/off switches by GATE_* row (wire_leg)
    position_gain: np.ndarray  #: (position routes,) 1.0 where a route's switch is closed
    sources: np.ndarray  #: (N_POSITION_SOURCES,) [arcsec] the positions S9-S15 switch
    sig: np.ndarray  #: (N_SIGNALS,) the signals the watch reads (allsky.sequencer.watch)


# The work arrays are allocated in the entries (with numba's runtime), once per leg; the
# frames run in _run_frames, compiled without it (allsky.jit), which cannot allocate.
@njit_alloc
def new_work(p, n_wheels):
    """:class:`Work` for the loop of parameters ``p``, with ``n_wheels`` wheels."""
    return Work(np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3),
                np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3),
                np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(n_wheels),
                np.zeros((N_GATES, 3)), np.zeros(p.routing.position_routes.shape[0]),
                np.zeros(N_POSITION_SOURCES), np.zeros(N_SIGNALS))


@njit_alloc
def _run_leg_plain(p, s, leg, tlm, tlm_rows, rec, rec_rows):
    """:func:`run_leg` on the jets, without faults."""
    return _run_frames(p, s, leg, tlm, tlm_rows, rec, rec_rows, new_work(p, 0), None, None, None)


@njit_alloc
def _run_leg_orbit(p, s, leg, tlm, tlm_rows, rec, rec_rows):
    """:func:`run_leg` on the jets, without faults, in orbit."""
    return _run_frames(p, s, leg, tlm, tlm_rows, rec, rec_rows, new_work(p, 0), None, None,
                       p.orbit)


@njit_alloc
def _run_leg_any(p, s, leg, tlm, tlm_rows, rec, rec_rows):
    """:func:`run_leg` on either actuator, with the scenario's faults."""
    return _run_frames(p, s, leg, tlm, tlm_rows, rec, rec_rows,
                       new_work(p, p.wheels.axes.shape[0]), p.wheels, p.faults, None)


@njit_alloc
def _run_leg_any_orbit(p, s, leg, tlm, tlm_rows, rec, rec_rows):
    """:func:`run_leg` on either actuator, with the scenario's faults, in orbit."""
    return _run_frames(p, s, leg, tlm, tlm_rows, rec, rec_rows,
                       new_work(p, p.wheels.axes.shape[0]), p.wheels, p.faults, p.orbit)


@njit_noalias
def _run_frames(p, s, leg, tlm, tlm_rows, rec, rec_rows, w, wheels_p, faults, orbit):
    """The frames of :func:`run_leg`.

    ``w`` holds the leg's work arrays (:class:`Work`). ``wheels_p``,
    ``faults`` and ``orbit`` are the loop's optional parts
    (:mod:`allsky.sim.parts`): the reaction wheels
    (:class:`allsky.vehicle.wheels.WheelParams`), the scenario's faults and the
    orbit's samples (:class:`allsky.vehicle.environment.OrbitParams`), each
    None where the mission has none; the stages of a part absent compile to
    nothing. Each stage is handed only the parameters and state arrays of its
    own blocks. No array written here may overlap another argument's
    (:func:`allsky.jit.njit_noalias`): the state's arrays, the buffers and the
    work arrays are each allocated apart.
    """
    if not leg.resume:
        gauss_seed(s.rng, leg.seed)
        carried = s.leg_clock[CLOCK_SETTLE] if leg.carry_settle else 0
        s.leg_clock[:] = 0
        s.leg_clock[CLOCK_SETTLE] = carried
    dt = p.frame_s
    ck = p.clock
    fine, trk, gyro, volts, torque = w.fine, w.trk, w.gyro, w.volts, w.torque
    gates = w.gates
    el = p.electronics
    sw = s.switches
    program = leg.program
    dithering = program == PROGRAM_DITHER or program == PROGRAM_TARGET_DITHER
    rrw_every = max(1, round(RRW_STEP_S / dt))
    wire_leg(p.routing, el, sw, s.rate_sign, gates, w.position_gain)
    sun_in_use, star_in_use = sensors_in_use(sw, p.routing)
    cone_armed = sun_holds_pitch(p.routing.position_routes, w.position_gain)
    tracking = excursion_tracked(s.excursion_ref_q)
    settled = s.leg_clock[CLOCK_SETTLE]
    sun_gone = s.leg_clock[CLOCK_SUN_GONE]
    star_gone = s.leg_clock[CLOCK_STAR_GONE]
    done = s.leg_clock[CLOCK_FRAMES]
    n_max = leg.timeout_frames
    fault_state = s.fault_state
    dac_hi = (1 << (el.drift_dac_bits - 1)) - 1
    dac_lo = -(1 << (el.drift_dac_bits - 1))
    fault_seen = SEEN_WHEEL + s.wheel_h.shape[0]  # the journal's first fault slot
    # A drift DAC's clip can change within a leg only while it is fed and counted at once.
    clip_every_frame = False
    for a in range(3):
        if gates[GATE_DRIFT, a] != 0.0 and gates[GATE_DRIFT_COUNT, a] != 0.0:
            clip_every_frame = True
    # The Sun's direction of a frame is computed a frame ahead, beside the plant's step (which
    # takes longest and does not depend on it), where it costs no latency of its own.
    k_orbit, j_orbit, w_orbit = orbit_start(orbit, s.frame[0], w.sun_i)
    if orbit is None:
        sun_inertial(p.sun0_inertial, p.sun_rate_inertial, frame_time(ck, s.frame[0]), w.sun_i)
    for frame_in_leg in range(done, n_max):
        frame = s.frame[0]  # the mission's clock: the frame flown now
        tracker_p, kh, wh, sunlit = orbit_sky(orbit, k_orbit, w_orbit, frame_in_leg == done,
                                              p.tracker)
        tracker_p = faults_tracker(faults, fault_state, frame, tracker_p, s.tracker_lock)
        tracker_p = orbit_glare(orbit, kh, wh, s.x, w.sun_i, tracker_p, s.tracker_lock,
                                s.journal, s.journal_n, frame, star_in_use)
        star = sense(p.sun, tracker_p, p.gyro, dt, w.sun_i, s.x, s.dtheta_rad,
                     frame % rrw_every == 0, s.gyro_rw_arcsec_s, s.rng, s.tracker_lock,
                     cone_armed, w.sun_b, fine, trk, gyro)
        orbit_shadow(orbit, sunlit, fine)
        star = faults_sense(faults, tracker_p, fault_state, frame, dt, s.dtheta_rad, fine, trk,
                            gyro, s.tracker_lock, star, cone_armed)
        star = orbit_blind(orbit, s.tracker_lock, star, trk)
        if tracker_p.bright_gate_mag > -np.inf:  # every light in the slit, glints too
            star = bright_gate(tracker_p, s.tracker_lock, star, trk)
        if star_in_use and star >= 0:
            s.locked_star[0] = star  # the star the loop is closed on (S12/S13)
        sum_and_count(el, p.vfc, dt, gates, gyro, s.drift_counters, s.counters,
                      s.vfc_residue_pulses, s.overflow, w.comp, w.line)
        compute(el, p.vfc.pulse_weight_arcsec, program, frame, s.counters, s.word23, s.word24,
                sw, s.cpu, s.registers)
        faults_upset(faults, fault_state, frame, s.drift_counters, s.counters, s.registers,
                     s.journal, s.journal_n, s.journal_seen, gates[GATE_DRIFT], dac_hi, dac_lo)
        feed = faults_feed(faults, p.jets, s.propellant_kg)
        if program == PROGRAM_MODE1:
            acquire_sun(p.sun, p.mode1, w.sun_b, fine, w.comp, s.rng, w.coarse, w.pos, w.rate)
        else:
            route(el, p.routing.position_routes, w.position_gain, s.registers, fine, trk, w.line,
                  w.sources, w.pos, w.rate)
        control(p.control, p.dither, gates, program, dithering, frame_time(ck, frame_in_leg),
                dt, w.pos, w.rate, s.amp_integral_arcsec, w.dith, w.ff, volts)
        tank_ok = actuate_vehicle(p.pwpf, p.jets, wheels_p, p.actuator, dt, volts,
                                  s.pwpf_filter_v, s.pwpf_out, s.pwpf_on_frames, s.propellant_kg,
                                  s.wheel_h, s.wheel_unload, w.wheel_u, torque, w.wheel_hb,
                                  w.wheel_hdot)
        tank_ok = faults_actuate(faults, fault_state, frame, p.jets, dt, s.pwpf_out,
                                 s.propellant_kg, torque, tank_ok, feed)
        orbit_torque(orbit, kh, wh, dt, s.x, p.plant.inertia_kg_m2, w.sun_b, torque)
        count_jet_time(s.pwpf_out, dt, s.jet_on_s)
        # The next frame's Sun
        k_orbit, j_orbit, w_orbit = orbit_next(orbit, k_orbit, j_orbit, w_orbit, w.sun_i)
        if orbit is None:
            sun_inertial(p.sun0_inertial, p.sun_rate_inertial, frame_time(ck, frame + 1),
                         w.sun_i)
        advance_vehicle(p.plant, wheels_p, p.actuator, dt, torque, w.wheel_hb, w.wheel_hdot,
                        w.wheel_u, s.wheel_h, s.wheel_peak_fraction, s.x, s.dtheta_rad, s.frame)
        if tracking:
            track_excursion(s.excursion_ref_q, s.x, s.max_excursion_rad)
        n_leg = frame_in_leg + 1
        wheels_row(wheels_p, p.telemetry_every, s.frame[0], s.wheel_h, w.wheel_hb)
        record_telemetry(tlm, tlm_rows, p.telemetry_every, ck, s, leg.mode_code, fine, trk,
                         gyro, volts, w.wheel_hb, w.wheel_hdot, s.wheel_unload[0])
        note_frame(s.journal, s.journal_n, s.journal_seen, frame, star, star_in_use, trk[1],
                   s.overflow, s.tracker_lock)
        if clip_every_frame or frame_in_leg == done:
            note_clip(s.journal, s.journal_n, s.journal_seen, frame, s.drift_counters,
                      gates[GATE_DRIFT], dac_hi, dac_lo)
        wheels_note(wheels_p, s.journal, s.journal_n, s.journal_seen, frame, s.wheel_unload[0],
                    s.wheel_h)
        faults_note(faults, s.journal, s.journal_n, s.journal_seen, fault_seen, frame,
                    fault_state)
        if dithering:
            record_dither(rec, rec_rows, p.dither_sample_frames, frame_time(ck, n_leg),
                          s.frame[0], s.counters, p.vfc.pulse_weight_arcsec, fine, trk)
        code, settled, sun_gone, star_gone = watch(p.sequencer, leg, sun_in_use, star_in_use,
                                                   tank_ok, fine, trk, s.cpu, w.sig, n_leg,
                                                   settled, sun_gone, star_gone)
        if code != EXIT_NONE:
            s.leg_clock[CLOCK_SETTLE] = settled  # for a next leg that carries it on
            _last_row(p, wheels_p, tlm, ck, s, leg, w)
            return code, n_leg
        if s.frame[0] >= leg.pause_at_frame and n_leg < n_max:
            _last_row(p, wheels_p, tlm, ck, s, leg, w)
            s.leg_clock[CLOCK_SETTLE] = settled
            s.leg_clock[CLOCK_SUN_GONE] = sun_gone
            s.leg_clock[CLOCK_STAR_GONE] = star_gone
            s.leg_clock[CLOCK_FRAMES] = n_leg
            return EXIT_PAUSE, n_leg
    if n_max > done:  # the last frame flown ends the leg
        _last_row(p, wheels_p, tlm, ck, s, leg, w)
    return EXIT_TIMEOUT, max(n_max, done)


@njit_stage
def _last_row(p, wheels_p, tlm, ck, s, leg, w):
    """The row of the frame the loop returns on (:func:`allsky.sim.recorder.record_last_row`)."""
    wheels_last_row(wheels_p, p.telemetry_every, s.wheel_h, w.wheel_hb)  # at the row's time
    record_last_row(tlm, p.telemetry_every, ck, s, leg.mode_code, w.fine, w.trk, w.gyro,
                    w.volts, w.wheel_hb, w.wheel_hdot, s.wheel_unload[0])


@njit_stage
def sun_inertial(sun0_inertial, sun_rate_inertial, t_s, out):
    """Unit vector to the Sun at mission time ``t_s`` (linear in time, renormalised).

    ``sun0_inertial`` [-] is the Sun's direction at t = 0 and
    ``sun_rate_inertial`` [1/s] its time derivative, inertial axes; ``out``
    (3) receives the direction.
    """
    n = 0.0
    for i in range(3):
        out[i] = sun0_inertial[i] + sun_rate_inertial[i] * t_s
        n += out[i] * out[i]
    n = np.sqrt(n)
    for i in range(3):
        out[i] /= n


@njit_stage
def sun_holds_pitch(routes, position_gain):
    """Whether S14 switches in the sun sensor's pitch: the roll axis held on the Sun.

    Read once a leg from the wiring table's position routes and their gains
    (:func:`wire_leg`); star tracker 105's cone-angle check is armed then.
    ``routes`` holds the rows (switch, source index, axis) of
    ``Routing.position_routes``; ``position_gain`` 1.0 where a row's switch is
    closed, 0.0 where open.
    """
    for r in range(routes.shape[0]):
        if routes[r, 1] == SRC_SUN_PITCH and position_gain[r] != 0.0:
            return True
    return False


@njit_stage
def sense(sun_p, tracker_p, gyro_p, dt_s, sun_inertial, x, dtheta_rad, step_bias,
          bias_rw_arcsec_s, rng, tracker_lock, cone_armed, sun_b, fine, trk, gyro):
    """Sun sensor 104 -> ``fine``, star tracker 105 -> ``trk``, gyros 1-3 -> ``gyro``.

    ``fine`` is (pitch, yaw [arcsec], present), ``trk`` (yaw, pitch [arcsec],
    present), ``gyro`` the measured rates [arcsec/s] over the last frame's
    body-angle increment ``dtheta_rad``; ``sun_b`` keeps the Sun's body
    direction for the Mode 1 controller. ``step_bias`` steps the gyros' rate
    random walk ``bias_rw_arcsec_s``; ``tracker_lock`` is the tracker's
    memory (the star it holds), ``cone_armed`` arms its cone-angle check.
    Returns the index of the star the tracker holds in
    ``tracker_p.stars_inertial`` (-1: none).

    Parameters
    ----------
    sun_p : allsky.hardware.sun_sensor.SunSensorParams
        Sun sensor 104.
    tracker_p : allsky.hardware.star_tracker.StarTrackerParams
        Star tracker 105 (with a wrong star while such a fault acts).
    gyro_p : allsky.hardware.gyro.GyroParams
        Gyros 1-3.
    dt_s : float
        [s] frame length.
    sun_inertial : numpy.ndarray
        (3,) [-] unit vector to the Sun, inertial axes (:func:`sun_inertial`).
    x : numpy.ndarray
        (7,) plant state: quaternion inertial to body, body rate [rad/s].
    rng : numpy.ndarray
        (1,) uint64 noise generator state (``allsky.gauss``), advanced.
    """
    rotate_to_body(x, sun_inertial, sun_b)
    sun_sensor(sun_p, sun_b, fine, rng)
    star = star_tracker(tracker_p, x, tracker_lock, trk, rng, cone_armed,
                        fine[0] if fine[2] != 0.0 else 1e9)
    gyro_output(gyro_p, dtheta_rad, dt_s, bias_rw_arcsec_s, gyro, step_bias, rng)
    return star


@njit_stage
def wire_leg(routing, el, bank, rate_sign, gates, position_gain):
    """Read the on/off switches through the wiring table, once a leg.

    The master sequencer operates these switches between legs only (within a
    leg computer sequencer 21 moves just the selectors S7/S8), so the loop
    reads them once a leg. ``gates`` (N_GATES, 3) gets, per axis, 1.0 for a
    closed switch and 0.0 for an open one (GATE_* rows), and the rate command
    of the axis's module 120/128 in the direction ``rate_sign`` [arcsec/s]
    (COMMAND_ARCSEC_S, 0 where the axis has none); ``position_gain`` the same
    1.0/0.0 for each row of ``routing.position_routes``.

    Parameters
    ----------
    routing : allsky.hardware.wiring.Routing
        The wiring table as index arrays (``Params.routing``).
    el : allsky.sim.state.ElectronicsParams
        Its ``rate_command_arcsec_s`` [arcsec/s] is the modules' rate.
    bank : numpy.ndarray
        The switch bank S1-S19 (entry k for Sk, 1 = closed).
    """
    for a in range(3):
        gates[GATE_DRIFT, a] = bank[routing.drift_switch[a]]
        gates[GATE_DRIFT_COUNT, a] = bank[routing.drift_count_switch[a]]
        k = routing.rate_command_switch[a]
        gates[GATE_COMMAND, a] = bank[k] if k != NONE else 0.0
        gates[COMMAND_ARCSEC_S, a] = 0.0 if k == NONE else rate_command(
            el.rate_command_arcsec_s, rate_sign[routing.rate_command_module[a]])
        k = routing.rate_mode_switch[a]
        gates[GATE_RATE_MODE, a] = bank[k] if k != NONE else 0.0
    for r in range(routing.position_routes.shape[0]):
        position_gain[r] = bank[routing.position_routes[r, 0]]


@njit_stage
def sum_and_count(el, vfc_p, dt_s, gates, gyro, drift_counters, counters, vfc_residue_pulses,
                  overflow, comp, line):
    """Summing amplifiers 4-6, converters 8/10/12, counters 14/16/18 and 13/15/17.

    Each amplifier takes its gyro rate ``gyro`` [arcsec/s], less its drift
    DAC 7/9/11 (fed by ``drift_counters``) through S1-S3, and on roll and yaw
    the rate command of module 120/128 through S16/S17 (``gates`` of
    :func:`wire_leg`). Its drift-compensated output ``comp`` drives the
    converter, whose pulses up/down counters 14/16/18 count, and drift
    counters 13/15/17 through S4-S6; ``line`` is the loop rate of lines 130/131.

    Parameters
    ----------
    el : allsky.sim.state.ElectronicsParams
        Word lengths of the counters and drift DACs, the drift DACs' scaling.
    vfc_p : allsky.hardware.vfc.VfcParams
        Converters 8, 10, 12.
    dt_s : float
        [s] frame length.
    counters : numpy.ndarray
        (3,) int64 [pulses] up/down counters 14, 16, 18, counted into.
    vfc_residue_pulses : numpy.ndarray
        (3,) the fractions of a pulse the converters carry to the next frame.
    overflow : numpy.ndarray
        (6,) int64 overflow latches of counters 14, 16, 18, 13, 15, 17.
    """
    for a in range(3):
        drift = dac(drift_counters[a], el.drift_dac_bits, el.drift_lsb_arcsec_s)
        comp[a], line[a] = summing_amp(gyro[a], drift, gates[GATE_DRIFT, a],
                                       gates[COMMAND_ARCSEC_S, a], gates[GATE_COMMAND, a])
    for a in range(3):
        n = vfc(vfc_p, a, comp[a], dt_s, vfc_residue_pulses)
        count(counters, a, n, el.counter_bits, el.overflow_mode, overflow, a)
        if gates[GATE_DRIFT_COUNT, a]:
            count(drift_counters, a, n, el.drift_counter_bits, el.overflow_mode, overflow, 3 + a)


@njit_stage
def compute(el, pulse_weight_arcsec, program, frame, counters, word23, word24, bank, cpu,
            registers):
    """Computer 111: sequencer 21 steps S7/S8, CPU 22 writes registers 25-27.

    Mode 6-1 (PROGRAM_TARGET_ROLL) services the roll axis only; Mode 6-2
    (PROGRAM_TARGET, and the dither held on target) all three. Other programs
    leave the computer idle.

    Parameters
    ----------
    el : allsky.sim.state.ElectronicsParams
        Frames per S7/S8 step; the registers' word length and LSB [arcsec].
    pulse_weight_arcsec : float
        [arcsec/pulse] a counter pulse as an angle.
    program : int
        The leg's ``PROGRAM_*`` (:mod:`allsky.sequencer.legs`).
    frame : int
        The mission's frame counter (it times sequencer 21's steps).
    counters : numpy.ndarray
        (3,) int64 [pulses] up/down counters 14, 16, 18.
    word23, word24 : numpy.ndarray
        Computed word register 23 (calibration) and programmed word register
        24 (roll and yaw [arcsec]).
    bank : numpy.ndarray
        The switch bank; S7/S8 are stepped in it.
    cpu : numpy.ndarray
        CPU 22's working store, updated.
    registers : numpy.ndarray
        (3,) int64 [LSB] storage registers 25, 26, 27, written.
    """
    all_axes = program == PROGRAM_TARGET or program == PROGRAM_TARGET_DITHER
    if program == PROGRAM_TARGET_ROLL or all_axes:
        a = sequencer_step(bank, frame, el.computer_step_frames)
        if a == 0 or (a > 0 and all_axes):
            err = target_step(a, counters[a] * pulse_weight_arcsec, word23, word24, cpu)
            store(registers, a, err, el.register_bits, el.register_lsb_arcsec)


@njit_stage
def acquire_sun(sun_p, mode1_p, sun_b, fine, gyro_arcsec_s, rng, coarse, pos, rate):
    """Mode 1: the sun-acquisition controller drives control amplifiers 31-33.

    It reads the coarse Sun (into ``coarse``), the fine sun sensor 104
    ``fine`` and the drift-compensated gyro rates ``gyro_arcsec_s``
    [arcsec/s] of summing amplifiers 4-6; no switch of the bank is involved.

    Parameters
    ----------
    sun_p : allsky.hardware.sun_sensor.SunSensorParams
        Sun sensor 104 and the coarse sun eyes.
    mode1_p : allsky.hardware.sun_acquisition.SunAcquisitionParams
        The Mode 1 controller.
    sun_b : numpy.ndarray
        (3,) [-] true unit vector to the Sun, body axes.
    rng : numpy.ndarray
        (1,) uint64 noise generator state (``allsky.gauss``), advanced.
    pos, rate : numpy.ndarray
        (3,) written: the amplifiers' position [arcsec] and rate [arcsec/s] inputs.
    """
    coarse_sun(sun_p, sun_b, coarse, rng)
    sun_acquisition(mode1_p, sun_p.linear_range_arcsec, fine, coarse, gyro_arcsec_s, pos, rate)


@njit_stage
def route(el, routes, position_gain, registers, fine, trk, line, sources, pos, rate):
    """The inputs of control amplifiers 31-33: ``pos`` [arcsec], ``rate`` [arcsec/s].

    Positions: the optical outputs ``fine`` and ``trk`` and DACs 28-30 (fed
    by storage registers 25-27) through S9-S15, gathered in ``sources`` in
    the order of :data:`allsky.hardware.wiring.POSITION_SOURCES` and summed by
    :func:`route_positions`. Rates: the summing amplifiers' lines 130/131.

    Parameters
    ----------
    el : allsky.sim.state.ElectronicsParams
        The registers' word length and LSB [arcsec] (DACs 28-30).
    routes : numpy.ndarray
        Rows (switch, source index, axis) of ``Routing.position_routes``.
    position_gain : numpy.ndarray
        1.0 where a route's switch is closed, 0.0 where open (:func:`wire_leg`).
    registers : numpy.ndarray
        (3,) int64 [LSB] storage registers 25, 26, 27.
    line : numpy.ndarray
        (3,) [arcsec/s] the summing amplifiers' loop rates.
    """
    sources[SRC_TRACKER_YAW] = trk[0]
    sources[SRC_TRACKER_PITCH] = trk[1]
    sources[SRC_SUN_PITCH] = fine[0]
    sources[SRC_SUN_YAW] = fine[1]
    for a in range(3):
        sources[SRC_DAC + a] = dac(registers[a], el.register_bits, el.register_lsb_arcsec)
    route_positions(routes, position_gain, sources, pos)
    for a in range(3):
        rate[a] = line[a]


@njit_stage
def route_positions(routes, gain, sources, pos):
    """Sum the switched ``sources`` into the amplifiers' position inputs ``pos``.

    ``routes`` are the wiring table's rows (switch, source index, axis),
    grouped by axis, and ``gain`` is 1.0 where the row's switch is closed,
    0.0 where it is open (:func:`wire_leg`): an open switch adds a zero. The
    first input of an axis is taken as it is, not added to 0.0, so that the
    sums, -0.0 included, round exactly as the written-out expressions
    ``S12 * tracker_yaw + S9 * dac28`` do.
    """
    pos[0] = 0.0  # an amplifier without position inputs
    pos[1] = 0.0
    pos[2] = 0.0
    if routes.shape[0] == 0:
        return
    # Indices as unsigned integers: numba then leaves out its negative-index
    # wrap-around, which cost about 4 % of the frame time here.
    axis = np.uint64(routes[0, 2])
    acc = gain[0] * sources[np.uint64(routes[0, 1])]
    for r in range(1, routes.shape[0]):
        row_axis = np.uint64(routes[r, 2])
        term = gain[r] * sources[np.uint64(routes[r, 1])]
        if row_axis == axis:
            acc += term
        else:  # the previous amplifier's sum is complete
            pos[axis] = acc
            axis = row_axis
            acc = term
    pos[axis] = acc


@njit_stage
def control(control_p, dither_p, gates, program, dithering, t_leg_s, dt_s, pos, rate,
            integral_arcsec, dith, ff, volts):
    """Control amplifiers 31-33: their output ``volts`` [V].

    An amplifier whose rate-mode switch (S18, S19; ``gates`` of
    :func:`wire_leg`) is closed follows the rate command: its position
    ``integral_arcsec`` is held at zero, as it is under the Mode 1 controller.
    While ``dithering``, the dither angle ``dith`` is added to the position
    inputs and its feed-forward ``ff`` to the outputs.

    Parameters
    ----------
    control_p : allsky.hardware.control_amp.ControlParams
        Gains and limits of the amplifiers.
    dither_p : allsky.sequencer.dither.DitherParams
        Dither generator and feed-forward.
    program : int
        The leg's ``PROGRAM_*``; under Mode 1's the integrals are held at zero.
    t_leg_s : float
        [s] time in the leg (the dither's clock).
    dt_s : float
        [s] frame length.
    pos, rate : numpy.ndarray
        (3,) the position [arcsec] and rate [arcsec/s] inputs (``pos`` gains
        the dither).
    """
    if dithering:
        dither_command(dither_p, t_leg_s, dith, ff)
        for a in range(3):
            pos[a] += dith[a]
    for a in range(3):
        integrate = program != PROGRAM_MODE1 and not gates[GATE_RATE_MODE, a]
        volts[a] = control_amp(control_p, a, pos[a], rate[a], integral_arcsec, integrate, dt_s)
        if dithering:  # feed-forward through the actuator path
            volts[a] += ff[a]


@njit_stage
def actuate(pwpf_p, jets_p, dt_s, volts, filter_v, valve, on_frames, propellant_kg, torque):
    """PWPF modulators 34-36 and jets 39-41: ``torque`` [N m].

    Returns False once the tank is dry.

    Parameters
    ----------
    pwpf_p : allsky.hardware.pwpf.PwpfParams
        The modulators.
    jets_p : allsky.hardware.jets.JetParams
        Jets 39-41 and their feed.
    dt_s : float
        [s] frame length.
    volts : numpy.ndarray
        (3,) [V] outputs of control amplifiers 31-33.
    filter_v, on_frames : numpy.ndarray
        (3,) the modulators' filter states [V] and frames since each valve
        opened, advanced.
    valve : numpy.ndarray
        (3,) int64 valve commands -1/0/+1, written.
    propellant_kg : numpy.ndarray
        (1,) [kg] propellant left in tank 108, drawn from.
    """
    for a in range(3):
        pwpf_step(pwpf_p, a, volts[a], filter_v, valve, on_frames)
    return jets(jets_p, valve, dt_s, propellant_kg, torque)


@njit_stage
def actuate_vehicle(pwpf_p, jets_p, wheels_p, actuator, dt_s, volts, filter_v, valve, on_frames,
                    propellant_kg, wheel_h, wheel_unload, wheel_u, torque, wheel_hb, wheel_hdot):
    """:func:`actuate`, or on the wheel vehicle :func:`actuate_wheels`.

    ``wheels_p`` is None on a vehicle without wheels (the loop then compiles
    :func:`actuate` alone, :mod:`allsky.sim.parts`). On the wheel vehicle
    (``actuator`` ACTUATOR_WHEELS) ``torque`` is the jets' unloading torque,
    and the wheels' share goes to ``wheel_u``, ``wheel_hb`` and
    ``wheel_hdot`` for :func:`advance_vehicle`. Returns False once the tank is dry.

    Parameters
    ----------
    pwpf_p : allsky.hardware.pwpf.PwpfParams
        The modulators (the jet vehicle).
    wheels_p : allsky.vehicle.wheels.WheelParams or None
        The wheel array (the wheel vehicle).
    jets_p : allsky.hardware.jets.JetParams
        Jets 39-41 and their feed.
    dt_s : float
        [s] frame length.
    volts : numpy.ndarray
        (3,) [V] outputs of control amplifiers 31-33.
    filter_v, on_frames : numpy.ndarray
        (3,) the modulators' filter states [V] and frames since each valve
        opened, advanced.
    valve : numpy.ndarray
        (3,) int64 valve commands -1/0/+1, written.
    propellant_kg : numpy.ndarray
        (1,) [kg] propellant left in tank 108, drawn from.
    wheel_h : numpy.ndarray
        [N m s] each wheel's momentum about its axis (``State.wheel_h``).
    wheel_unload : numpy.ndarray
        (4,) int64 the unloader's state (:func:`allsky.vehicle.wheels.unload_valves`).
    """
    if wheels_p is not None:  # noqa: SIM102 - alone, so numba decides it before typing
        if actuator == ACTUATOR_WHEELS:
            return actuate_wheels(wheels_p, jets_p, dt_s, volts, valve, propellant_kg, wheel_h,
                                  wheel_unload, wheel_u, torque, wheel_hb, wheel_hdot)
    return actuate(pwpf_p, jets_p, dt_s, volts, filter_v, valve, on_frames, propellant_kg,
                   torque)


@njit_stage
def actuate_wheels(wheels_p, jets_p, dt_s, volts, valve, propellant_kg, wheel_h, wheel_unload,
                   wheel_u, torque, wheel_hb, wheel_hdot):
    """The reaction wheels, and jets 39-41 unloading them (allsky.vehicle.wheels).

    Control amplifiers 31-33 command a body torque, linearly (no modulator):
    ``volts`` times ``torque_per_volt_n_m_v``. The jets fire only to unload
    (``valve``, ``torque`` [N m]); the wheels are asked for the amplifiers'
    torque less the jets', so that they cancel each pulse. Out: the motor
    torques ``wheel_u`` [N m] and, in body axes, the wheels' momentum
    ``wheel_hb`` [N m s] and its rate ``wheel_hdot`` [N m] over the frame.
    Returns False once the tank is dry.

    Parameters
    ----------
    wheels_p : allsky.vehicle.wheels.WheelParams
        The wheel array.
    jets_p : allsky.hardware.jets.JetParams
        Jets 39-41 and their feed.
    dt_s : float
        [s] frame length.
    volts : numpy.ndarray
        (3,) [V] outputs of control amplifiers 31-33.
    propellant_kg : numpy.ndarray
        (1,) [kg] propellant left in tank 108, drawn from.
    wheel_h : numpy.ndarray
        [N m s] each wheel's momentum about its axis (``State.wheel_h``).
    wheel_unload : numpy.ndarray
        (4,) int64 the unloader's state (:func:`allsky.vehicle.wheels.unload_valves`).
    """
    unload_valves(wheels_p, wheel_h, wheel_unload, valve)
    tank_ok = jets(jets_p, valve, dt_s, propellant_kg, torque)
    for a in range(3):
        wheel_hdot[a] = volts[a] * wheels_p.torque_per_volt_n_m_v[a] - torque[a]
    if wheels_p.allocation == ALLOCATION_DIRECT:
        distribute_direct(wheels_p, wheel_hdot, wheel_h, dt_s, wheel_u)
    else:
        distribute(wheels_p, wheel_hdot, wheel_h, dt_s, wheel_u)
    body_vector(wheels_p.axes, wheel_h, wheel_hb)
    body_vector(wheels_p.axes, wheel_u, wheel_hdot)
    return tank_ok


@njit_stage
def count_jet_time(valve, dt_s, jet_on_s):
    """Add the frame to the on-time of each axis whose modulator holds a valve open.

    ``valve`` (3) holds the valve commands -1/0/+1, ``dt_s`` [s] is the frame
    length and ``jet_on_s`` (3) [s] the on-times since ejection, added to.
    """
    for a in range(3):  # valve is -1, 0 or +1: its square is 1 while open (no branch)
        jet_on_s[a] += dt_s * (valve[a] * valve[a])


@njit_stage
def advance_vehicle(plant_p, wheels_p, actuator, dt_s, torque, wheel_hb, wheel_hdot, wheel_u,
                    wheel_h, wheel_peak_fraction, x, dtheta_rad, frame):
    """The rigid body (or the gyrostat) over a frame under ``torque``; the clock.

    ``wheels_p`` is None on a vehicle without wheels (the loop then compiles
    the rigid body alone, :mod:`allsky.sim.parts`). On the wheel vehicle the
    wheels' momentum ``wheel_hb`` changes at ``wheel_hdot`` (body axes), and
    the wheel momenta ``wheel_h`` under their motor torques ``wheel_u``.

    Parameters
    ----------
    plant_p : allsky.vehicle.plant.RigidBodyParams
        The body's mass properties (on the wheel vehicle, less the wheels'
        spin inertia).
    wheels_p : allsky.vehicle.wheels.WheelParams or None
        The wheel array.
    actuator : int
        ``ACTUATOR_JETS`` or ``ACTUATOR_WHEELS`` (:mod:`allsky.vehicle.wheels`).
    dt_s : float
        [s] frame length.
    torque : numpy.ndarray
        (3,) [N m] the torque on the body (the jets', the environment's), body axes.
    wheel_peak_fraction : numpy.ndarray
        (1,) largest ``|h_i| / limit_i`` of any wheel so far, updated.
    x : numpy.ndarray
        (7,) plant state: quaternion inertial to body, body rate [rad/s]; advanced.
    dtheta_rad : numpy.ndarray
        (3,) [rad] written: the frame's body-angle increment (what the gyros see).
    frame : numpy.ndarray
        (1,) int64 the mission clock, advanced by one frame.
    """
    if wheels_p is not None:  # noqa: SIM102 - alone, so numba decides it before typing
        if actuator == ACTUATOR_WHEELS:
            rk4_step_gyrostat(plant_p, x, torque, wheel_hb, wheel_hdot, dt_s, dtheta_rad)
            advance_momentum(wheels_p, wheel_u, dt_s, wheel_h, wheel_peak_fraction)
            frame[0] += 1
            return
    rk4_step(plant_p, x, torque, dt_s, dtheta_rad)
    frame[0] += 1


@njit_stage
def excursion_tracked(excursion_ref_q):
    """Whether the mission tracks its largest excursion from ``excursion_ref_q``.

    All zero: not tracked. Read once a leg: the mission sets the reference between legs
    (:meth:`allsky.sim.mission.Mission.track_excursion`).
    """
    return (excursion_ref_q[0] != 0.0 or excursion_ref_q[1] != 0.0
            or excursion_ref_q[2] != 0.0 or excursion_ref_q[3] != 0.0)


@njit_stage
def track_excursion(excursion_ref_q, x, max_excursion_rad):
    """The largest rotation [rad] away from the attitude ``excursion_ref_q``, updated.

    ``x`` is the plant's state after the frame (its quaternion first);
    ``max_excursion_rad`` (1,) [rad] the largest so far.
    """
    e = _rotation_angle(excursion_ref_q, x)
    max_excursion_rad[0] = max(max_excursion_rad[0], e)


@njit_stage
def _rotation_angle(qa, qb):
    """Angle [rad] of the rotation taking attitude ``qa`` to ``qb`` (atan2 form)."""
    w = qa[0] * qb[0] + qa[1] * qb[1] + qa[2] * qb[2] + qa[3] * qb[3]
    x = qa[0] * qb[1] - qa[1] * qb[0] - qa[2] * qb[3] + qa[3] * qb[2]
    y = qa[0] * qb[2] + qa[1] * qb[3] - qa[2] * qb[0] - qa[3] * qb[1]
    z = qa[0] * qb[3] - qa[1] * qb[2] + qa[2] * qb[1] - qa[3] * qb[0]
    return 2.0 * xmath.atan2(np.sqrt(x * x + y * y + z * z), abs(w))
