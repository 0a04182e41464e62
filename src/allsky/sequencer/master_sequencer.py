"""Master sequencer 20: runs the mode table, step by step.

The modes are data (:mod:`allsky.sequencer.modes`, SPEC section 4);
:func:`run_mode` walks one mode's steps in order: it operates the switch
bank, hands each leg to the frame loop through the mission (``m.leg``,
:func:`allsky.sim.frame_loop.run_leg` waits for the leg's condition), and
calls the named actions of :data:`ACTIONS` for what is neither a switch
nor a leg. A leg that does not finish within what is left of the mode's
timeout ends the mission as aborted, with the reason (:class:`ModeAbort`).
With ``sequencer.recovery = true`` (beyond the patent) a failed leg that
names a recovery of :data:`allsky.sequencer.modes.RETRIES` for its failure
is retried once instead (:func:`run_mode`).

The mission object ``m`` the actions work on offers ``state``
(:class:`allsky.sim.state.State`), ``cfg`` (the scenario), ``params``,
``switch(close, open_)``, ``leg(...)``, ``pulse_weight_arcsec``,
``apply_calibration``, the programmed angles, ``program_target()``
(the ground computation of register 24), ``pointing_error_arcsec()``,
``next_target()`` (turn to the next target of the sequence) and
``extend_mode(seconds)`` (move the mode's deadline on, for a recovery), and keeps
``counted_arcsec``, ``dither_estimates``, ``dither_record`` and ``hold``
(the measurements of the hold on target).

Calibration sequencer 19 (the counter reading and register 23 update at the
end of Modes 4 and 5) is part of computer 111:
:mod:`allsky.computer.calibration_sequencer`.
"""

import numpy as np

from allsky import clock, units, vocabulary
from allsky.computer import calibration_sequencer as cal19
from allsky.computer import cpu, targeting
from allsky.computer import word_registers as wr
from allsky.hardware import wiring
from allsky.sequencer import modes
from allsky.sequencer.dither_mode import dither_analysis
from allsky.sequencer.legs import WATCH_HANDOVER
from allsky.vehicle import quaternion

#: The patent's modes in flight order (the legacy plan).
MODES = modes.LEGACY_PLAN
#: Up/down counters 14, 16, 18 and drift counters 13, 15, 17, by axis.
COUNTERS = ("14", "16", "18")
DRIFT_COUNTERS = ("13", "15", "17")
#: Register 23's words each calibration turn writes.
WORDS_OF_TURN = cal19.WORDS_OF_TURN
#: Index of each rate-command module's direction in ``State.rate_sign``: 120 roll, 128 yaw.
RATE_SIGN = wiring.RATE_SIGN_SLOT


class ModeAbort(Exception):
    """A mode could not finish; the message is the abort reason.

    ``reason`` is that message, naming the mode and what failed. ``failure``
    says how: a leg's "timeout", "Sun lost", "star lost" or "propellant
    exhausted", or the turn check's "turn refused" ("" for none of these).
    """

    def __init__(self, reason, failure=""):
        super().__init__(reason)
        self.failure = failure


class ModeInterrupted(Exception):
    """A ground command ends the mode being flown, at a frame boundary.

    The message is the command's words. The mission raises it inside a leg
    (:func:`allsky.sim.commands.replan`); :func:`run_mode` flies the
    mode's ``on_command`` steps and lets it go on to the mission, which
    ends the mode and flies the plan the command set.
    """


def run_mode(m, name) -> str:
    """Fly mode ``name`` of the mode table on mission ``m``; return its exit text.

    With ``sequencer.recovery``, a wait that fails and names a recovery for
    its failure (:class:`~allsky.sequencer.modes.Retry`) is not the end:
    the recovery's steps are flown, the mode's deadline moved on, and the
    mode goes on from the recovery's step. Each recovery of a wait is flown
    at most once per flight of the mode, so the mode still ends in bounded
    time; the abort reason then says which recoveries were tried.

    Raises
    ------
    ModeAbort
        A leg was not completed (timeout, Sun or star lost, propellant gone).
    ModeInterrupted
        A ground command ended the mode (its ``on_command`` steps flown).
    """
    mode = modes.BY_NAME[name]
    records = {}
    try:
        return _run_steps(m, name, mode, records)
    except ModeInterrupted:
        context = {"after": "a ground command", "then": ""}
        for step in mode.on_command:
            _fly_step(m, name, step, records, context)
        raise


def _run_steps(m, name, mode, records) -> str:
    """The steps of ``mode`` in order, with the recoveries (:func:`run_mode`)."""
    recovery = bool(m.cfg.sequencer.recovery)
    tried = []  # (step index, recovery name) flown in this flight of the mode
    # What the sequencer last waited for: the reason the journal gives for a switch step.
    context = {"after": f"start of Mode {name}"}
    i = 0
    while i < len(mode.steps):
        step = mode.steps[i]
        context["then"] = next_wait(mode.steps[i + 1:])
        try:
            _fly_step(m, name, step, records, context)
        except ModeAbort as e:
            key = _recovery_for(step, e.failure, i, tried) if recovery else None
            if key is None:
                raise _with_recoveries(e, tried) from None
            rule = modes.RETRIES[key]
            why_not = GUARDS[rule.needs](m) if rule.needs else None
            if why_not:
                m.note("action", action="recovery", recovery=key,
                       text=f"no recovery after {e.failure}: {why_not}")
                raise _with_recoveries(ModeAbort(f"{e}; no recovery: {why_not}", e.failure),
                                       tried) from None
            tried.append((i, key))
            m.note("action", action="recovery", text=f"recovery after {e.failure}: "
                   f"{rule.text}", recovery=key)
            m.extend_mode(modes.DURATIONS[rule.extend].seconds(m.cfg, name))
            context["after"] = f"recovery: {rule.text}"
            try:
                for k, s in enumerate(rule.steps):
                    context["then"] = next_wait(rule.steps[k + 1:]) or next_wait(
                        mode.steps[i if rule.resume is None else rule.resume:])
                    _fly_step(m, name, s, records, context)
            except ModeAbort as e2:
                raise _with_recoveries(e2, tried) from None
            if rule.resume is not None:
                i = rule.resume
            continue
        i += 1
    text = mode.exit.format(cfg=m.cfg)
    if tried:
        text += "; recovered: " + ", then ".join(modes.RETRIES[key].text for _, key in tried)
    return text


def _fly_step(m, name, step, records, context):
    """One step: operate the bank, fly a leg (keeping its record), or call an action.

    Each is journaled: a switch step with what the sequencer had waited for
    (``context["after"]``), an action with its words; a wait becomes that.
    """
    if isinstance(step, modes.Operate):
        m.board.switch(close=step.close, open_=step.open_, step=context["after"],
                       waits_for=context["then"])
    elif isinstance(step, modes.Wait):
        out = fly_leg(m, name, step)
        context["after"] = f"after \u00ab{step.what}\u00bb"
        if step.record:
            records[step.record] = out
    elif not step.when or modes.CONDITIONS[step.when][1](m.cfg):
        m.note("action", action=step.action, text=modes.action_text(step))
        ACTIONS[step.action](m, records, *step.args)


def next_wait(steps) -> str:
    """What the first wait of ``steps`` waits for ("" if none)."""
    return next((s.what for s in steps if isinstance(s, modes.Wait)), "")


def _recovery_for(step, failure, index, tried):
    """The first recovery of ``step`` for ``failure`` not yet flown; None if none."""
    for key in getattr(step, "retry", ()):
        if failure in modes.RETRIES[key].on and (index, key) not in tried:
            return key
    return None


def _with_recoveries(e, tried) -> ModeAbort:
    """``e``, its reason saying which recoveries were flown before it (if any)."""
    if not tried:
        return e
    done = ", then ".join(modes.RETRIES[key].text for _, key in tried)
    return ModeAbort(f"{e}; recovery tried: {done}", e.failure)


def fly_leg(m, name, step):
    """Hand the leg of a :class:`~allsky.sequencer.modes.Wait` step to the mission.

    Returns what ``m.leg`` returns (the samples kept by the leg).

    ``m`` is the mission (:class:`~allsky.sequencer.host.Host`), ``name`` the
    mode being flown (its durations, such as the settle time, depend on it) and
    ``step`` the Wait.
    """
    watch = modes.WATCHES[step.watch].code
    cfg = m.cfg
    return m.leg(
        step.what, modes.PROGRAMS[step.program].code, watch,
        mask=modes.signal_mask(step.signals) if watch != WATCH_HANDOVER else 0,
        signal=modes.SIGNALS[step.signals[0]].code if watch == WATCH_HANDOVER else 0,
        blank_s=modes.DURATIONS[step.blank].seconds(cfg, name) if step.blank else 0.0,
        hold_s=modes.DURATIONS[step.hold].seconds(cfg, name),
        on_timeout=step.on_timeout or None,
        record_rows=modes.RECORDS[step.record](cfg) if step.record else 0,
        carry_settle=step.carry_settle)


# -- actions: what is neither a switch nor a leg ---------------------------------------
# Each is called as ``action(m, records, *args)``; ``records`` holds the samples kept
# by the mode's legs so far, by name.

def clear_drift_counters(m, records):
    """Clear drift counters 13, 15, 17 before the Mode 3 count.

    An action: ``m`` is the mission (:class:`~allsky.sequencer.host.Host`),
    ``records`` the samples the mode's legs kept, by name (not read).
    """
    m.board.clear_drift()


def clear_counters(m, records):
    """Clear up/down counters 14, 16, 18 before a calibration turn or the target roll.

    An action: ``m`` is the mission (:class:`~allsky.sequencer.host.Host`),
    ``records`` the samples the mode's legs kept, by name (not read).
    """
    m.board.clear_counters()


def roll_rate_positive(m, records):
    """Set roll rate-command module 120 to roll in the positive direction.

    An action: ``m`` is the mission (:class:`~allsky.sequencer.host.Host`),
    ``records`` the samples the mode's legs kept, by name (not read).
    """
    m.board.set_rate_sign("roll", 1)


def yaw_rate_positive(m, records):
    """Set yaw rate-command module 128 to yaw in the positive direction.

    An action: ``m`` is the mission (:class:`~allsky.sequencer.host.Host`),
    ``records`` the samples the mode's legs kept, by name (not read).
    """
    m.board.set_rate_sign("yaw", 1)


def calibration_sequencer(m, records, axis):
    """Start calibration sequencer 19 for ``axis``: counters -> register 23.

    ``axis`` is "roll" or "yaw". The turn is one full turn; with
    ``sequencer.recovery`` it is the whole number of turns the turned axis's
    counter holds, so that a turn flown on past a missed star or Sun is
    calibrated as two: with the turn check (``sequencer.turn_check_ppm`` >
    0) the number it accepted (:func:`check_turn`), without it the nearest
    to the count, whatever the count (:func:`turns_counted`).

    An action: ``m`` is the mission (:class:`~allsky.sequencer.host.Host`),
    ``records`` the samples the mode's legs kept, by name (not read).
    """
    turns = 1
    if m.cfg.sequencer.recovery:
        turns = (turn_verdict(m, axis)[0] if m.cfg.sequencer.turn_check_ppm > 0
                 else turns_counted(m, axis))
    counts = m.board.calibrate(axis, int(m.view.rate_sign[RATE_SIGN[axis]]) * turns)
    m.counted_arcsec[axis] = counts.tolist()


def turns_counted(m, axis) -> int:
    """Whole turns about ``axis`` ("roll", "yaw") counter 14 or 18 holds, at least 1.

    A scale-factor error is parts per thousand at most, far from the half
    turn that would make the nearest whole number of turns a wrong one.

    ``m`` is the mission (:class:`~allsky.sequencer.host.Host`).
    """
    k = 0 if axis == "roll" else 2
    angle_arcsec = abs(float(m.view.counters[k])) * m.pulse_weight_arcsec
    return max(1, round(angle_arcsec / cal19.FULL_TURN_ARCSEC))


def turn_verdict(m, axis):
    """What the turn check makes of the count of ``axis`` ("roll", "yaw").

    Returns ``(turns, angle_deg, off_ppm)``: the whole number of turns the
    counter (14 or 18) is judged against -- one for the patent's sequencer,
    the nearest whole number (at least one) with ``sequencer.recovery`` --,
    the counted angle [deg] and its departure from that many turns [ppm].

    ``m`` is the mission (:class:`~allsky.sequencer.host.Host`).
    """
    k = 0 if axis == "roll" else 2
    angle_arcsec = abs(float(m.view.counters[k])) * m.pulse_weight_arcsec
    turns = turns_counted(m, axis) if m.cfg.sequencer.recovery else 1
    full = turns * cal19.FULL_TURN_ARCSEC
    return turns, angle_arcsec * units.ARCSEC2DEG, (angle_arcsec - full) / full * units.FRACTION2PPM


def _turn_words(m, axis) -> tuple:
    """``(off_ppm, text)``: the count of ``axis`` against whole turns, in words."""
    turns, angle_deg, off_ppm = turn_verdict(m, axis)
    counter = COUNTERS[0 if axis == "roll" else 2]
    whole = "one turn" if turns == 1 else f"{turns} turns"
    text = (f"counter {counter} holds {angle_deg:.2f} deg, {angle_deg - 360.0 * turns:+.2f} "
            f"deg ({off_ppm:+.0f} ppm) from {whole}; sequencer.turn_check_ppm = "
            f"{m.cfg.sequencer.turn_check_ppm:g}")
    return off_ppm, text


def check_turn(m, records, axis):
    """The turn check: refuse a re-acquisition that ends no whole turn of ``axis``.

    Beyond the patent (``sequencer.turn_check_ppm`` > 0; the mode table flies
    it only then). The optics say that *a* star (or the Sun) is back in view;
    the turned axis's counter says how far the vehicle turned. A count more
    than the check from one full turn (from the nearest whole number of
    turns with ``sequencer.recovery``) is not a turn, whatever the optics
    saw: a wrong star met on the way, or a turn flown on past a missed one.

    An action: ``m`` is the mission (:class:`~allsky.sequencer.host.Host`),
    ``records`` the samples the mode's legs kept, by name (not read).

    Raises
    ------
    ModeAbort
        The turn refused (failure "turn refused"), with the count in words.
    """
    off_ppm, text = _turn_words(m, axis)
    if abs(off_ppm) > m.cfg.sequencer.turn_check_ppm:
        what = "star" if axis == "roll" else "Sun"
        raise ModeAbort(f"Mode {m.current_mode}: the turn check refused the {what} re-acquired: "
                        f"{text}", "turn refused")


def _stopped_at_a_whole_turn(axis):
    """The guard of a retry after the star (the Sun) was lost settling at a turn's end.

    With the turn check on, the turned axis's counter tells the causes
    apart. Within the sensor's field of whole turns (the tracker's narrow
    half-field for the star, the sun sensor's presence cone for the Sun,
    plus the turn check's tolerance), the target should still be in view: it
    vanished (a dropout, an occultation), and one more turn can meet it
    again. Beyond it, the vehicle turned on and carried the target out of
    view -- a jet it cannot brake against --, which one more turn does not
    mend; nor does it a counter that does not follow the vehicle (a dead or
    stuck gyro), which the count shows the same way. Returns None to retry,
    else why not.
    """
    def guard(m):
        ppm = m.cfg.sequencer.turn_check_ppm
        if ppm <= 0:
            return None
        turns, angle_deg, _ = turn_verdict(m, axis)
        field_deg = (m.cfg.star_tracker.fov_narrow_half_deg if axis == "roll"
                     else m.cfg.sun_sensor.presence_half_angle_deg)
        past_deg = angle_deg - 360.0 * turns
        if abs(past_deg) <= field_deg + 360.0 * turns * ppm * units.PPM2FRACTION:
            return None
        counter, what, turn = (("14", "star", "roll") if axis == "roll"
                               else ("18", "Sun", "yaw"))
        whole = "one turn" if turns == 1 else f"{turns} turns"
        return (f"counter {counter} holds {angle_deg:.2f} deg, {past_deg:+.2f} deg from "
                f"{whole}, beyond the {field_deg:g} deg in which the {what} stays in view: "
                f"the {what} did not vanish at the turn's end (the vehicle {turn}ed on past "
                f"it, or the counter does not follow the vehicle), and one more {turn} "
                "cannot mend that")
    guard.__name__ = f"stopped_at_a_whole_{axis}"
    return guard


#: The tests of :data:`allsky.sequencer.modes.GUARDS`: ``guard(m)`` -> None (a retry can
#: help) or the reason it cannot.
GUARDS = {"roll stopped at a whole turn": _stopped_at_a_whole_turn("roll"),
          "yaw stopped at a whole turn": _stopped_at_a_whole_turn("yaw")}


def withhold_calibration(m, records):
    """Fly Mode 6 uncalibrated if so configured: register 23 neutral, S1-S3 open.

    Only when the scenario says so (``m.apply_calibration`` false).

    An action: ``m`` is the mission (:class:`~allsky.sequencer.host.Host`),
    ``records`` the samples the mode's legs kept, by name (not read).
    """
    if not m.apply_calibration:
        m.board.neutral_word23()
        m.board.switch(open_=(1, 2, 3),
                       step="the calibration withheld (calibration.apply = false)")


def load_register_24(m, records):
    """Load programmed word register 24 with the target's roll and yaw angles [arcsec].

    The angles are computed on the ground (``m.program_target()``) unless
    the mission already holds them.

    An action: ``m`` is the mission (:class:`~allsky.sequencer.host.Host`),
    ``records`` the samples the mode's legs kept, by name (not read).
    """
    if m.programmed_roll_deg is None:
        m.program_target()
    m.board.load_word24(m.programmed_roll_deg, m.programmed_yaw_deg)


def start_roll_computation(m, records):
    """Clear CPU 22's work words and compute the first roll error (counter 14 at zero).

    An action: ``m`` is the mission (:class:`~allsky.sequencer.host.Host`),
    ``records`` the samples the mode's legs kept, by name (not read).
    """
    m.board.clear_cpu()
    m.board.cpu_step("roll", 0.0)


def roll_rate_toward_target(m, records):
    """Set roll rate-command module 120 to the direction of the programmed roll.

    An action: ``m`` is the mission (:class:`~allsky.sequencer.host.Host`),
    ``records`` the samples the mode's legs kept, by name (not read).
    """
    m.board.set_rate_sign("roll", 1 if m.view.word24[wr.PROGRAMMED_ROLL] >= 0 else -1)


def preset_counters(m, records):
    """Preset counters 16 and 18 so the corrected pitch and yaw start Mode 6-2 at zero.

    An action: ``m`` is the mission (:class:`~allsky.sequencer.host.Host`),
    ``records`` the samples the mode's legs kept, by name (not read).
    """
    pitch_arcsec, yaw_arcsec = cpu.mode6_preset_arcsec(m.view.word23, m.view.cpu)
    m.board.preset_counters({"pitch": pitch_arcsec, "yaw": yaw_arcsec})


def start_yaw_computation(m, records):
    """CPU 22 computes the yaw, then the pitch error from preset counters 18 and 16.

    An action: ``m`` is the mission (:class:`~allsky.sequencer.host.Host`),
    ``records`` the samples the mode's legs kept, by name (not read).
    """
    s = m.view
    m.board.cpu_step("yaw", s.counters[2] * m.pulse_weight_arcsec)
    m.board.cpu_step("pitch", s.counters[1] * m.pulse_weight_arcsec)


def yaw_rate_toward_target(m, records):
    """Set yaw rate-command module 128 to the direction of CPU 22's yaw error.

    An action: ``m`` is the mission (:class:`~allsky.sequencer.host.Host`),
    ``records`` the samples the mode's legs kept, by name (not read).
    """
    m.board.set_rate_sign("yaw", 1 if m.view.cpu[cpu.ERROR_YAW] >= 0 else -1)


def record_hold_start(m, records):
    """Note the true attitude, time and pointing error at the start of the hold.

    Kept in ``m.hold`` (plain numbers, so a snapshot can save them).

    An action: ``m`` is the mission (:class:`~allsky.sequencer.host.Host`),
    ``records`` the samples the mode's legs kept, by name (not read).
    """
    s = m.view
    m.hold = {"start_time_s": m.now_s(),
              "start_quaternion": [float(v) for v in s.x[0:4]],
              "start_pointing_error_arcsec": float(m.pointing_error_arcsec())}


def measure_hold(m, records):
    """Measure the hold: end pointing error and the attitude's drift per body axis.

    The drift is the small rotation from the attitude at the hold's start to
    the one at its end, ``2 q_vec`` of ``q_start^-1 (x) q_end`` (the
    quaternions rotate inertial into body coordinates,
    :mod:`allsky.vehicle.quaternion`), in arcsec per minute of hold about
    roll, pitch and yaw.

    An action: ``m`` is the mission (:class:`~allsky.sequencer.host.Host`),
    ``records`` the samples the mode's legs kept, by name (not read).
    """
    s = m.view
    h = m.hold
    q_start = np.asarray(h["start_quaternion"])
    q_end = np.array(s.x[0:4], dtype=float)
    conj = q_start * np.array([1.0, -1.0, -1.0, -1.0])
    dq = quaternion.multiply(conj, q_end)
    if dq[0] < 0:  # the same rotation, the short way round
        dq = -dq
    rot_arcsec = 2.0 * dq[1:4] * units.RAD2ARCSEC
    # The hold's length from frames, not the difference of two rounded times.
    ck = m.params.clock
    hold_s = clock.time_s(ck, m.frame - clock.frame_at(ck, h["start_time_s"]))
    per_min = rot_arcsec / (hold_s / 60.0)
    m.hold = {"hold_s": hold_s,
              "start_pointing_error_arcsec": h["start_pointing_error_arcsec"],
              "end_pointing_error_arcsec": float(m.pointing_error_arcsec()),
              "drift_arcsec_per_min": {axis: float(v) for axis, v in
                                       zip(vocabulary.AXES, per_min)}}


def turn_to_next_target(m, records):
    """Take the next target; CPU 22 forms the turn to it from the target held.

    The turn is formed from programmed angles only, all measured from the
    first target's reference attitude (``m.program_target()`` keeps it for
    ``sequencer.between_targets = "direct"``): the attitude the computer
    holds, the first target's angles and the turns flown since
    (``m.held_axes``), and the next target's angles
    (:func:`allsky.computer.targeting.turn_to_deg`). Register 24 gets the
    turn's roll; its yaw word stays zero while the vehicle rolls, so that
    CPU 22 holds the yaw where it is (:func:`load_turn_yaw` loads the yaw
    once the roll has settled).

    An action: ``m`` is the mission (:class:`~allsky.sequencer.host.Host`),
    ``records`` the samples the mode's legs kept, by name (not read).
    """
    held = (np.asarray(m.held_axes, dtype=float) if m.held_axes is not None else
            targeting.attitude_after(m.programmed_roll_deg, m.programmed_yaw_deg))
    m.next_target()
    m.program_target()
    roll, yaw, after = targeting.turn_to_deg(held, m.programmed_roll_deg, m.programmed_yaw_deg)
    m.turn_roll_deg, m.turn_yaw_deg = roll, yaw
    m.held_axes = after.tolist()
    m.board.load_word24(roll, 0.0)


def load_turn_yaw(m, records):
    """Load register 24's yaw word with the yaw of the turn to the next target.

    An action: ``m`` is the mission (:class:`~allsky.sequencer.host.Host`),
    ``records`` the samples the mode's legs kept, by name (not read).
    """
    m.board.load_word24(yaw_deg=m.turn_yaw_deg)


def next_target(m, records):
    """Take the next target of ``target.sequence``; Mode 6-1 loads its angles.

    The mission closes the record of the target just flown and clears the
    programmed angles and the hold's measurements for the next
    (``m.next_target()``); the calibration is left as it is.

    An action: ``m`` is the mission (:class:`~allsky.sequencer.host.Host`),
    ``records`` the samples the mode's legs kept, by name (not read).
    """
    m.next_target()


_FUNCTIONS = {f.__name__: f for f in (
    clear_drift_counters, clear_counters, roll_rate_positive, yaw_rate_positive,
    calibration_sequencer, withhold_calibration, load_register_24, start_roll_computation,
    roll_rate_toward_target, preset_counters, start_yaw_computation, yaw_rate_toward_target,
    record_hold_start, measure_hold, next_target, dither_analysis, check_turn,
    turn_to_next_target, load_turn_yaw)}
#: Action name -> function, for each action the vocabulary names (its words are
#: :data:`allsky.vocabulary.ACTIONS`).
ACTIONS = {name: _FUNCTIONS[name] for name in vocabulary.ACTIONS}
