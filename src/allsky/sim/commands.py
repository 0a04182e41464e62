"""Ground commands: checked, applied at a frame boundary, saved, and flown again.

A command (:data:`allsky.vocabulary.GROUND_COMMANDS`) is a dict ``{"kind":
..., fields}``. :func:`validate` checks one against the scenario flown;
:class:`Station` applies them to a mission (:meth:`Station.apply`), each
at the frame boundary where the flight stands, and keeps the log of what
it applied with the mission time of each; :func:`fly` flies a mission,
stopping at the boundaries a front end asks for (a live session's slices,
or the times of a saved session's commands) to apply commands there.

Exactness. The frame loop pauses and resumes a leg bit for bit
(:mod:`allsky.sequencer.legs`), so where the flight is paused never changes
it; a command acts from the frame boundary it is applied at, and the log
records that frame's mission time (an exact decimal of the frame grid). A
command at a time ``t_s`` acts at the first frame starting at or after it
(:func:`allsky.clock.frame_at`, the rule every scheduled thing follows).
:func:`fly_log` pauses at exactly those frames and applies the same
commands: the summary and the telemetry are those of the session that
wrote the log, whatever the speed it was flown at live.

Several commands at one mission time act in the order given, each
completely before the next (:meth:`Station.take`): a command that changes
the plan (:data:`allsky.sequencer.ground.SEQUENCER_COMMANDS`) is the last
one taken at its boundary; the flight acts on it -- ends the mode it ends,
journals the hold's end, finishes the mission -- and the next command is
taken at the next boundary, which is at the same frame. The live server
and a saved session's flight both take commands so.

What a command changes, it changes through the scenario and the mode
table, never by writing the state:

* a ``fault`` becomes the scenario's next ``[[faults]]`` entry, with
  ``start_s`` the boundary's time (so the flight is exactly the flight of
  the scenario with that entry from the start: the frame loop with faults
  flies the fault-free mission bit for bit until the first onset);
  ``clear_fault`` gives an acting fault the ``duration_s`` that ends it at
  the boundary; ``tracker_window`` and ``bright_gate`` set
  ``star_tracker.magnitude_window`` and ``star_tracker.bright_gate``
  (:func:`amend`); ``step_on`` has the tracker
  let go of the object it holds and ignore it until it leaves the slit
  (:func:`step_on`), as the cone-angle check
  ignores a star it refused;
* ``target``, ``hold``, ``proceed``, ``reacquire`` and ``recycle`` change
  the plan with the modes of the mode table (:mod:`allsky.sequencer.ground`,
  :func:`replan`); a target flown again or anew
  joins the scenario's ``target.sequence``;
* ``pause``, ``resume``, ``speed`` and ``end`` act on the session (the live
  clock, its end); they change nothing of the flight.

Every command applied is a ``ground_command`` entry of the journal. A
command that cannot be taken where the mission is raises :class:`Refused`
and leaves no trace. The log is TOML (:func:`log_text`, :func:`read_log`):
the scenario flown and ``[[commands]]``, each with ``t_s`` and its fields.
"""

import math
from collections.abc import Mapping

from allsky import clock
from allsky.config import scenario_from_dict
from allsky.config.faults import MAX_FAULTS, describe, validate_fault
from allsky.config.rules import NON_NEGATIVE, ConfigError, in_open_closed, number, type_name
from allsky.config.schema import RULES
from allsky.config.toml_io import read_toml, toml_key, toml_value
from allsky.hardware import star_tracker
from allsky.sequencer import ground, modes
from allsky.sequencer.ground import Refused
from allsky.sequencer.watch import sensors_in_use
from allsky.sim import faults as sim_faults
from allsky.sim import journal, record
from allsky.sim import mission as mission_mod
from allsky.vocabulary import FAULT_KIND, GROUND_COMMAND

#: Version of the command log's layout.
LOG_FORMAT = 1
#: Fastest live speed a ``speed`` command may ask for [x real time].
SPEED_MAX = 10000.0
#: Commands that act on the live session's clock only, never on the flight.
SESSION_CLOCK = ("pause", "resume", "speed")
#: Commands that end a hold on target the ground commanded (``hold``).
ENDS_A_HOLD = ("proceed", "target", "reacquire", "recycle", "end")


class Ended(BaseException):
    """The session's ``end`` command: the flight stops at this frame boundary.

    A :class:`BaseException`, as KeyboardInterrupt is, so that the mission
    keeps the telemetry flown and nothing between the hook and :func:`fly`
    takes it for a failure.
    """


def _values(cfg) -> dict:
    """The scenario's values by dotted key (``star_tracker.fov_narrow_half_deg``)."""
    out = {}
    for sec, table in cfg.as_dict().items():
        if isinstance(table, Mapping) and sec != "dispersions":
            section = getattr(cfg, sec)
            for k in table:
                out[f"{sec}.{k}"] = getattr(section, k)
    for k in ("target.star", "target.ra_deg", "target.dec_deg", "target.sequence"):
        out.setdefault(k, None)
    return out


def validate(command, cfg, where="command") -> dict:
    """One command, checked against scenario ``cfg``; returns it normalised.

    ``command`` is ``{"kind": ..., fields}`` (a log's ``t_s`` is checked by
    :func:`validate_log`); ``where`` names it in errors (``commands[2]``).

    Raises
    ------
    ConfigError
        Naming the field, the value and the rule (``commands[2].axis``).
    """
    if not isinstance(command, Mapping):
        raise ConfigError(where, command, f"must be a table, not {type_name(command)}")
    kind = command.get("kind")
    if not isinstance(kind, str) or kind not in GROUND_COMMAND:
        raise ConfigError(f"{where}.kind", kind, "must be one of "
                          + ", ".join(f'"{k}"' for k in GROUND_COMMAND))
    spec = GROUND_COMMAND[kind]
    fields = {k: v for k, v in command.items() if k not in ("kind", "t_s")}
    out = {"kind": kind}
    if kind == "fault":
        return {**out, **_fault_fields(fields, cfg, where)}
    for k, v in fields.items():
        if k not in (*spec.fields, *spec.optional):
            allowed = ", ".join((*spec.fields, *spec.optional)) or "none"
            raise ConfigError(f"{where}.{k}", v,
                              f'unknown field for kind = "{kind}"; valid: {allowed}')
    for k in spec.fields:
        if k not in fields:
            raise ConfigError(f"{where}.{k}", rule=f'missing: kind = "{kind}" needs '
                              f"{', '.join(spec.fields)}")
    if kind == "speed":
        out["speed"] = number(in_open_closed(0, SPEED_MAX))(f"{where}.speed", fields["speed"])
    elif kind == "clear_fault":
        v = fields["fault"]
        if isinstance(v, bool) or not isinstance(v, int) or not 0 <= v < MAX_FAULTS:
            raise ConfigError(f"{where}.fault", v, f"must be a fault's index in [[faults]], "
                              f"an integer 0..{MAX_FAULTS - 1}")
        out["fault"] = v
    elif kind == "tracker_window":
        out["magnitude_window"] = list(RULES["star_tracker.magnitude_window"](
            f"{where}.magnitude_window", fields["magnitude_window"]))
    elif kind == "bright_gate":
        out["enabled"] = RULES["star_tracker.bright_gate"](f"{where}.enabled",
                                                            fields["enabled"])
    elif kind == "target":
        out.update(_target_fields(fields, where))
    return out


def _fault_fields(fields, cfg, where) -> dict:
    """A fault command's fields: ``fault_kind``, the kind's own, ``duration_s``."""
    kind = fields.get("fault_kind")
    if kind is None:
        raise ConfigError(f"{where}.fault_kind", rule="missing: one of "
                          + ", ".join(f'"{k}"' for k in FAULT_KIND))
    if kind not in FAULT_KIND:
        raise ConfigError(f"{where}.fault_kind", kind, "must be one of "
                          + ", ".join(f'"{k}"' for k in FAULT_KIND))
    rest = {k: v for k, v in fields.items() if k != "fault_kind"}
    for k, v in rest.items():
        if k in ("start_s", "start_mode", "kind"):
            raise ConfigError(f"{where}.{k}", v, "a commanded fault starts when it is "
                              "applied; give its fields and duration_s only")
    checked = validate_fault(where, {"kind": kind, **rest, "start_s": 0.0}, _values(cfg))
    checked.pop("start_s")
    checked.pop("kind")
    return {"fault_kind": kind, **checked}


def _target_fields(fields, where) -> dict:
    """A target command's ``star``, or ``ra_deg`` and ``dec_deg``."""
    if "star" in fields:
        if "ra_deg" in fields or "dec_deg" in fields:
            raise ConfigError(where, rule="give star, or ra_deg and dec_deg, not both")
        return {"star": RULES["target.star"](f"{where}.star", fields["star"])}
    if "ra_deg" not in fields or "dec_deg" not in fields:
        raise ConfigError(where, rule="a target needs star, or ra_deg and dec_deg")
    return {"ra_deg": RULES["target.ra_deg"](f"{where}.ra_deg", fields["ra_deg"]),
            "dec_deg": RULES["target.dec_deg"](f"{where}.dec_deg", fields["dec_deg"])}


def validate_log(commands, cfg) -> list:
    """A log's commands, each checked (:func:`validate`) with its ``t_s``.

    ``commands`` is the log's ``[[commands]]`` array as read (:func:`read_log`),
    checked against ``cfg``, the scenario they are to be flown with.

    ``t_s`` [s] is a number >= 0, never less than the command before's; an
    ``end`` is the last command; a ``hold`` is followed by a command that
    ends it (:data:`ENDS_A_HOLD`), so that a flight of the log ends.

    Raises
    ------
    ConfigError
        Naming the command (``commands[3].t_s``) and the rule.
    """
    if not isinstance(commands, list):
        raise ConfigError("commands", commands, "must be an array of tables ([[commands]])")
    out, last = [], 0.0
    for i, c in enumerate(commands):
        where = f"commands[{i}]"
        checked = validate(c, cfg, where)
        if "t_s" not in c:
            raise ConfigError(f"{where}.t_s", rule="missing: the mission time [s] it acts at")
        t = number(NON_NEGATIVE)(f"{where}.t_s", c["t_s"])
        if t < last:
            raise ConfigError(f"{where}.t_s", t, f"must not be before the command before it "
                              f"({last!r} s)")
        if out and out[-1]["kind"] == "end":
            raise ConfigError(where, checked["kind"], "comes after the session's end")
        last = t
        out.append({"t_s": t, **checked})
    for i, c in enumerate(out):
        if c["kind"] == "hold" and not any(d["kind"] in ENDS_A_HOLD for d in out[i + 1:]):
            raise ConfigError(f"commands[{i}]", "hold", "a hold lasts until a command ends it "
                              f"({', '.join(ENDS_A_HOLD)}); none follows")
    return out


def words(command, fault_index=None) -> str:
    """A command in words, for the journal and the page.

    ``command`` is a validated command (:func:`validate`); ``fault_index`` the
    slot in ``[[faults]]`` a ``fault`` command took (None: not named).
    """
    kind = command["kind"]
    if kind == "fault":
        fault = {"kind": command["fault_kind"],
                 **{k: v for k, v in command.items() if k not in ("kind", "fault_kind")}}
        span = f" for {command['duration_s']:g} s" if "duration_s" in command else ""
        slot = f" (fault {fault_index})" if fault_index is not None else ""
        return f"inject {describe(fault)}{span}{slot}"
    if kind == "clear_fault":
        return f"clear fault {command['fault']}"
    if kind == "tracker_window":
        lo, hi = command["magnitude_window"]
        return f"tracker's magnitude window {lo:+g} to {hi:+g} mag"
    if kind == "bright_gate":
        return f"tracker's bright gate {'enabled' if command['enabled'] else 'disabled'}"
    if kind == "step_on":
        return "tracker steps on past the object it holds"
    if kind == "target":
        return f"new target {mission_mod.target_name(_target_spec(command))}"
    if kind == "speed":
        return f"speed x{command['speed']:g}"
    return {"pause": "pause the live clock", "resume": "resume the live clock",
            "hold": "hold on the target", "proceed": "proceed from the hold",
            "reacquire": "reacquire the Sun and the star", "recycle": "recycle every mode",
            "end": "end of the session"}[kind]


def _target_spec(command) -> dict:
    """A target command's target, as :func:`allsky.sim.mission.target_specs` gives one."""
    if "star" in command:
        return {"star": command["star"]}
    return {"ra_deg": float(command["ra_deg"]), "dec_deg": float(command["dec_deg"])}


def _as_lists(v):
    """A checked value as a scenario file holds it: tuples (a checked array) as lists."""
    return [_as_lists(x) for x in v] if isinstance(v, (tuple, list)) else v


def _amended(m, change) -> object:
    """The mission's scenario with ``change(data)`` made to its dict; Refused if invalid."""
    data = m.cfg.as_dict()
    change(data)
    try:
        return scenario_from_dict(data)
    except ConfigError as e:
        raise Refused(f"the scenario would not hold: {e}") from None


class Station:
    """The ground station of one mission: applies commands, keeps their log.

    Parameters
    ----------
    m : allsky.sim.mission.Mission
        The mission commanded.
    """

    def __init__(self, m):
        self.m = m
        #: the commands applied, in order, each with ``t_s``, the mission time it acted at
        self.log = []
        #: the live speed last commanded (None: none commanded)
        self.speed = None
        #: the live clock is paused
        self.paused = False
        #: an ``end`` has been applied
        self.ended = False

    def where(self) -> ground.Where:
        """Where the mission is, as the sequencer's commands see it."""
        m = self.m
        flying = m.mode_in_flight is not None
        index = m.mode_in_flight if flying else (m.next_mode - 1 if m.next_mode > 0 else None)
        return ground.Where(tuple(m.plan), index, flying, m.status)

    def apply(self, command) -> dict:
        """Apply a validated ``command`` at the frame boundary the flight stands at.

        Returns the ``ground_command`` journal entry.

        Raises
        ------
        Refused
            The command cannot be taken here (the mission unchanged).
        """
        m, kind = self.m, command["kind"]
        fields = {k: v for k, v in command.items() if k not in ("kind", "t_s")}
        effect, extra = self._prepare(kind, fields)
        entry = m.note("ground_command", command=kind, **fields, **extra,
                       text=words(command, extra.get("fault")))
        if effect is not None:
            effect()
        self.log.append({"t_s": entry["t_s"], "kind": kind, **fields})
        if kind == "pause":
            self.paused = True
        elif kind == "resume":
            self.paused = False
        elif kind == "speed":
            self.speed = float(fields["speed"])
        elif kind == "end":
            self.ended = True
        return entry

    def take(self, commands) -> int:
        """Apply ``commands`` in order, at this boundary, as far as the rule allows.

        A command that changes the plan is the last one applied here: the
        flight must act on it before the next (module docstring). Returns how
        many were applied (each raising :class:`Refused` stops there).
        """
        n = 0
        for command in commands:
            self.apply(command)
            n += 1
            if command["kind"] in ground.SEQUENCER_COMMANDS:
                break
        return n

    def _prepare(self, kind, fields):
        """``(effect, extra)``: what applying the command does, and the entry's fields."""
        m = self.m
        if kind == "fault":
            n = len(m.cfg.faults)
            if n >= MAX_FAULTS:
                raise Refused(f"the scenario holds {MAX_FAULTS} faults already, the frame "
                              "loop's slots")
            entry = {"kind": fields["fault_kind"],
                     **{k: _as_lists(v) for k, v in fields.items() if k != "fault_kind"},
                     "start_s": m.now_s()}

            def add(data):
                data["faults"] = [*data.get("faults", []), entry]
            cfg = _amended(m, add)
            return (lambda: amend(m, cfg)), {"fault": n}
        if kind == "clear_fault":
            cfg = _amended(m, lambda data: self._clear(data, fields["fault"]))
            return (lambda: amend(m, cfg)), {}
        if kind == "tracker_window":
            cfg = _amended(m, lambda data: data["star_tracker"].update(
                magnitude_window=list(fields["magnitude_window"])))
            return (lambda: amend(m, cfg)), {}
        if kind == "bright_gate":
            cfg = _amended(m, lambda data: data["star_tracker"].update(
                bright_gate=bool(fields["enabled"])))
            return (lambda: amend(m, cfg)), {}
        if kind == "step_on":
            held = held_object(m)
            if held is None:
                raise Refused("star tracker 105 holds nothing to step on from")
            return (lambda: step_on(m)), {"object": held}
        if kind in ground.SEQUENCER_COMMANDS:
            return self._sequencer(kind, fields), {}
        if kind == "resume" and not self.paused:
            raise Refused("the live clock is not paused")
        if kind == "pause" and self.paused:
            raise Refused("the live clock is paused already")
        return None, {}

    def _clear(self, data, index):
        """End fault ``index`` of scenario dict ``data`` at this boundary."""
        m = self.m
        faults = data.get("faults", [])
        if index >= len(faults):
            raise Refused(f"no fault {index}: the scenario has {len(faults)}")
        onset = m.state.fault_state[sim_faults.ONSET, index]
        now = m.frame
        if not 0.0 <= onset < now:
            raise Refused(f"fault {index} ({describe(faults[index])}) has not begun to act")
        ck = m.params.clock
        if now >= onset + clock.frames_for(ck, faults[index].get("duration_s", math.inf)):
            raise Refused(f"fault {index} ({describe(faults[index])}) has ended already")
        # The duration from its onset to this frame, exactly: it acts no more from here.
        faults[index] = {**faults[index], "duration_s": clock.time_s(ck, now - int(onset))}

    def _sequencer(self, kind, fields):
        """The effect of a command to master sequencer 20 (Refused where it cannot act)."""
        m = self.m
        plan = ground.replan(kind, self.where(), m.cfg)
        cfg = None
        if plan.target is not None:
            specs = mission_mod.target_specs(m.cfg)
            k = m.target_index
            spec = _target_spec(fields) if kind == "target" else dict(specs[k])
            if plan.target == "replace":
                specs[k] = spec
            else:
                specs.insert(k + 1, spec)

            def sequence(data):
                table = data["target"]
                for key in ("star", "ra_deg", "dec_deg"):
                    table.pop(key, None)
                table["sequence"] = [s["star"] if "star" in s else dict(s) for s in specs]
            cfg = _amended(m, sequence)
        text = words({"kind": kind, **fields})

        def effect():
            if cfg is not None:
                amend(m, cfg, retarget=plan.target == "replace")
            replan(m, plan.plan, plan.end_mode, text)
        return effect


def fly(m, boundary, pause_at, hooks=None) -> None:
    """Fly mission ``m``, calling ``boundary`` at frame boundaries to command it.

    ``boundary(m, where)`` is called with ``where`` "start" (before the first
    mode), "leg" (inside a leg, at the mission time ``pause_at(m)`` asked for)
    and "finished" (the mission complete or aborted: the flight stands
    still); it applies commands (:meth:`Station.apply`). At "finished" it
    returns False when nothing more will come, and the flight ends. An
    ``end`` command raises :class:`Ended` from it: the flight stops there.
    ``pause_at``, called as ``pause_at(m)``, returns the mission time [s] of
    the next pause inside a leg (``math.inf``: none). ``hooks`` (:class:`allsky.sim.mission.Hooks`)
    are called as well (a progress line).
    """
    base = hooks or mission_mod.NO_HOOKS

    def on_pause(mm, what):
        if base.on_pause is not None:
            base.on_pause(mm, what)
        boundary(mm, "leg")

    flight = base._replace(on_pause=on_pause, pause_at=pause_at)
    try:
        if m.next_mode == 0 and not m.timeline:
            boundary(m, "start")
        while True:
            if m.finished:
                if not boundary(m, "finished"):
                    return
                continue
            m.run_mode(flight)
    except Ended:
        return


def fly_log(m, commands, hooks=None) -> Station:
    """Fly ``m`` with a saved session's ``commands``, each at its ``t_s``.

    ``commands`` are checked by :func:`validate_log`; ``hooks``
    (:class:`allsky.sim.mission.Hooks`, optional) are called as in :func:`fly`.

    The flight pauses at each command's frame (the first frame starting at
    or after its ``t_s``, :func:`allsky.clock.frame_at`) and takes the
    commands due there (:meth:`Station.take`); when the mission has
    finished, the rest in order. A log written by a live session gives that
    session's flight, bit for bit. Returns the :class:`Station` (its log
    holds the times the commands acted at).

    Raises
    ------
    Refused
        A command the mission could not take where it stood (a log edited
        by hand, or flown with another scenario).
    """
    station = Station(m)
    todo = list(commands)
    ck = m.params.clock

    def pause_at(mm):
        return todo[0]["t_s"] if todo else math.inf

    def boundary(mm, where):
        if where == "finished" and not todo:
            return False
        due = [c for c in todo if clock.frame_at(ck, c["t_s"]) <= mm.frame]
        if where == "finished" and not due:
            due = todo[:1]  # the flight stands still: the next command now
        n = station.take(due)
        if any(c["kind"] == "end" for c in due[:n]):
            raise Ended
        del todo[:n]
        return True

    fly(m, boundary, pause_at, hooks)
    return station


# -- the log ---------------------------------------------------------------------

_HEADER = ("# allsky ground-control session: the scenario flown and the commands sent, each\n"
           "# at the mission time it acted (t_s, s). Fly it again, exactly:\n"
           "#   allsky run --commands THIS_FILE\n")


def log_text(commands, scenario=None, note="") -> str:
    """The command log as TOML text: the scenario and ``[[commands]]``.

    ``scenario`` is a scenario's dict (:meth:`allsky.config.Scenario.as_dict`).

    ``commands`` are the commands applied, each with ``t_s``; ``note`` a
    comment line (who flew what). Every float is written exactly (its
    shortest repr), so the log reads back to the same times.
    """
    key = toml_key
    lines = [_HEADER.rstrip("\n")]
    if note:
        lines.append(f"# {note}")
    lines += ["", f"format = {LOG_FORMAT}"]
    if scenario is not None:
        for sec, table in scenario.items():
            if isinstance(table, Mapping):
                lines += ["", f"[scenario.{key(sec)}]"]
                lines += [f"{key(k)} = {toml_value(v)}" for k, v in table.items()]
        for fault in scenario.get("faults", []):
            lines += ["", "[[scenario.faults]]"]
            lines += [f"{key(k)} = {toml_value(v)}" for k, v in fault.items()]
    for c in commands:
        lines += ["", "[[commands]]", f"t_s = {toml_value(float(c['t_s']))}",
                  f"kind = {toml_value(c['kind'])}"]
        lines += [f"{key(k)} = {toml_value(v)}" for k, v in c.items()
                  if k not in ("t_s", "kind")]
    return "\n".join(lines) + "\n"


def read_log(path) -> tuple:
    """The command log at ``path``: ``(scenario dict or None, commands as read)``.

    Check the commands with :func:`validate_log` against the scenario flown.

    Raises
    ------
    ConfigError
        An unreadable file, bad TOML, another format, a key that is not
        ``format``, ``scenario`` or ``commands``.
    """
    data = read_toml(path, what="command log")
    for k in data:
        if k not in ("format", "scenario", "commands"):
            raise ConfigError(k, rule="unknown key of a command log; valid: format, scenario, "
                              "commands")
    if "format" not in data:
        raise ConfigError("format", rule=f"missing: a command log says its format (format = "
                          f"{LOG_FORMAT}, as allsky serve --save-commands writes it)")
    if type(data["format"]) is not int or data["format"] != LOG_FORMAT:
        raise ConfigError("format", data["format"], f"this allsky reads command logs of "
                          f"format {LOG_FORMAT}")
    scenario = data.get("scenario")
    if scenario is not None and not isinstance(scenario, Mapping):
        raise ConfigError("scenario", scenario, "must be a table of the scenario's sections")
    return scenario, data.get("commands", [])


# -- the applying half: what a command does to the mission, at a frame boundary -------
# The deciding half (:class:`Station`) says what a command means; these apply it
# through the mission's declared interface (``fly_on_with``, ``interrupt``, its state,
# journal and target log).

def amend(m, cfg, retarget=False) -> None:
    """Fly on with scenario ``cfg`` from this frame boundary (a ground command).

    What a command changes of the scenario mid-flight: a fault added (its
    ``start_s`` onset armed) or ended (its ``duration_s``), star tracker
    105's magnitude window and bright gate, the targets. The frame loop's
    parameters are built again (:func:`allsky.sim.mission.build_params`, as for a scenario
    that had the change from the start); a leg in flight goes on with
    them. The tracker's memory is carried over by star name; a star it
    held that the new window does not pass is lost, and the journal says
    so. With ``retarget`` the target being flown becomes the new
    scenario's at its index (``target.sequence``): a target whose Mode 6
    has not begun.

    ``m`` is the mission (:class:`allsky.sim.mission.Mission`).
    """
    old_names = mission_mod.tracker_star_names(m.cfg)
    gate_before = m.params.tracker.bright_gate_mag
    m.fly_on_with(cfg)
    sim_faults.arm(m.state.fault_state, cfg.faults, m.params.clock)
    new_names = mission_mod.tracker_star_names(cfg)
    if new_names != old_names:
        _carry_tracker(m, old_names, new_names)
    if m.params.tracker.bright_gate_mag != gate_before:
        m.state.tracker_lock[star_tracker.GATE] = 0.0
    if retarget:
        start = m.target_log[-1]["start_s"]
        m.target_log[-1] = mission_mod.new_target_record(cfg, m.target_index, start)
        m.state.target_inertial[:] = m.target_direction()

def held_object(m):
    """Name of the object star tracker 105 holds now: a star, "stray light", or None.

    ``m`` is the mission (:class:`allsky.sim.mission.Mission`).
    """
    held = int(m.state.tracker_lock[star_tracker.HELD])
    if held == star_tracker.FALSE_TARGET:
        return "stray light"
    return mission_mod.tracker_star_names(m.cfg)[held] if held >= 0 else None

def step_on(m) -> None:
    """Star tracker 105 lets go of what it holds, ignoring it until it leaves the slit.

    The ground's ``step_on`` (:mod:`allsky.sim.commands`): the object is
    remembered as the cone-angle check remembers a star it refused
    (:func:`allsky.hardware.star_tracker.refuse_now`), so the search
    passes it by; the journal's ``star_lock`` tells the lock's end.

    ``m`` is the mission (:class:`allsky.sim.mission.Mission`).
    """
    lock = m.state.tracker_lock
    held = lock[star_tracker.HELD]
    record.python_of(star_tracker.refuse_now)(lock, held, 0.0)
    lock[star_tracker.NEW_REFUSAL] = star_tracker.NONE  # the ground's, not the check's
    lock[star_tracker.HELD] = star_tracker.NONE

def _carry_tracker(m, old_names, new_names) -> None:
    """Star tracker 105's memory, from the star list ``old_names`` to ``new_names``."""
    s = m.state
    lock = s.tracker_lock

    def index(k):
        k = int(k)
        if k < 0 or k >= len(old_names):  # nothing, or a glint
            return k
        return new_names.index(old_names[k]) if old_names[k] in new_names \
            else star_tracker.NONE

    held = int(lock[star_tracker.HELD])
    if 0 <= held < len(old_names) and old_names[held] not in new_names:
        star_in_use = record.python_of(sensors_in_use)(s.switches, m.params.routing)[1]
        m.note("star_lock", star=None, previous=old_names[held], cone_angle_deg=None,
                  in_use=bool(star_in_use))
    slots = (star_tracker.HELD, star_tracker.NEW_REFUSAL, star_tracker.DROPPED,
             star_tracker.NEW_DROP, *range(star_tracker.REFUSED,
                                           star_tracker.REFUSED + star_tracker.N_REFUSED))
    for slot in slots:
        lock[slot] = index(lock[slot])
    if int(lock[star_tracker.HELD]) == star_tracker.FALSE_TARGET:
        # A glint held is judged again against the new window from the next frame.
        lock[star_tracker.HELD] = star_tracker.NONE
    seen = s.journal_seen[journal.SEEN_STAR]
    s.journal_seen[journal.SEEN_STAR] = -1.0 if index(seen) == star_tracker.NONE \
        else index(seen)
    k = int(s.locked_star[0])
    if k >= 0:
        if index(k) < 0:
            m.locked_before = old_names[k]
        s.locked_star[0] = index(k)

def replan(m, plan, end_mode=False, reason="") -> None:
    """Fly ``plan`` from the next mode on; with ``end_mode`` end the mode being flown.

    A ground command's change of the plan (:mod:`allsky.sequencer.ground`):
    ``plan`` is the whole plan, the modes flown and the one being flown
    as they are. With ``end_mode`` the mode being flown ends at this
    frame boundary, ``reason`` in its exit (its ``on_command`` steps
    flown), and the plan goes on after it. A finished mission (complete
    or aborted) flies again: its status is running and the abort reason
    cleared (the journal and the timeline keep the abort).

    Raises
    ------
    ValueError
        ``plan`` changes a mode flown, or names a mode not in the table.

    ``m`` is the mission (:class:`allsky.sim.mission.Mission`).
    """
    plan = tuple(plan)
    in_mode = m.mode_in_flight is not None
    kept = m.next_mode + (1 if in_mode else 0)
    if plan[:kept] != tuple(m.plan[:kept]) or any(n not in modes.BY_NAME for n in plan):
        raise ValueError(f"plan {plan} does not keep the modes flown {m.plan[:kept]}")
    m.plan = plan
    if end_mode:
        m.interrupt(reason)
    if m.finished and m.next_mode < len(plan):
        m.status = "running"
        m.abort_reason = None
