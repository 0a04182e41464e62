"""Faults compiled into the frame loop: small fixed-size arrays and where they act.

A scenario's ``[[faults]]`` (:mod:`allsky.config.faults`) become a
:class:`FaultParams` of :data:`MAX_FAULTS` slots: kind code, axis, jet sign,
duration and size per slot. Their onsets live in the mission state
(``State.fault_state``, row :data:`ONSET`), as frames of the mission clock
(:mod:`allsky.clock`): a ``start_s`` onset is set at ejection (:func:`arm`,
the first frame starting at or after ``start_s``), a ``start_mode`` onset by
the mission driver when that mode starts (:func:`on_mode_start`). A fault
acts in the frames ``onset <= n < onset + duration_frames``, its duration
counted in whole frames from its onset (``clock.frames_for``).

Each helper acts at the block the fault affects, called by the frame loop
only when the mission has faults (``FaultParams.n > 0``), so that the
fault-free loop runs the same code as before:

* :func:`fault_tracker` (before ``sense``): a wrong star joins the stars
  star tracker 105's magnitude window passes; :func:`fault_release`: the
  tracker forgets a glint once none acts;
* :func:`fault_sense` (after ``sense``): gyros 1-3 stuck, dead, bias or
  scale-factor step; sun sensor 104 blind; tracker 105 dropout or stray light,
  and its bright gate;
* :func:`fault_upset` (after ``compute``): one bit of a counter 13-18 or a
  storage register 25-27 flips, once;
* :func:`fault_actuate` (after ``actuate``): jets 39-41 stuck open or failed
  off; a propellant leak.

Rows :data:`MEMORY` and :data:`LATCHED` of ``State.fault_state`` keep what a
fault remembers: the output a stuck gyro froze at, and whether it has (or
whether an upset has happened). Every entry is finite, as a saved state's must be.
"""

import math
import re
from typing import NamedTuple

import numpy as np

from allsky import clock, units, xmath
from allsky.config.faults import MAX_FAULTS, describe
from allsky.hardware import star_tracker as st
from allsky.hardware.star_tracker import FALSE_TARGET, StarTrackerParams
from allsky.jit import njit_stage
from allsky.units import RAD2ARCSEC
from allsky.vocabulary import AXES, FAULT_CODE

#: Scenario kind -> code (FaultParams.kind; 0 = an empty slot): the vocabulary's.
KIND_CODE = FAULT_CODE
# The codes the frame loop tests, by name.
JET_STUCK_OPEN = KIND_CODE["jet_stuck_open"]
JET_FAILED_OFF = KIND_CODE["jet_failed_off"]
GYRO_STUCK = KIND_CODE["gyro_stuck"]
GYRO_DEAD = KIND_CODE["gyro_dead"]
GYRO_BIAS_STEP = KIND_CODE["gyro_bias_step"]
GYRO_SCALE_FACTOR_STEP = KIND_CODE["gyro_scale_factor_step"]
SUN_SENSOR_BLIND = KIND_CODE["sun_sensor_blind"]
TRACKER_DROPOUT = KIND_CODE["tracker_dropout"]
TRACKER_STRAY_LIGHT = KIND_CODE["tracker_stray_light"]
WRONG_STAR = KIND_CODE["wrong_star"]
COUNTER_UPSET = KIND_CODE["counter_upset"]
PROPELLANT_LEAK = KIND_CODE["propellant_leak"]
#: Counter or register numeral -> word index: drift counters 13/15/17 (0-2),
#: up/down counters 14/16/18 (3-5), storage registers 25-27 (6-8).
WORD_INDEX = {"13": 0, "15": 1, "17": 2, "14": 3, "16": 4, "18": 5, "25": 6, "26": 7, "27": 8}
# Rows of State.fault_state.
ONSET = 0  #: [frames] the frame the fault starts in (negative: not yet known)
MEMORY = 1  #: what the fault remembers (a stuck gyro's output [arcsec/s])
LATCHED = 2  #: 1.0 once the fault has taken its memory, or its upset has happened
N_ROWS = 3
UNKNOWN = -1.0  #: the onset of a fault whose mode has not started yet


class FaultParams(NamedTuple):
    """The scenario's faults as fixed-size arrays (slots ``n`` and on are empty)."""

    n: int  #: number of faults
    kind: np.ndarray  #: (MAX_FAULTS,) int64 kind code
    axis: np.ndarray  #: (MAX_FAULTS,) int64 0 roll, 1 pitch, 2 yaw
    sign: np.ndarray  #: (MAX_FAULTS,) int64 jet of the couple, +1 or -1
    #: (MAX_FAULTS,) int64 [frames] how long each acts from its onset; NEVER = permanent
    duration_frames: np.ndarray
    #: (MAX_FAULTS,) bias [arcsec/s], scale step [-], stray-light offset [arcsec], leak [kg/s]
    size: np.ndarray
    word: np.ndarray  #: (MAX_FAULTS,) int64 upset word (WORD_INDEX)
    bit: np.ndarray  #: (MAX_FAULTS,) int64 upset bit
    width_bits: np.ndarray  #: (MAX_FAULTS,) int64 word length of the upset word [bit]
    #: (MAX_FAULTS,) [mag] a glint's brightness; nan = none given (followed whatever it is)
    magnitude: np.ndarray
    jets: np.ndarray  #: (MAX_FAULTS,) int64 jets of a couple stuck open: 1 or 2
    torque_n_m: np.ndarray  #: (MAX_FAULTS, 3) [N m] a leak's body torque
    #: star tracker 105 with the wrong stars added after the window's (as Params.tracker if none)
    tracker: StarTrackerParams


def new_fault_state() -> np.ndarray:
    """``State.fault_state`` with no onset known yet: (N_ROWS, MAX_FAULTS)."""
    out = np.zeros((N_ROWS, MAX_FAULTS))
    out[ONSET] = UNKNOWN
    return out


def wrong_stars(faults) -> list:
    """Names of the wrong stars the faults add to the tracker's window, in order.

    ``faults`` is the scenario's ``[[faults]]`` (a list of dicts).
    """
    out = []
    for f in faults:
        if f["kind"] == "wrong_star" and f["star"] not in out:
            out.append(f["star"])
    return out


def compile_faults(cfg, tracker: StarTrackerParams, window_names, star_direction,
                   star_magnitude) -> FaultParams:
    """:class:`FaultParams` from the scenario's faults.

    ``cfg`` is the scenario (its ``faults`` and ``electronics``),
    ``tracker`` is star tracker 105's parameters, ``window_names`` the names
    of the stars its window passes; ``star_direction`` gives a star's unit
    vector (inertial axes) by name and ``star_magnitude`` its visual
    magnitude [mag]: a wrong star not already in the window is added after them.
    """
    faults = cfg.faults
    n = len(faults)
    ck = clock.clock(cfg.mission.frame_s)
    kind = np.zeros(MAX_FAULTS, dtype=np.int64)
    axis = np.zeros(MAX_FAULTS, dtype=np.int64)
    sign = np.ones(MAX_FAULTS, dtype=np.int64)
    duration = np.full(MAX_FAULTS, clock.NEVER, dtype=np.int64)
    size = np.zeros(MAX_FAULTS)
    word = np.zeros(MAX_FAULTS, dtype=np.int64)
    bit = np.zeros(MAX_FAULTS, dtype=np.int64)
    width = np.ones(MAX_FAULTS, dtype=np.int64)
    magnitude = np.full(MAX_FAULTS, np.nan)
    jets = np.full(MAX_FAULTS, 2, dtype=np.int64)
    torque = np.zeros((MAX_FAULTS, 3))
    el = cfg.electronics
    for i, f in enumerate(faults):
        kind[i] = KIND_CODE[f["kind"]]
        axis[i] = AXES.index(f.get("axis", "roll"))
        sign[i] = f.get("sign", 1)
        duration[i] = clock.frames_for(ck, f.get("duration_s", math.inf))
        size[i] = (f.get("size_deg_h", 0.0) * units.DEG_H2ARCSEC_S
                   + f.get("size_ppm", 0.0) * units.PPM2FRACTION
                   + f.get("offset_deg", 0.0) * units.DEG2ARCSEC + f.get("rate_kg_s", 0.0))
        if f["kind"] == "counter_upset":
            reg = f["register"]
            word[i], bit[i] = WORD_INDEX[reg], f["bit"]
            width[i] = (el.drift_counter_bits if reg in ("13", "15", "17") else
                        el.counter_bits if reg in ("14", "16", "18") else el.register_bits)
        magnitude[i] = f.get("magnitude", np.nan)
        jets[i] = f.get("jets", 2)
        torque[i] = f.get("torque_n_m", (0.0, 0.0, 0.0))
        if "vent_position_m" in f:
            torque[i] = vent_torque_n_m(f["rate_kg_s"], cfg.jets.isp_s, f["vent_position_m"],
                                        f["vent_direction"])
    extra = [s for s in wrong_stars(faults) if s not in window_names]
    if extra:
        stars = np.vstack([tracker.stars_inertial.reshape(-1, 3),
                           np.array([star_direction(s) for s in extra], dtype=float)])
        mags = np.concatenate([tracker.magnitudes,
                               np.array([star_magnitude(s) for s in extra], dtype=float)])
        tracker = tracker._replace(stars_inertial=np.ascontiguousarray(stars),
                                   magnitudes=np.ascontiguousarray(mags))
    return FaultParams(n, kind, axis, sign, duration, size, word, bit, width, magnitude, jets,
                       torque, tracker)


def vent_torque_n_m(rate_kg_s, isp_s, vent_position_m, vent_direction):
    """The body torque [N m] of gas leaving a vent at the jets' exhaust speed.

    The gas leaves at ``rate_kg_s`` [kg/s] along the unit ``vent_direction``
    (body axes) with the exhaust speed ``isp_s g0`` [m/s] (``isp_s`` [s], the
    jets' specific impulse, ``jets.isp_s``); the vehicle feels
    the opposite thrust ``F = -rate v_e d`` at ``vent_position_m`` [m] from
    the centre of mass, the torque ``r x F``. (The thrust's force moves the
    centre of mass; the emulator has no translation, so only the torque
    acts.) Values at the initial tank pressure.
    """
    f = -float(rate_kg_s) * float(isp_s) * units.G0_M_S2 * np.asarray(vent_direction, float)
    r = np.asarray(vent_position_m, dtype=float)
    return np.array([r[1] * f[2] - r[2] * f[1], r[2] * f[0] - r[0] * f[2],
                     r[0] * f[1] - r[1] * f[0]])


def arm(fault_state, faults, ck) -> None:
    """Set the onsets given in mission time (``start_s``); mode onsets wait.

    ``fault_state`` is ``State.fault_state``, its :data:`ONSET` row written
    with the first frame starting at or after each ``start_s`` (the clock
    ``ck``'s rule, :func:`allsky.clock.frame_at`); ``faults`` is the
    scenario's ``[[faults]]`` (a list of dicts).
    """
    for i, f in enumerate(faults):
        if "start_s" in f:
            fault_state[ONSET, i] = clock.frame_at(ck, f["start_s"])


def on_mode_start(fault_state, faults, mode, frame) -> None:
    """The mission driver's hook as ``mode`` starts: the onsets of its faults.

    A mode flown again (a recovery) does not move an onset already set.
    ``fault_state`` is ``State.fault_state`` (its :data:`ONSET` row written),
    ``faults`` is the scenario's ``[[faults]]`` (a list of dicts), ``frame``
    the frame the mode starts in.
    """
    for i, f in enumerate(faults):
        if f.get("start_mode") == mode and fault_state[ONSET, i] < 0.0:
            fault_state[ONSET, i] = frame


def started(fault_state, faults, frame) -> list:
    """``(fault, onset frame)`` of the faults that have started by frame ``frame``.

    ``fault_state`` is ``State.fault_state`` (the onsets [frames]);
    ``faults`` is the scenario's ``[[faults]]`` (a list of dicts).
    """
    return [(f, int(fault_state[ONSET, i])) for i, f in enumerate(faults)
            if 0.0 <= fault_state[ONSET, i] <= frame]


def acting(fault_state, faults, ck, frame) -> list:
    """``(fault, onset frame)`` of the faults acting in frame ``frame`` (clock ``ck``).

    ``fault_state`` and ``faults`` as for :func:`started`.
    """
    return [(f, onset) for f, onset in started(fault_state, faults, frame)
            if frame < onset + clock.frames_for(ck, f.get("duration_s", math.inf))]


def blame(fault_state, faults, ck, frame) -> str:
    """What an abort reason adds: `` (tracker dropout at 512.0 s)``, or "".

    It names the faults acting in frame ``frame``, or else the last to
    start. ``fault_state`` is ``State.fault_state`` (the onsets [frames]);
    ``faults`` is the scenario's ``[[faults]]`` (a list of dicts); ``ck``
    the mission's clock.
    """
    # The faults acting at the abort; when none does any more, the last one that started.
    hit = acting(fault_state, faults, ck, frame) or sorted(
        started(fault_state, faults, frame), key=lambda h: h[1])[-1:]
    if not hit:
        return ""
    return " (" + "; ".join(f"{describe(f)} at {clock.time_s(ck, onset):.1f} s"
                            for f, onset in hit) + ")"


_BLAME = re.compile(r" \([^()]* at -?[0-9.]+ s\)$")


def symptom(reason: str) -> str:
    """An abort reason without what :func:`blame` added: the outcome, fault-free words.

    ``reason`` is the abort reason (None or "" gives "").
    """
    return _BLAME.sub("", reason or "")


# -- in the frame loop -------------------------------------------------------------

@njit_stage
def _active(fp, fault_state, i, frame):
    """Whether fault ``i`` acts in frame ``frame``."""
    onset = fault_state[ONSET, i]
    return 0.0 <= onset <= frame < onset + fp.duration_frames[i]


@njit_stage
def fault_tracker(fp, tracker_p, fault_state, frame):
    """Star tracker 105's parameters this frame: with the wrong stars while one acts.

    Parameters
    ----------
    fp : FaultParams
        The scenario's faults.
    tracker_p : allsky.hardware.star_tracker.StarTrackerParams
        The tracker without a fault (returned while no wrong star acts).
    fault_state : numpy.ndarray
        ``State.fault_state`` (``N_ROWS``, ``MAX_FAULTS``): onsets [frames], memories.
    frame : int
        The mission's frame (its clock).
    """
    for i in range(fp.n):
        if fp.kind[i] == WRONG_STAR and _active(fp, fault_state, i, frame):
            return fp.tracker
    return tracker_p


@njit_stage
def fault_release(fp, fault_state, frame, lock):
    """Before ``sense``: a glint held or refused is forgotten once no glint acts.

    ``lock`` is star tracker 105's memory (:mod:`allsky.hardware.star_tracker`):
    the tracker searches again in the frame after the last glint ends.

    Parameters
    ----------
    fp : FaultParams
        The scenario's faults.
    fault_state : numpy.ndarray
        ``State.fault_state`` (``N_ROWS``, ``MAX_FAULTS``): onsets [frames], memories.
    frame : int
        The mission's frame (its clock).
    """
    for i in range(fp.n):
        if fp.kind[i] == TRACKER_STRAY_LIGHT and _active(fp, fault_state, i, frame):
            return
    if lock[st.HELD] == FALSE_TARGET:
        lock[st.HELD] = st.NONE
    for j in range(st.N_REFUSED):
        if lock[st.REFUSED + j] == FALSE_TARGET:
            lock[st.REFUSED + j] = st.NONE


@njit_stage
def _glint_refused(tracker_p, lock, cone_armed):
    """Whether the cone-angle check refuses a glint (its cone angle, pitch output, is 0).

    Only while the check is armed (``cone_armed``: the roll axis on the Sun).
    The refusal is remembered and flagged once, as a star's is (in the next
    frame if a star was refused in this one).
    """
    if not cone_armed or tracker_p.cone_check_rad <= 0.0 \
            or abs(tracker_p.reference_cone_rad) <= tracker_p.cone_check_rad:
        return False
    # One refusal a frame: a star's refused in this frame leaves the glint's to the next.
    if not st.refused(lock, FALSE_TARGET) and lock[st.NEW_REFUSAL] == st.NONE:
        st.refuse_now(lock, FALSE_TARGET, 0.0)
    return True


@njit_stage
def fault_sense(fp, tracker_p, fault_state, frame, dt_s, dtheta_rad, fine, trk, gyro, lock, star,
                cone_armed):
    """Sensor faults on the outputs of ``sense``; returns the star the tracker holds.

    Gyros 1-3 (``gyro`` [arcsec/s]): stuck at the output of the onset frame,
    dead (zero), a bias step, a scale-factor step on the rate of the frame's
    increment ``dtheta_rad``. Sun sensor 104 blind: ``fine`` absent.
    Star tracker 105 (``tracker_p``, its memory ``lock``): a dropout loses
    the lock (``trk`` absent); a glint, a body-fixed false target at the
    fault's offset in the yaw output and at cone angle 0, takes the lock
    (unless the cone-angle check refuses it) or, given a brightness, is
    locked only when the tracker holds nothing and the glint is inside the
    magnitude window. With a bright gate the glints' light is added to the
    stars' in the slit (``lock[SLIT_FLUX]``), which the gate judges next
    (:func:`allsky.hardware.star_tracker.bright_gate`).
    ``cone_armed`` says whether the cone-angle check is armed.

    Parameters
    ----------
    fp : FaultParams
        The scenario's faults.
    fault_state : numpy.ndarray
        ``State.fault_state`` (``N_ROWS``, ``MAX_FAULTS``): onsets [frames], memories.
    frame : int
        The mission's frame (its clock).
    dt_s : float
        [s] frame length.
    star : int
        The target the tracker holds after ``sense``: a star's index, -1
        none, or ``FALSE_TARGET``.
    """
    glint_flux = 0.0  # the glints of known brightness acting in this frame
    for i in range(fp.n):
        if not _active(fp, fault_state, i, frame):
            continue
        k = fp.kind[i]
        a = fp.axis[i]
        if k == GYRO_STUCK:
            if fault_state[LATCHED, i] == 0.0:
                fault_state[MEMORY, i] = gyro[a]
                fault_state[LATCHED, i] = 1.0
            gyro[a] = fault_state[MEMORY, i]
        elif k == GYRO_DEAD:
            gyro[a] = 0.0
        elif k == GYRO_BIAS_STEP:
            gyro[a] += fp.size[i]
        elif k == GYRO_SCALE_FACTOR_STEP:
            gyro[a] += fp.size[i] * dtheta_rad[a] / dt_s * RAD2ARCSEC
        elif k == SUN_SENSOR_BLIND:
            fine[0] = 0.0
            fine[1] = 0.0
            fine[2] = 0.0
        elif k == TRACKER_DROPOUT:
            trk[0] = 0.0
            trk[1] = 0.0
            trk[2] = 0.0
            star = -1
            lock[st.HELD] = st.NONE
        elif k == TRACKER_STRAY_LIGHT:
            m = fp.magnitude[i]
            bright = not np.isnan(m)
            if bright:
                glint_flux += xmath.exp10(-0.4 * m)
            take = (not bright or (star == -1 and tracker_p.window_bright_mag <= m
                                   <= tracker_p.window_faint_mag))
            if star == FALSE_TARGET or (take and not st.refused(lock, FALSE_TARGET)
                                        and not _glint_refused(tracker_p, lock, cone_armed)):
                trk[0] = fp.size[i]
                trk[1] = 0.0
                trk[2] = 1.0
                star = FALSE_TARGET
                lock[st.HELD] = FALSE_TARGET
    if tracker_p.bright_gate_mag > -np.inf:  # the glints' light beside the stars' in the slit
        lock[st.SLIT_FLUX] += glint_flux
    return star


@njit_stage
def _flip(value, bit, width_bits):
    """``value`` (two's complement of ``width_bits`` bits) with ``bit`` flipped."""
    span = np.int64(1) << width_bits
    u = (value & (span - 1)) ^ (np.int64(1) << bit)
    if u >= span >> 1:
        u -= span
    return u


@njit_stage
def fault_upset(fp, fault_state, frame, drift_counters, counters, registers):
    """Counter upsets: flip the fault's bit of counter 13-18 or register 25-27, once.

    Returns True in the frame a drift counter 13/15/17 is upset.

    Parameters
    ----------
    fp : FaultParams
        The scenario's faults.
    fault_state : numpy.ndarray
        ``State.fault_state`` (``N_ROWS``, ``MAX_FAULTS``): onsets [frames], memories.
    frame : int
        The mission's frame (its clock).
    drift_counters : numpy.ndarray
        [pulses] drift counters 13, 15, 17.
    counters : numpy.ndarray
        [pulses] up/down counters 14, 16, 18.
    registers : numpy.ndarray
        [LSB] storage registers 25, 26, 27.
    """
    drift = False
    for i in range(fp.n):
        if fp.kind[i] != COUNTER_UPSET or fault_state[LATCHED, i] != 0.0 \
                or not 0.0 <= fault_state[ONSET, i] <= frame:
            continue
        fault_state[LATCHED, i] = 1.0
        w = fp.word[i]
        if w < 3:
            drift_counters[w] = _flip(drift_counters[w], fp.bit[i], fp.width_bits[i])
            drift = True
        elif w < 6:
            counters[w - 3] = _flip(counters[w - 3], fp.bit[i], fp.width_bits[i])
        else:
            registers[w - 6] = _flip(registers[w - 6], fp.bit[i], fp.width_bits[i])
    return drift


@njit_stage
def fault_actuate(fp, fault_state, frame, jets_p, dt_s, valve, propellant_kg, torque, tank_ok,
                  feed):
    """Jets 39-41 and the tank after ``actuate``; returns False once the tank is dry.

    A couple stuck open (``jets`` 2) fires whatever modulators 34-36 command
    (against the opposite couple the torques cancel, both use gas); one jet
    of it stuck open (``jets`` 1) gives half the couple's torque and flow,
    so that the opposite couple, commanded, still brakes at half its torque.
    A couple failed off gives no torque and uses no gas when commanded. A
    leak drains the tank and turns the vehicle, both in proportion to the
    feed pressure, as the jets' flow and thrust are. ``feed`` is the
    jets' thrust over its full-pressure value in this frame
    (:func:`allsky.hardware.jets.thrust_fraction` at the frame's start, 1 on
    a regulated feed): a stuck or failed jet's thrust and flow are the
    others'.

    Parameters
    ----------
    fp : FaultParams
        The scenario's faults.
    fault_state : numpy.ndarray
        ``State.fault_state`` (``N_ROWS``, ``MAX_FAULTS``): onsets [frames], memories.
    frame : int
        The mission's frame (its clock).
    jets_p : allsky.hardware.jets.JetParams
        The couples' full-pressure torque and flow.
    dt_s : float
        [s] frame length.
    valve : numpy.ndarray
        Valve commands of modulators 34-36 (-1, 0, +1 per axis).
    propellant_kg : numpy.ndarray
        (1,) [kg] propellant left in tank 108, drawn from.
    torque : numpy.ndarray
        (3,) [N m] the jets' torque of the frame, body axes, added to.
    tank_ok : bool
        False when ``actuate`` found the tank dry (nothing more is done).
    """
    if not tank_ok:
        return False
    for i in range(fp.n):
        if not _active(fp, fault_state, i, frame):
            continue
        k = fp.kind[i]
        a = fp.axis[i]
        if k == JET_STUCK_OPEN and valve[a] != fp.sign[i]:
            share = 0.5 * fp.jets[i] * feed
            torque[a] += fp.sign[i] * jets_p.torque_n_m[a] * share
            propellant_kg[0] -= jets_p.flow_kg_s[a] * dt_s * share
        elif k == JET_FAILED_OFF and valve[a] == fp.sign[i]:
            torque[a] -= fp.sign[i] * jets_p.torque_n_m[a] * feed
            propellant_kg[0] += jets_p.flow_kg_s[a] * dt_s * feed
        elif k == PROPELLANT_LEAK:  # the flow and its thrust follow the feed pressure
            propellant_kg[0] -= fp.size[i] * dt_s * feed
            for j in range(3):
                torque[j] += fp.torque_n_m[i, j] * feed
    if propellant_kg[0] <= 0.0:
        propellant_kg[0] = 0.0
        return False
    return True
