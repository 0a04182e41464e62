"""The mode table of master sequencer 20: every mode's steps, as data.

Each :class:`Mode` is a name, the code the telemetry writes for it, a
title and an ordered tuple of steps (SPEC section 4, patent US 4,012,018
Modes 1 to 6-2, what may follow 6-2: the hold on target and the move to a
next target, and the dither comparison mode of seed 000):

* :class:`Operate`: close and open switches of the bank, by number
  (coupled pairs S16+S18, S17+S19 named together);
* :class:`Wait`: a leg of the frame loop: what the sequencer waits for,
  the program computer 111 runs meanwhile, the kind of watch, the watched
  signals by name, the blanking, the hold and the abort text on timeout;
* :class:`Do`: a named action, for what is neither a switch nor a leg
  (clear counters 14/16/18, set a rate-command direction, calibration
  sequencer 19, load register 24, preset counters 16/18, the dither
  analysis ...), flown always or only when the scenario asks for it
  (:data:`CONDITIONS`: the turn check).

A ground command (:mod:`allsky.sequencer.ground`) may end the mode being
flown at a frame boundary; the mode's ``on_command`` steps (switches and
actions, no wait) are flown then (the hold measures itself).

:func:`allsky.sequencer.master_sequencer.run_mode` walks a mode's steps;
the actions are the functions of
:data:`allsky.sequencer.master_sequencer.ACTIONS`. The documentation's
switch table and the displays read their mode names, codes and titles
from here, so a mode is written once. Adding a step is a table edit;
adding an action is one entry in :data:`ACTIONS` and one function.

The words below name durations (:data:`DURATIONS`), programs, watches and
signals; each maps to the frame loop's vocabulary
(:mod:`allsky.sequencer.legs`) and, for durations, to scenario keys.
"""

import math
from collections.abc import Callable
from typing import NamedTuple

from allsky import vocabulary
from allsky.config.schema import HOLD_TIMEOUT_ALLOWANCE_S, MISSION_MAX_S
from allsky.hardware import switch_bank
from allsky.sequencer import legs


class Operate(NamedTuple):
    """Close and open switches of the bank, by number (coupled pairs named together)."""

    close: tuple = ()  #: numbers of the switches closed
    open_: tuple = ()  #: numbers of the switches opened


class Wait(NamedTuple):
    """One leg: computer 111 runs ``program`` until the watch sees its condition.

    The watch is master sequencer 20's.
    """

    what: str  #: what is awaited, in words (abort messages and the step display show it)
    program: str  #: key of :data:`PROGRAMS`
    watch: str  #: key of :data:`WATCHES`
    signals: tuple = ()  #: keys of :data:`SIGNALS`: all settle, or the one handed over
    blank: str = ""  #: key of :data:`DURATIONS`: the watched signal is ignored this long
    hold: str = "settle"  #: key of :data:`DURATIONS`: settle time, or the elapsed time
    on_timeout: str = ""  #: abort reason on timeout ("" = "<what> not achieved")
    record: str = ""  #: key of :data:`RECORDS`: keep the leg's samples under this name
    #: True: the settle time goes on from the previous wait's (which timed ``signals``)
    carry_settle: bool = False
    #: keys of :data:`RETRIES`: what the sequencer may do once, with ``sequencer.recovery``,
    #: when the leg fails (the first rule for the failure applies)
    retry: tuple = ()


class Do(NamedTuple):
    """A named action (key of :data:`ACTIONS`) with its arguments."""

    action: str  #: key of :data:`ACTIONS` (and of the master sequencer's functions)
    args: tuple = ()  #: passed to the action after ``(m, records)`` (an axis, for some)
    #: key of :data:`CONDITIONS`: the action is flown only when the scenario asks for it
    #: ("" = always); skipped, it leaves no trace
    when: str = ""
    #: keys of :data:`RETRIES`: what the sequencer may do once, with ``sequencer.recovery``,
    #: when the action refuses to go on (as a wait's)
    retry: tuple = ()


class Retry(NamedTuple):
    """A recovery: what master sequencer 20 does once when a leg fails, then goes on.

    Flown only with ``sequencer.recovery = true`` (beyond the patent): the
    ``steps`` in order, then the mode from step ``resume`` (None: the failed
    wait again; 0: the mode from its start), its deadline moved on by
    ``extend``.
    """

    text: str  #: what is done, in words (step display, abort reasons, documentation)
    on: tuple  #: failures it answers: "timeout", "Sun lost", "star lost" (:data:`FAILURES`)
    steps: tuple  #: :class:`Operate`, :class:`Wait` and :class:`Do` flown first
    extend: str  #: key of :data:`DURATIONS`: the mode's deadline moves on by this
    resume: int | None = None  #: step of the mode to go on from; None = the failed wait
    #: key of :data:`GUARDS`: what must hold for a retry to help ("" = nothing); when it
    #: does not, the sequencer does not retry and its abort says why
    needs: str = ""


class Mode(NamedTuple):
    """One mode of the master sequencer."""

    name: str  #: as plans and the timeline name it ("6-1")
    code: float  #: written in the telemetry's mode column
    title: str  #: what the mode does, for displays
    steps: tuple  #: :class:`Operate`, :class:`Wait` and :class:`Do`, in order
    exit: str  #: exit text; ``{cfg.section.key}`` fields are filled from the scenario
    timeout: str = "mode timeout"  #: key of :data:`DURATIONS`: the time the mode is allowed
    #: :class:`Operate` and :class:`Do` steps flown when a ground command ends the mode
    on_command: tuple = ()


def _mode(name, steps, exit, timeout="mode timeout", on_command=()) -> Mode:
    """A :class:`Mode` with the code and title the vocabulary gives its name."""
    return Mode(name, vocabulary.MODE_CODE[name], vocabulary.MODE_TITLE[name], steps, exit,
                timeout, on_command)


class Term(NamedTuple):
    """A word of the table and the frame loop's code for it."""

    code: int  #: legs.PROGRAM_*, WATCH_* or SIG_*
    text: str  #: meaning, for the documentation


class Duration(NamedTuple):
    """A named duration of the table, taken from the scenario."""

    text: str  #: meaning, with the scenario keys it comes from
    seconds: Callable  #: ``seconds(cfg, mode_name) -> float`` [s]


#: Computer programs a leg can run.
PROGRAMS = {
    "none": Term(legs.PROGRAM_NONE, "none: the switched optical and rate loops hold"),
    "sun acquisition": Term(legs.PROGRAM_MODE1, "the Mode 1 sun-acquisition controller"),
    "target roll": Term(legs.PROGRAM_TARGET_ROLL, "CPU 22 computes the roll error "
                        "(counter 14 -> register 25)"),
    "target": Term(legs.PROGRAM_TARGET, "CPU 22 computes the roll, pitch and yaw errors, "
                   "S7/S8 stepping over the three axes"),
    "dither": Term(legs.PROGRAM_DITHER, "the dither generator adds A sin(wt) to the hold's "
                   "attitude command, and its feed-forward"),
    "target dither": Term(legs.PROGRAM_TARGET_DITHER, "the dither added to the target hold "
                          "of Mode 6-2"),
}
#: What ends a leg.
WATCHES = {
    "settle": Term(legs.WATCH_SETTLE, "every watched signal under "
                   "`sequencer.settle_threshold_arcsec` for the hold"),
    "handover": Term(legs.WATCH_HANDOVER, "the watched signal inside "
                     "`sequencer.handover_arcsec` (its Sun or star present), after the "
                     "blanking"),
    "elapsed": Term(legs.WATCH_ELAPSED, "the hold has elapsed"),
}
#: Signals the sequencer watches.
SIGNALS = {
    "sun pitch": Term(legs.SIG_SUN_PITCH, "sun sensor 104 pitch output"),
    "sun yaw": Term(legs.SIG_SUN_YAW, "sun sensor 104 yaw output"),
    "tracker yaw": Term(legs.SIG_TRACKER_YAW, "star tracker 105 yaw output"),
    "tracker pitch": Term(legs.SIG_TRACKER_PITCH, "star tracker 105 pitch output"),
    "roll error": Term(legs.SIG_ERROR_ROLL, "roll error computed by CPU 22"),
    "pitch error": Term(legs.SIG_ERROR_PITCH, "pitch error computed by CPU 22"),
    "yaw error": Term(legs.SIG_ERROR_YAW, "yaw error computed by CPU 22"),
}
#: The optical errors of the Sun-and-star hold.
OPTICAL = ("sun pitch", "sun yaw", "tracker yaw")

#: [s] allowed to the dither mode after its record, for the settling that follows.
DITHER_SETTLE_ALLOWANCE_S = 300.0


def _dither_record_s(cfg, mode) -> float:
    d = cfg.dither
    return d.lead_in_s + d.record_s + 2 * d.sample_s


def _mode_timeout_s(cfg, mode) -> float:
    return cfg.sequencer.timeout_s[mode]


def _dither_timeout_s(cfg, mode) -> float:
    d = cfg.dither
    return d.lead_in_s + d.record_s + DITHER_SETTLE_ALLOWANCE_S


def _hold_s(cfg, mode) -> float:
    return cfg.target.hold_s


def _hold_timeout_s(cfg, mode) -> float:
    return cfg.target.hold_s + HOLD_TIMEOUT_ALLOWANCE_S


def _no_time_s(cfg, mode) -> float:
    return 0.0


def _until_commanded_s(cfg, mode) -> float:
    return MISSION_MAX_S


def _until_commanded_timeout_s(cfg, mode) -> float:
    return MISSION_MAX_S + HOLD_TIMEOUT_ALLOWANCE_S


def _revolution_s(cfg, mode) -> float:
    return 360.0 / cfg.electronics.rate_command_deg_s


def _direct_s(cfg, mode) -> float:
    return cfg.sequencer.timeout_s["6-1"]


def _sun_and_star_again_s(cfg, mode) -> float:
    t = cfg.sequencer.timeout_s
    return t["1"] + t["2"] + t[mode]


#: Durations the table names.
DURATIONS = {
    "settle": Duration("`sequencer.settle_time_s`",
                       lambda cfg, mode: cfg.sequencer.settle_time_s),
    "drift count": Duration("`sequencer.drift_count_s`",
                            lambda cfg, mode: cfg.sequencer.drift_count_s),
    "blanking": Duration("`sequencer.tracker_blanking_s`",
                         lambda cfg, mode: cfg.sequencer.tracker_blanking_s),
    "dither record": Duration("`dither.lead_in_s` + `dither.record_s` + 2 `dither.sample_s`",
                              _dither_record_s),
    "mode timeout": Duration("`sequencer.timeout_s` of the mode", _mode_timeout_s),
    "dither timeout": Duration(f"`dither.lead_in_s` + `dither.record_s` + "
                               f"{DITHER_SETTLE_ALLOWANCE_S:g} s", _dither_timeout_s),
    "hold": Duration("`target.hold_s`", _hold_s),
    "hold timeout": Duration(f"`target.hold_s` + {HOLD_TIMEOUT_ALLOWANCE_S:g} s",
                             _hold_timeout_s),
    "no time": Duration("none: the mode flies no leg", _no_time_s),
    "until commanded": Duration(f"until a ground command ends it, at most {MISSION_MAX_S:g} s "
                                "(a day: the longest mission)", _until_commanded_s),
    "until commanded timeout": Duration(f"{MISSION_MAX_S:g} s + "
                                        f"{HOLD_TIMEOUT_ALLOWANCE_S:g} s",
                                        _until_commanded_timeout_s),
    "target roll timeout": Duration("`sequencer.timeout_s` of Mode 6-1", _direct_s),
    "revolution": Duration("one revolution at the commanded rate: 360 deg / "
                           "`electronics.rate_command_deg_s`", _revolution_s),
    "Sun acquisition": Duration("`sequencer.timeout_s` of Mode 1",
                                lambda cfg, mode: cfg.sequencer.timeout_s["1"]),
    "restart": Duration("`sequencer.timeout_s` of Modes 1, 2 and the mode",
                        _sun_and_star_again_s),
}


def _dither_rows(cfg) -> int:
    d = cfg.dither
    return math.ceil((d.lead_in_s + d.record_s) / d.sample_s) + 4


#: Samples a leg can keep for an action: name -> rows needed, from the scenario.
RECORDS = {"dither record": _dither_rows}

#: Named actions, in words ("{0}" is the first argument): the vocabulary's.
ACTIONS = vocabulary.ACTIONS


def action_text(step: Do) -> str:
    """The words of action ``step`` (a :class:`Do`), its arguments filled in."""
    return ACTIONS[step.action].format(*step.args)


#: Failures a recovery can answer: the exits of the frame loop's watch, and a turn the
#: turn check refused (:func:`allsky.sequencer.master_sequencer.check_turn`).
FAILURES = ("timeout", "Sun lost", "star lost", "turn refused")

#: Steps flown only when the scenario asks for them: name -> (meaning, ``applies(cfg)``).
CONDITIONS = {
    "turn check": ("`sequencer.turn_check_ppm` > 0",
                   lambda cfg: cfg.sequencer.turn_check_ppm > 0),
}
#: What must hold for a recovery to help (:attr:`Retry.needs`), in words; the tests are
#: :data:`allsky.sequencer.master_sequencer.GUARDS`. Each holds when the turn check is off.
GUARDS = {
    "roll stopped at a whole turn": (
        "counter 14 holds whole turns to within the tracker's narrow half-field "
        "(`star_tracker.fov_narrow_half_deg`, and `sequencer.turn_check_ppm`): the star "
        "should still be in the slit, so it vanished and may be met again; beyond, the "
        "vehicle rolled on and carried it away, which one more roll cannot mend"),
    "yaw stopped at a whole turn": (
        "counter 18 holds whole turns to within the sun sensor's presence cone "
        "(`sun_sensor.presence_half_angle_deg`, and `sequencer.turn_check_ppm`): the Sun "
        "should still be in view; beyond, the vehicle yawed on and carried it away"),
}

# Recoveries (beyond the patent): steps a 1970s sequencer could fly again from wherever the
# vehicle is. The drift calibration (S1-S3, drift DACs 7/9/11) is kept through them.
#: Mode 1's leg again: every loop switch but S1-S3 open, the Sun acquired, S14/S15 closed.
SUN_AGAIN = (
    Operate(open_=(4, 5, 6, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18, 19)),
    Wait("Sun acquired again and settled", "sun acquisition", "settle", ("sun pitch", "sun yaw")),
    Operate(close=(14, 15)),
)
#: Mode 2's search again: roll at the commanded rate until a star is in the window, lock.
STAR_SEARCH = (
    Do("roll_rate_positive"),
    Operate(open_=(12,), close=(16, 18)),
    Wait("star in the magnitude window again", "none", "handover", ("tracker yaw",)),
    Operate(open_=(16, 18), close=(12,)),
)
#: Mode 2's lock again, after :data:`STAR_SEARCH`.
STAR_LOCK = Wait("locked on Sun and star again", "none", "settle", OPTICAL)
#: Recovery name -> :class:`Retry`.
RETRIES = {
    "Sun acquisition again": Retry(
        "go on acquiring the Sun for one more Mode 1 timeout", ("timeout",), (), "Sun acquisition"),
    "search on": Retry("turn on for one more revolution", ("timeout",), (), "revolution"),
    "star search again": Retry(
        "roll for the star again, one more revolution allowed", ("star lost",),
        STAR_SEARCH, "revolution"),
    "Sun again, mode again": Retry(
        "acquire the Sun again with Mode 1's leg, then fly the mode from its start",
        ("Sun lost",), SUN_AGAIN, "restart", resume=0),
    "Sun and star again, mode again": Retry(
        "acquire the Sun with Mode 1's leg and the star with Mode 2's search again, then fly "
        "the mode from its start", ("Sun lost",),
        (*SUN_AGAIN, *STAR_SEARCH, STAR_LOCK), "restart", resume=0),
    "Sun and star again, Mode 5 again": Retry(
        "acquire the Sun with Mode 1's leg and the star with Mode 2's search again, then fly "
        "the yaw calibration from its start", ("Sun lost", "star lost"),
        (*SUN_AGAIN, *STAR_SEARCH, STAR_LOCK), "restart", resume=0),
    "star again, count again": Retry(
        "roll for the star again with S1-S6 open, lock, and count the drift from the start",
        ("star lost",), (Operate(open_=(1, 2, 3, 4, 5, 6)), *STAR_SEARCH, STAR_LOCK),
        "restart", resume=0),
    "Sun and star again, count again": Retry(
        "acquire the Sun and the star again with S1-S6 open, then count the drift anew",
        ("Sun lost",), (Operate(open_=(1, 2, 3)), *SUN_AGAIN, *STAR_SEARCH, STAR_LOCK),
        "restart", resume=0),
    "roll again": Retry(
        "roll on for one more revolution to the star, calibration sequencer 19 counting two "
        "turns", ("star lost",),
        (Operate(open_=(12,), close=(16, 18)),
         Wait("star re-acquired after one more roll", "none", "handover", ("tracker yaw",),
              blank="blanking"),
         Operate(open_=(16, 18), close=(12,))), "revolution",
        needs="roll stopped at a whole turn"),
    "yaw again": Retry(
        "yaw on for one more revolution to the Sun, calibration sequencer 19 counting two "
        "turns", ("Sun lost",),
        (Operate(open_=(15,), close=(17, 19)),
         Wait("Sun re-acquired in yaw after one more yaw", "none", "handover", ("sun yaw",),
              blank="blanking"),
         Operate(open_=(17, 19), close=(15,))), "revolution",
        needs="yaw stopped at a whole turn"),
    # The turn is checked settled on the star (the Sun): the roll (yaw) starts again.
    "roll on to the next star": Retry(
        "roll on past the refused star to the next one, settle and check the turn again",
        ("turn refused",),
        (Operate(open_=(12,), close=(16, 18)),
         Wait("next star in the slit after the refused one", "none", "handover",
              ("tracker yaw",), blank="blanking"),
         Operate(open_=(16, 18), close=(12,)),
         Wait("settled on Sun and the next star", "none", "settle", OPTICAL)),
        "revolution", resume=6),
    "yaw on to the Sun": Retry(
        "yaw on past the refused re-acquisition to the Sun's next, settle and check the turn "
        "again", ("turn refused",),
        (Operate(open_=(15,), close=(17, 19)),
         Wait("Sun in yaw again after the refused re-acquisition", "none", "handover",
              ("sun yaw",), blank="blanking"),
         Operate(open_=(17, 19), close=(15,)),
         Wait("settled on star (yaw, pitch) and the Sun's next yaw", "none", "settle",
              ("tracker yaw", "tracker pitch", "sun yaw"))),
        "revolution", resume=8),
}


def retry_text(step) -> str:
    """The recoveries of a wait or an action (``step``), in words ("" for none).

    A recovery with a guard (:attr:`Retry.needs`) says when it is flown.
    """
    def one(r):
        rule = RETRIES[r]
        guard = (f" (with the turn check, only if {rule.needs}: {GUARDS[rule.needs]})"
                 if rule.needs else "")
        return f"on {' or '.join(rule.on)}: {rule.text}{guard}"
    return "; ".join(one(r) for r in step.retry)


#: The mode table: the patent's six modes (SPEC section 4) and the hold after them, then
#: the comparison mode.
MODE_TABLE = (
    _mode("1", (
        Wait("sun acquired and settled", "sun acquisition", "settle",
             ("sun pitch", "sun yaw"), retry=("Sun acquisition again",)),
        Operate(close=(14, 15)),
    ), "sun pitch and yaw settled; S14, S15 closed"),
    _mode("2", (
        Do("roll_rate_positive"),
        Operate(close=(16, 18)),
        Wait("star in the magnitude window", "none", "handover", ("tracker yaw",),
             on_timeout="no star in the tracker's magnitude window during the acquisition "
                        "roll", retry=("search on", "Sun again, mode again")),
        Operate(open_=(16, 18), close=(12,)),
        Wait("locked on Sun and star", "none", "settle", OPTICAL,
             retry=("star search again", "Sun again, mode again")),
    ), "tracker yaw and sun pitch/yaw settled"),
    _mode("3", (
        Do("clear_drift_counters"),
        Operate(close=(4, 5, 6)),
        # Patent: Mode 4 starts when, S1-S3 closed, the optical errors "have remained
        # less than 50 arc-seconds for at least 10 seconds": timed through the count.
        Wait("drift count", "none", "elapsed", OPTICAL, hold="drift count",
             retry=("star again, count again", "Sun and star again, count again")),
        Operate(open_=(4, 5, 6), close=(1, 2, 3)),
        Wait("optical errors have remained settled", "none", "settle", OPTICAL,
             carry_settle=True,
             retry=("star again, count again", "Sun and star again, count again")),
    ), "drift counted over {cfg.sequencer.drift_count_s:g} s; S1-S3 closed"),
    _mode("4", (
        Do("clear_counters"),
        Do("roll_rate_positive"),
        Operate(open_=(12,), close=(16, 18)),
        Wait("star re-acquired after a full roll", "none", "handover", ("tracker yaw",),
             blank="blanking",
             on_timeout="star not re-acquired after the calibration roll",
             retry=("search on", "Sun and star again, mode again")),
        Operate(open_=(16, 18), close=(12,)),
        Wait("settled on Sun and star", "none", "settle", OPTICAL,
             retry=("roll again", "Sun and star again, mode again")),
        Do("check_turn", ("roll",), when="turn check", retry=("roll on to the next star",)),
        Do("calibration_sequencer", ("roll",)),
    ), "roll scale factor and roll cross-coupling stored in register 23"),
    _mode("5", (
        Do("clear_counters"),
        Do("yaw_rate_positive"),
        Operate(close=(13,), open_=(14,)),
        Wait("tracker pitch nulled", "none", "settle", ("tracker pitch",),
             retry=("Sun and star again, Mode 5 again",)),
        Operate(open_=(15,), close=(17, 19)),
        Wait("Sun re-acquired in yaw after a full yaw", "none", "handover", ("sun yaw",),
             blank="blanking", on_timeout="Sun not re-acquired after the calibration yaw",
             retry=("search on", "Sun and star again, Mode 5 again")),
        Operate(open_=(17, 19), close=(15,)),
        Wait("settled on star (yaw, pitch) and Sun yaw", "none", "settle",
             ("tracker yaw", "tracker pitch", "sun yaw"),
             retry=("yaw again", "Sun and star again, Mode 5 again")),
        Do("check_turn", ("yaw",), when="turn check", retry=("yaw on to the Sun",)),
        Operate(close=(14,), open_=(13,)),
        Wait("pitched back, settled on Sun and star", "none", "settle", OPTICAL,
             retry=("Sun and star again, Mode 5 again",)),
        Do("calibration_sequencer", ("yaw",)),
    ), "yaw scale factor and yaw cross-coupling stored in register 23"),
    _mode("6-1", (
        Do("withhold_calibration"),
        Do("load_register_24"),
        Do("clear_counters"),
        Do("start_roll_computation"),
        Do("roll_rate_toward_target"),
        Operate(open_=(12,), close=(16, 18)),
        Wait("roll error inside the hand-over threshold", "target roll", "handover",
             ("roll error",), retry=("Sun and star again, mode again",)),
        Operate(open_=(16, 18), close=(9,)),
        Wait("roll error and Sun errors settled", "target roll", "settle",
             ("roll error", "sun pitch", "sun yaw"), retry=("Sun and star again, mode again",)),
        Do("preset_counters"),
    ), "roll settled; pitch and yaw counters preset"),
    _mode("6-2", (
        Do("start_yaw_computation"),
        Do("yaw_rate_toward_target"),
        Operate(open_=(14, 15), close=(17, 19, 10)),
        Wait("yaw error inside the hand-over threshold", "target", "handover", ("yaw error",)),
        Operate(open_=(17, 19), close=(11,)),
        Wait("roll, pitch and yaw errors settled", "target", "settle",
             ("roll error", "pitch error", "yaw error")),
    ), "on target: computed errors settled"),
    # After 6-2 the master sequencer may hold the target for any time: CPU 22 keeps forming
    # the errors from counters 14/16/18, S14/S15 stay open, so the gyros alone hold it.
    _mode("hold", (
        Do("record_hold_start"),
        Wait("hold on target elapsed", "target", "elapsed", hold="hold"),
        Do("measure_hold"),
    ), "held on target for {cfg.target.hold_s:g} s on the gyros", timeout="hold timeout",
        on_command=(Do("measure_hold"),)),
    # Or it may move to a new target with new programmed angles. Those angles are measured
    # from the Sun-star reference attitude, so the vehicle first goes back to it: the Sun
    # (Mode 1) and the star (Mode 2), calibration kept; or it recycles through every mode.
    # Neither mode flies a leg: each sets the bank for the modes that follow (BETWEEN_TARGETS).
    _mode("reacquire", (
        Do("next_target"),
        Operate(open_=(9, 10, 11, 12, 13, 14, 15, 16, 17, 18, 19)),
    ), "next target; S1-S3 stay closed (drift DACs 7/9/11 and register 23 kept)",
        timeout="no time"),
    _mode("recycle", (
        Do("next_target"),
        Operate(open_=(1, 2, 3, 4, 5, 6, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18, 19)),
    ), "next target; every switch open, as at ejection", timeout="no time"),
    # Or the new angles are the roll and yaw from the target held to the next, flown from
    # where the vehicle is on the gyros alone (the patent's third reading, beyond the two
    # above): the roll with CPU 22 holding pitch and yaw (S10, S11), then Mode 6-2's yaw.
    _mode("direct", (
        Do("turn_to_next_target"),
        Do("clear_counters"),
        Do("start_roll_computation"),
        Do("roll_rate_toward_target"),
        Operate(open_=(9,), close=(16, 18)),
        Wait("roll error inside the hand-over threshold", "target", "handover",
             ("roll error",)),
        Operate(open_=(16, 18), close=(9,)),
        Wait("roll, pitch and yaw errors settled", "target", "settle",
             ("roll error", "pitch error", "yaw error")),
        Do("load_turn_yaw"),
        Operate(open_=(11,)),
    ), "rolled toward the next target on the gyros; register 24 holds the turn's yaw",
        timeout="target roll timeout"),
    # Ground commands (allsky.sequencer.ground): the hold on target a command ends, and the
    # way back to the references for the target being flown before its Mode 6 begins (from
    # Mode 6 on, a command flies the target again through "reacquire" or "recycle" above).
    _mode("standby", (
        Do("record_hold_start"),
        Wait("a ground command", "target", "elapsed", hold="until commanded"),
        Do("measure_hold"),
    ), "held on target on the gyros until a ground command", timeout="until commanded timeout",
        on_command=(Do("measure_hold"),)),
    _mode("references", (
        Operate(open_=(4, 5, 6, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18, 19)),
    ), "S4-S6 and S9-S19 open; S1-S3 as they were (drift DACs 7/9/11 and register 23 kept)",
        timeout="no time"),
    _mode("restart", (
        Operate(open_=(1, 2, 3, 4, 5, 6, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18, 19)),
    ), "every switch open, as at ejection", timeout="no time"),
    _mode("dither", (
        Wait("dither record complete", "dither", "elapsed", hold="dither record",
             record="dither record"),
        Wait("optical errors settled after the dither", "none", "settle", OPTICAL),
        Do("dither_analysis"),
    ), ("dither record of {cfg.dither.record_s:g} s analysed ({cfg.dither.estimator} "
        "estimator, {cfg.dither.detector} detector); results in register 23"),
        timeout="dither timeout"),
)
#: Mode name -> its :class:`Mode`.
BY_NAME = {mode.name: mode for mode in MODE_TABLE}
#: Mode name -> telemetry code.
MODE_CODE = {mode.name: mode.code for mode in MODE_TABLE}
#: Mode name -> title, for displays.
MODE_TITLE = {mode.name: mode.title for mode in MODE_TABLE}

#: The patent's mission: Modes 1 to 6-2.
LEGACY_PLAN = vocabulary.PATENT_MODES
#: The comparison mission: the dither calibration in place of Modes 4 and 5.
DITHER_PLAN = ("1", "2", "3", "dither", "6-1", "6-2")
#: Plans by the name ``--plan`` takes.
PLANS = {"legacy": LEGACY_PLAN, "dither": DITHER_PLAN}
#: Flown after a plan when the scenario asks for a hold (``target.hold_s`` > 0).
HOLD_MODE = "hold"
#: The modes that fly Mode 6 to a target once the vehicle is back on its references.
TARGET_MODES = ("6-1", "6-2")
#: Modes flown before Mode 6-1 for each target after the first, by
#: ``sequencer.between_targets``: "reacquire" goes back to the Sun and the star (Modes 1
#: and 2); "recycle" flies every mode of the plan before 6-1 again (None: the plan's);
#: "direct" flies its own roll in place of Mode 6-1 (:data:`DIRECT_REPLACES`).
BETWEEN_TARGETS = {"reacquire": ("reacquire", "1", "2"), "recycle": ("recycle", None),
                   "direct": ("direct",)}
#: The move to a next target that replaces Mode 6-1 (its roll flown on the gyros).
DIRECT_REPLACES = {"direct": "6-1"}


def with_hold(plan, cfg) -> tuple:
    """``plan`` with the hold on target appended if ``cfg.target.hold_s`` > 0.

    ``plan`` is a sequence of mode names, ``cfg`` the scenario. A plan that
    already ends with the hold, or a scenario without one, is returned
    unchanged, so a plan given in full is flown as given.
    """
    plan = tuple(plan)
    if cfg.target.hold_s > 0 and plan[-1:] != (HOLD_MODE,):
        return (*plan, HOLD_MODE)
    return plan


def next_target_modes(plan, how) -> tuple:
    """Modes flown for each target after the first: ``how``, then 6-1 and 6-2.

    ``how`` is "reacquire", "recycle" or "direct" (:data:`BETWEEN_TARGETS`).

    ``plan`` is the plan flown for the first target (without the hold); with
    ``how = "recycle"`` its modes before 6-1 are flown again; with "direct"
    the move's own roll takes 6-1's place.
    """
    plan = tuple(m for m in plan if m != HOLD_MODE)
    first_6 = plan.index(TARGET_MODES[0])
    before = []
    for name in BETWEEN_TARGETS[how]:
        before += plan[:first_6] if name is None else [name]
    after = plan[first_6:]
    if how in DIRECT_REPLACES:
        after = tuple(m for m in after if m != DIRECT_REPLACES[how])
    return (*before, *after)


def target_count(cfg) -> int:
    """How many targets scenario ``cfg`` flies: ``target.sequence``'s length, else 1."""
    return len(cfg.target.sequence) if cfg.target.sequence is not None else 1


def mission_plan(plan, cfg) -> tuple:
    """Every mode a mission flies: ``plan`` for the first target, then the others.

    ``plan`` is a sequence of mode names, ``cfg`` the scenario. The hold
    follows each target's 6-2 when ``target.hold_s`` > 0 (:func:`with_hold`);
    each target after the first of ``target.sequence`` is flown as
    :func:`next_target_modes` says for ``sequencer.between_targets``. A plan
    that already holds a move to a next target is returned as given.
    """
    first = with_hold(plan, cfg)
    n = target_count(cfg)
    if n == 1 or TARGET_MODES[0] not in first or any(m in BETWEEN_TARGETS for m in first):
        return first
    further = with_hold(next_target_modes(plan, cfg.sequencer.between_targets), cfg)
    return first + further * (n - 1)


#: The programs in which CPU 22 forms attitude errors (registers 25-27 in use).
CPU_PROGRAMS = ("target roll", "target", "target dither")


def cpu_modes(table=MODE_TABLE) -> tuple:
    """Names of the modes in which CPU 22 forms attitude errors (its program runs).

    ``table`` is the mode table searched (:class:`Mode` entries).
    """
    return tuple(m.name for m in table if any(
        isinstance(s, Wait) and s.program in CPU_PROGRAMS for s in m.steps))


def signal_mask(signals) -> int:
    """Settle mask of the frame loop: bit ``SIG_*`` set for each named signal.

    ``signals`` are keys of :data:`SIGNALS`.
    """
    mask = 0
    for name in signals:
        mask |= 1 << SIGNALS[name].code
    return mask


def timeout_s(cfg, name) -> float:
    """Time allowed to mode ``name`` [s] under scenario ``cfg``."""
    mode = BY_NAME[name]
    return float(DURATIONS[mode.timeout].seconds(cfg, name))


def closed_after(plan) -> dict:
    """Mode name -> switches closed at its end, flying ``plan`` from an all-open bank.

    Folds the :class:`Operate` steps only, on the nominal path (the
    calibration applied; :func:`allsky.sequencer.master_sequencer.withhold_calibration`
    would open S1-S3 at the start of Mode 6-1).
    """
    bank = switch_bank.new_bank()
    out = {}
    for name in plan:
        for step in BY_NAME[name].steps:
            if isinstance(step, Operate):
                switch_bank.operate(bank, close=step.close, open_=step.open_)
        out[name] = switch_bank.closed(bank)
    return out


def check(table=MODE_TABLE) -> None:
    """Raise ValueError unless every word of ``table`` is in the vocabulary.

    A settle watch needs at least one signal, a hand-over exactly one (an
    elapsed wait may time any); a wait carries a settle time on only after a
    wait that timed the same signals; names, codes and plans must be unique
    and known; a recovery (:data:`RETRIES`) answers known failures, flies
    valid steps and goes on from a step of the mode.
    """
    def fail(mode, msg):
        raise ValueError(f"mode table, Mode {mode.name}: {msg}")

    if len({m.name for m in table}) != len(table) or len({m.code for m in table}) != len(table):
        raise ValueError("mode table: mode names and codes must be unique")
    for mode in table:
        if mode.timeout not in DURATIONS:
            fail(mode, f"unknown timeout {mode.timeout!r}")
        _check_steps(mode, mode.steps, fail)
        if any(isinstance(s, Wait) for s in mode.on_command):
            fail(mode, "the steps flown when a command ends the mode must not wait")
        _check_steps(mode, mode.on_command, fail)
        for i, step in enumerate(mode.steps):
            what = getattr(step, "what", None) or getattr(step, "action", "")
            for key in getattr(step, "retry", ()):
                rule = RETRIES.get(key)
                if rule is None:
                    fail(mode, f"{what}: unknown recovery {key!r}")
                if not rule.on or not set(rule.on) <= set(FAILURES) \
                        or rule.extend not in DURATIONS or (rule.needs and rule.needs
                                                            not in GUARDS) \
                        or not (rule.resume is None or 0 <= rule.resume < len(mode.steps)):
                    fail(mode, f"{what}: recovery {key!r} is not a valid rule")
                if rule.resume is None and not isinstance(step, Wait):
                    fail(mode, f"{what}: recovery {key!r} must name the step to go on from")
                if rule.resume is not None and rule.resume > i:
                    fail(mode, f"{what}: recovery {key!r} goes on from a later step")
                if any(getattr(s, "retry", ()) for s in rule.steps):
                    fail(mode, f"recovery {key!r}: its steps must not recover again")
                _check_steps(mode, rule.steps, fail)
    names = {m.name for m in table}
    for plan in PLANS.values():
        if not set(plan) <= names:
            raise ValueError(f"plan {plan} names modes not in the table")
    if table is MODE_TABLE and tuple(m.name for m in table) != tuple(
            w.name for w in vocabulary.MODES):
        raise ValueError("mode table: its modes must be the vocabulary's, in its order")


def _check_steps(mode, steps, fail) -> None:
    """The checks of :func:`check` on one sequence of steps of ``mode``."""
    previous = None  # the last wait
    for step in steps:
        if isinstance(step, Operate):
            if not (step.close or step.open_):
                fail(mode, "a switch step operates no switch")
        elif isinstance(step, Wait):
            if step.program not in PROGRAMS or step.watch not in WATCHES:
                fail(mode, f"{step.what}: unknown program or watch")
            unknown = [s for s in step.signals if s not in SIGNALS]
            if unknown:
                fail(mode, f"{step.what}: unknown signals {unknown}")
            n = len(step.signals)
            if (step.watch == "settle" and n == 0) or (step.watch == "handover" and n != 1):
                fail(mode, f"{step.what}: {n} signals for a {step.watch} watch")
            if step.carry_settle and not (
                    step.watch == "settle" and previous is not None
                    and previous.watch != "handover" and previous.signals == step.signals):
                fail(mode, f"{step.what}: carries a settle time no wait before timed")
            previous = step
            for d in (step.blank, step.hold):
                if d and d not in DURATIONS:
                    fail(mode, f"{step.what}: unknown duration {d!r}")
            if step.record and step.record not in RECORDS:
                fail(mode, f"{step.what}: unknown record {step.record!r}")
        elif isinstance(step, Do):
            if step.action not in ACTIONS:
                fail(mode, f"unknown action {step.action!r}")
            if step.when and step.when not in CONDITIONS:
                fail(mode, f"{step.action}: unknown condition {step.when!r}")
        else:
            fail(mode, f"not a step: {step!r}")


check()
