"""The machine's words, written once: axes, modes, faults, actions, journal kinds.

Configuration (``config``), master sequencer 20 (``sequencer``), the frame
loop and mission (``sim``) and the front ends (``apps``) all name the same
things; each name, its code and its meaning live here, and nowhere else.
The module imports nothing but the standard library, so that validating a
scenario (``allsky config show|check``) starts without NumPy.

* :data:`AXES`: the body axes, x roll, y pitch, z yaw.
* :data:`MODES`: every mode of master sequencer 20, its telemetry code and
  title (the steps of each are the mode table, :mod:`allsky.sequencer.modes`).
* :data:`FAULT_KINDS`: every fault kind of a scenario's ``[[faults]]``: its
  code in the frame loop, the fields it needs and the block it acts on.
* :data:`ACTIONS`: the named actions of the mode table, in words (their
  functions are :data:`allsky.sequencer.master_sequencer.ACTIONS`).
* :data:`EVENT_KINDS` and :data:`SATURATIONS`: what the mission's journal
  records (:mod:`allsky.sim.journal`).
* :data:`GROUND_COMMANDS`: what the ground may command during a flight
  (``allsky serve``, ``allsky run --commands``; :mod:`allsky.sim.commands`).
"""

from typing import NamedTuple

#: Body axes: x roll (the sun sensor's null axis), y pitch, z yaw (the star tracker's).
AXES = ("roll", "pitch", "yaw")
#: Axes whose scale factor the patent's computer calibrates (register 23).
SCALE_FACTOR_AXES = ("roll", "yaw")
#: Cross-coupling factors of register 23, "<turned axis>_into_<axis that counts>".
CROSS_COUPLING_KEYS = ("roll_into_pitch", "roll_into_yaw", "yaw_into_pitch", "yaw_into_roll")


class ModeWord(NamedTuple):
    """A mode's name, telemetry code and title."""

    name: str  #: as plans, the timeline and the journal name it ("6-1")
    code: float  #: written in the telemetry's mode column
    title: str  #: what the mode does, for displays


#: Every mode, in the order the mode table lists them.
MODES = (
    ModeWord("1", 1.0, "Sun orientation"),
    ModeWord("2", 2.0, "Canopus acquisition"),
    ModeWord("3", 3.0, "drift calibration"),
    ModeWord("4", 4.0, "roll calibration, 360 deg roll"),
    ModeWord("5", 5.0, "yaw calibration, 360 deg yaw"),
    ModeWord("6-1", 6.1, "target acquisition, roll"),
    ModeWord("6-2", 6.2, "target acquisition, yaw"),
    ModeWord("hold", 6.3, "hold on target"),
    ModeWord("reacquire", 6.4, "next target: back to the Sun and the star, calibration kept"),
    ModeWord("recycle", 6.5, "next target: every mode again, calibration included"),
    ModeWord("direct", 6.6, "next target: the roll from the target held, on the gyros alone "
                            "(Mode 6-2's yaw follows)"),
    ModeWord("standby", 6.7, "hold on target until a ground command ends the hold"),
    ModeWord("references", 6.8, "back to the Sun and the star by ground command, the target "
                                "and the calibration kept"),
    ModeWord("restart", 6.9, "every mode again by ground command, from an open switch bank, "
                             "the target kept"),
    ModeWord("dither", 7.0, "dither calibration (comparison method)"),
)
#: Mode name -> telemetry code.
MODE_CODE = {m.name: m.code for m in MODES}
#: Mode name -> title.
MODE_TITLE = {m.name: m.title for m in MODES}
#: The patent's six modes (Mode 6 in its two parts), in flight order.
PATENT_MODES = ("1", "2", "3", "4", "5", "6-1", "6-2")


class FaultKind(NamedTuple):
    """A kind of ``[[faults]]`` entry."""

    name: str  #: as the scenario writes it
    code: int  #: in the frame loop's fault arrays (0 is an empty slot)
    fields: tuple  #: the fields it needs beyond the timing, in this order
    blocks: tuple  #: patent numerals of the blocks it acts on ("" for the tank)
    meaning: str  #: what happens, in words
    optional: tuple = ()  #: fields it may have beyond those, in this order


#: Every fault kind (:mod:`allsky.config.faults` validates them, :mod:`allsky.sim.faults`
#: applies them in the frame loop).
FAULT_KINDS = (
    FaultKind("jet_stuck_open", 1, ("axis", "sign"), ("39", "40", "41"),
              "the couple of the axis firing the sign's way (`jets = 2`, the default) or one "
              "jet of it (`jets = 1`) fires whatever its modulator commands", ("jets",)),
    FaultKind("jet_failed_off", 2, ("axis", "sign"), ("39", "40", "41"),
              "a jet of the axis's couple gives no thrust when commanded"),
    FaultKind("gyro_stuck", 3, ("axis",), ("1", "2", "3"),
              "the gyro's output freezes at its value at the onset"),
    FaultKind("gyro_dead", 4, ("axis",), ("1", "2", "3"), "the gyro's output is zero"),
    FaultKind("gyro_bias_step", 5, ("axis", "size_deg_h"), ("1", "2", "3"),
              "the gyro's drift steps by the size"),
    FaultKind("gyro_scale_factor_step", 6, ("axis", "size_ppm"), ("1", "2", "3"),
              "the gyro's scale factor steps by the size"),
    FaultKind("sun_sensor_blind", 7, (), ("104",), "sun sensor 104 sees no Sun"),
    FaultKind("tracker_dropout", 8, (), ("105",), "star tracker 105 sees no star"),
    FaultKind("tracker_stray_light", 9, ("offset_deg",), ("105",),
              "a body-fixed false target (a glint) at the offset in star tracker 105's slit: "
              "tracked instead of the star or, with a magnitude, as bright as that",
              ("magnitude",)),
    FaultKind("wrong_star", 10, ("star",), ("105",),
              "another catalog star passes the tracker's magnitude window"),
    FaultKind("counter_upset", 11, ("register", "bit"), ("13", "14", "15", "16", "17", "18",
                                                        "25", "26", "27"),
              "one bit of a counter or storage register flips, once"),
    FaultKind("propellant_leak", 12, ("rate_kg_s",), ("",),
              "the tank leaks at the rate (at the initial tank pressure; following it on a "
              "blow-down feed), with the given body torque or thrusting from its vent at the "
              "jets' exhaust speed", ("torque_n_m", "vent_position_m", "vent_direction")),
)
#: Fault kind name -> :class:`FaultKind`.
FAULT_KIND = {k.name: k for k in FAULT_KINDS}
#: Fault kind name -> the frame loop's code.
FAULT_CODE = {k.name: k.code for k in FAULT_KINDS}

#: The named actions of the mode table (:class:`allsky.sequencer.modes.Do`), in words
#: ("{0}" is the first argument).
ACTIONS = {
    "clear_drift_counters": "clear drift counters 13, 15, 17",
    "clear_counters": "clear up/down counters 14, 16, 18",
    "roll_rate_positive": "set roll rate-command module 120 to the positive direction",
    "yaw_rate_positive": "set yaw rate-command module 128 to the positive direction",
    "calibration_sequencer": ("calibration sequencer 19: CPU 22 reads counters 14, 16, 18 "
                              "through S7 and stores the {0} scale factor and the {0} "
                              "cross-coupling factors in register 23"),
    "withhold_calibration": ("if the scenario withholds the calibration "
                             "(`calibration.apply = false`): register 23 neutral, S1-S3 "
                             "opened"),
    "load_register_24": ("load register 24 with the programmed roll and yaw angles (computed "
                         "on the ground for the target, if not given)"),
    "start_roll_computation": "clear CPU 22 and compute the first roll error",
    "roll_rate_toward_target": ("set roll rate-command module 120 to the direction of the "
                                "programmed roll"),
    "preset_counters": ("preset counters 16 and 18 so that the corrected pitch and yaw start "
                        "Mode 6-2 at zero"),
    "start_yaw_computation": ("CPU 22 computes the yaw and pitch errors from the preset "
                              "counters"),
    "yaw_rate_toward_target": ("set yaw rate-command module 128 to the direction of the yaw "
                               "error"),
    "check_turn": ("the turn check, settled at the turn's end: refuse the re-acquisition "
                   "unless the {0} counter holds a whole number of turns within "
                   "`sequencer.turn_check_ppm` (one turn unless `sequencer.recovery`)"),
    "record_hold_start": ("note the true attitude and pointing error at the start of the "
                          "hold (for the drift measured at its end)"),
    "measure_hold": ("measure the hold: pointing error at its end and the attitude's drift "
                     "per body axis since its start"),
    "turn_to_next_target": ("take the next target of `target.sequence`; CPU 22 forms the "
                            "roll and yaw from the target held to it from the two targets' "
                            "programmed angles (both from the first target's reference "
                            "attitude) and loads register 24 with the roll, its yaw word "
                            "zero while the vehicle rolls"),
    "load_turn_yaw": "load register 24's yaw word with the yaw of the turn to the next target",
    "next_target": ("take the next target of `target.sequence`: its programmed angles are "
                    "computed when Mode 6-1 loads register 24"),
    "dither_analysis": ("analyse the dither record at each dither frequency; scale factors "
                        "(with `dither.store_cross_coupling`, cross-coupling too) into "
                        "register 23"),
}


class Field(NamedTuple):
    """One field of a journal entry: its name, unit and meaning."""

    name: str  #: as the entry writes it
    unit: str  #: its unit ("" for a name, a text, a flag or a list)
    meaning: str  #: in words
    required: bool = True  #: every entry of the kind carries it


class EventKind(NamedTuple):
    """A kind of journal entry, and the fields it carries beside time, mode and kind.

    The fields are data: :meth:`allsky.sim.journal.Journal.note` refuses an
    entry with a field its kind does not declare, or without one it requires.
    """

    name: str  #: the entry's ``kind``
    code: int  #: the frame loop's code for it (entries it writes itself)
    fields: tuple  #: its :class:`Field` s
    #: what else an entry may carry, in words ("" for nothing): a ground command carries
    #: its own fields (:data:`GROUND_COMMANDS`, and a fault's :data:`FAULT_KINDS` fields)
    more: str = ""

    @property
    def names(self) -> frozenset:
        """The names of its fields."""
        return frozenset(f.name for f in self.fields)

    @property
    def required(self) -> frozenset:
        """The names of the fields every entry of the kind carries."""
        return frozenset(f.name for f in self.fields if f.required)

    @property
    def words(self) -> str:
        """Its fields in words (docs/journal.md)."""
        parts = []
        for f in self.fields:
            unit = f" [{f.unit}]" if f.unit else ""
            opt = "; optional" if not f.required else ""
            parts.append(f"`{f.name}`{unit} ({f.meaning}{opt})")
        return "; ".join(parts) + (f"; {self.more}" if self.more else "")


F = Field
#: What the journal records (:mod:`allsky.sim.journal`).
EVENT_KINDS = (
    EventKind("mode_start", 1, (
        F("title", "", "the mode's title"),
        F("target", "", "the target being flown"),
        F("waits_for", "", "what the mode waits for first"))),
    EventKind("mode_end", 2, (
        F("exit", "", "the exit text, or `aborted: <reason>`"),
        F("status", "", "`done` or `aborted`"))),
    EventKind("switch", 3, (
        F("close", "", "the switches closed, coupled ones included"),
        F("open", "", "the switches opened"),
        F("step", "", "what the sequencer had waited for, or the recovery that did it"),
        F("waits_for", "", "what it waits for next"))),
    EventKind("action", 4, (
        F("action", "", "its name"),
        F("text", "", "in words"),
        F("recovery", "", "the recovery flown, by name", False))),
    EventKind("register", 5, (
        F("register", "", "the numeral: 7/9/11, 13-18, 22 (CPU 22 cleared), 23, 24, 120/128 "
                          "(a rate-command direction, `value` +1 or -1)"),
        F("word", "", "the word written: an axis, a register 23 word, `all`"),
        F("value", "unit", "the value written, in `unit`"),
        F("unit", "", "its unit in words (`deg`, `arcsec`, `deg/h`, `-`)"),
        F("by", "", "who wrote it: `master sequencer 20`, the ground, or the study that "
                    "loaded its estimate"),
        F("pulses", "pulse", "the raw content of a counter or DAC", False),
        F("counted_pulses", "pulse", "a drift DAC's count, before its full scale", False))),
    EventKind("star_lock", 6, (
        F("star", "", "the star in the tracker's slit, null when the slit is empty"),
        F("previous", "", "the star it held before"),
        F("cone_angle_deg", "deg", "its position along the slit"),
        F("in_use", "", "S12 or S13 closed"))),
    EventKind("saturation", 7, (
        F("what", "", "one of the saturations"),
        F("block", "", "the block's numeral"),
        F("active", "", "true as it begins, false as it ends"),
        F("axis", "", "the axis", False),
        F("wheel", "", "the wheel, from 0", False),
        F("counted_pulses", "pulse", "a drift DAC's count", False),
        F("applied_pulses", "pulse", "what the DAC applies", False),
        F("counted_deg_h", "deg/h", "the count as a rate", False),
        F("applied_deg_h", "deg/h", "what the DAC applies, as a rate", False),
        F("momentum_n_m_s", "N m s", "a wheel's momentum", False),
        F("limit_n_m_s", "N m s", "its limit", False))),
    EventKind("fault", 8, (
        F("fault", "", "its index in `[[faults]]`"),
        F("fault_kind", "", "its kind"),
        F("text", "", "in words"),
        F("active", "", "true at the onset, false at the end"))),
    EventKind("abort", 9, (F("reason", "", "why the mission ended"),)),
    EventKind("lock_rejected", 10, (
        F("star", "", "the star, or `stray light`, the tracker found in its slit and "
                      "refused, or held from a lock made while the check was not armed and "
                      "refused before the loop used it"),
        F("cone_angle_deg", "deg", "its position along the slit"),
        F("reference_cone_angle_deg", "deg", "the planned reference star's"),
        F("check_deg", "deg", "`star_tracker.cone_angle_check_deg`"),
        F("in_use", "", "S12 or S13 closed"))),
    EventKind("lock_dropped", 11, (
        F("star", "", "the star, or `stray light`, the tracker held"),
        F("magnitude", "mag", "all the light in its slit: every star's and glint's"),
        F("gate_magnitude", "mag", "the bright gate: the magnitude window's bright end"),
        F("in_use", "", "S12 or S13 closed"))),
    EventKind("ground_command", 12, (
        F("command", "", "its kind: one of the ground commands"),
        F("text", "", "in words"),
        F("fault", "", "a `fault` command's index in `[[faults]]`", False),
        F("object", "", "what a `step_on` command let go of (a star, `stray light`)", False)),
        more="and the command's own fields"),
    EventKind("eclipse", 13, (
        F("phase", "", "what the vehicle enters, in orbit: `penumbra`, `umbra` or `sunlit`"),
        F("active", "", "false once fully sunlit again"),
        F("sunlit_fraction", "", "of the Sun's disk, in the entry's frame"))),
    EventKind("occultation", 14, (
        F("body", "", "a star of the tracker's magnitude window, or `target`"),
        F("active", "", "true when the Earth's disk begins to hide it, false when it clears"))),
    EventKind("earth_glare", 15, (
        F("active", "", "true as sunlit Earth enters the tracker's slit (it is blinded: no "
                        "star found, none held), false as the last of it leaves"),
        F("star", "", "the star, or `stray light`, the tracker held as it was blinded; null "
                      "for none (and at the end)"),
        F("cos_incidence", "", "the cosine of the Sun's incidence at the most directly lit "
                               "point of the Earth in the slit, as it enters", False),
        F("surface_brightness_mag_arcsec2", "mag/arcsec^2",
          "that point's brightness (a Lambertian Earth of albedo 0.30), as it enters", False),
        F("in_use", "", "S12 or S13 closed"))),
)
del F
#: Journal kind name -> :class:`EventKind`.
EVENT_KIND = {k.name: k for k in EVENT_KINDS}

#: Saturations the journal records: name -> (block numerals, meaning).
SATURATIONS = {
    "drift_dac_clip": (("7", "9", "11"), "a drift DAC applies its full scale, not the count"),
    "counter_overflow": (("14", "16", "18", "13", "15", "17"),
                         "an up/down or drift counter overflowed (latched)"),
    "wheel_momentum_limit": (("wheels",), "a reaction wheel holds its momentum limit"),
    "wheel_unloading": (("wheels", "39", "40", "41"),
                        "the jets unload the wheels' momentum"),
}


class CommandKind(NamedTuple):
    """A kind of ground command: what it needs and what it acts on."""

    name: str  #: the command's ``kind``
    fields: tuple  #: the fields it needs, in this order
    optional: tuple  #: the fields it may have beyond those
    acts_on: str  #: "session" (the live clock), "hardware" or "sequencer" (master sequencer 20)
    meaning: str  #: what it does, in words (docs/ground_control.md)


#: What the ground may command during a flight (:mod:`allsky.sim.commands` applies them, at
#: a frame boundary; each is a ``ground_command`` entry of the journal).
GROUND_COMMANDS = (
    CommandKind("pause", (), (), "session",
                "stop the live clock at this frame boundary; the flight goes on from it, bit "
                "for bit, at `resume`"),
    CommandKind("resume", (), (), "session", "start the live clock again"),
    CommandKind("speed", ("speed",), (), "session",
                "fly at `speed` times real time (a live session; what is flown does not change)"),
    CommandKind("fault", ("fault_kind",), ("duration_s",), "hardware",
                "inject a fault now: `fault_kind` and the fields of that kind of `[[faults]]`, "
                "optional `duration_s`; exactly the `[[faults]]` entry with `start_s` = now"),
    CommandKind("clear_fault", ("fault",), (), "hardware",
                "end fault number `fault` (its index in `[[faults]]`, from 0) now: its "
                "`duration_s` becomes the time it has acted"),
    CommandKind("tracker_window", ("magnitude_window",), (), "hardware",
                "set star tracker 105's magnitude window [bright, faint] (mag); a star it "
                "held outside the new window is lost"),
    CommandKind("bright_gate", ("enabled",), (), "hardware",
                "enable or disable star tracker 105's bright gate"),
    CommandKind("step_on", (), (), "hardware",
                "star tracker 105 lets go of the object it holds and ignores it until it has "
                "left the slit, as the cone-angle check ignores a star it refused; the search "
                "goes on (Mariner 4's star-hopping; with `reacquire` the roll searches again)"),
    CommandKind("target", (), ("star", "ra_deg", "dec_deg"), "sequencer",
                "upload register 24's programmed angles for a new target (`star`, or "
                "`ra_deg` and `dec_deg`): it replaces the target while the vehicle has not "
                "begun Mode 6; else it is flown next, from the target being flown, by "
                "`sequencer.between_targets`"),
    CommandKind("hold", (), (), "sequencer",
                "hold on the target until a command ends the hold (`proceed`, `target`, "
                "`reacquire`, `recycle`): now if on target, else once the target is reached"),
    CommandKind("proceed", (), (), "sequencer",
                "end the hold on target and go on with the plan"),
    CommandKind("reacquire", (), (), "sequencer",
                "end the mode being flown; acquire the Sun and the star again (Modes 1 and 2, "
                "the calibration kept), then fly that mode again or, from Mode 6 on, the "
                "target again"),
    CommandKind("recycle", (), (), "sequencer",
                "end the mode being flown; every mode again from Mode 1, calibration included, "
                "then the target again"),
    CommandKind("end", (), (), "session",
                "end the session at this frame boundary (the outputs are those of the flight "
                "so far)"),
)
#: Command kind name -> :class:`CommandKind`.
GROUND_COMMAND = {k.name: k for k in GROUND_COMMANDS}
