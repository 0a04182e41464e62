"""Ground commands to master sequencer 20, as changes of the plan.

The operators of the 1970s commanded the sequencer from the ground: hold
on the target, go back to the Sun and Canopus (Mariner 4's team did so six
times), fly every mode again, take a new target by uploading register 24's
programmed angles. Here each such command is a change of the mission's
plan, made of the modes of the mode table (:mod:`allsky.sequencer.modes`):
no command touches a switch or a register but through the modes it makes
the sequencer fly. :func:`replan` says, for a command and where the mission
is, the plan to fly, whether the mode being flown ends now, and what
becomes of the targets; :mod:`allsky.sim.commands` applies it to the
mission at a frame boundary.

Where the mission is (:func:`phase`):

* ``"before"``: before the target's Mode 6 (Modes 1 to 5, the dither, the
  ground's "references" and "restart"): register 24 is not loaded;
* ``"turning"``: Mode 6-1, 6-2 or a direct move: register 24 loaded, the
  vehicle on its way to the target;
* ``"on target"``: holding on it (the hold, the standby), or the mission
  complete on it.

What each command does there:

============  =========================  ============================  ==========================
command       before                     turning                       on target
============  =========================  ============================  ==========================
target        replaces the target        flown next, after this one    flown next, now
hold          standby after this 6-2     standby after this 6-2        standby now
proceed       --                         --                            ends the standby
reacquire     references, 1, 2, mode     the target again: reacquire   the target again, now
recycle       restart, 1 to 5, 6-1 ...   the target again: recycle     the target again, now
============  =========================  ============================  ==========================

"The target again" is a new entry of the targets flown (its programmed
angles computed anew from the references found again): the scenario's
``target.sequence`` gains the same target after the one flown, and the
between-targets move "reacquire" (or "recycle") takes it. A new target
flown next goes by ``sequencer.between_targets``. An aborted mission is
flown again by ``reacquire`` or ``recycle`` (from the mode it aborted in);
the other sequencer commands wait for that.
"""

from typing import NamedTuple

from allsky.sequencer import modes

#: The sequencer's commands (:data:`allsky.vocabulary.GROUND_COMMANDS` acting on it).
SEQUENCER_COMMANDS = ("target", "hold", "proceed", "reacquire", "recycle")
#: Modes before a target's Mode 6: register 24 not yet loaded for it.
BEFORE = ("1", "2", "3", "4", "5", "dither", "references", "restart", "reacquire", "recycle")
#: Modes that fly the vehicle to its target (register 24 loaded).
TURNING = ("6-1", "6-2", "direct")
#: Modes that hold the vehicle on its target.
HOLDING = (modes.HOLD_MODE, "standby")
#: The ground's hold until a command ends it.
STANDBY = "standby"


class Refused(Exception):
    """A command the sequencer cannot take where the mission is; the message says why."""


class Replan(NamedTuple):
    """What a command makes of the plan (:func:`replan`)."""

    plan: tuple  #: the whole plan to fly
    end_mode: bool  #: the mode being flown ends now
    #: the target being flown is flown again next ("again"), a new target is flown next
    #: ("next"), replaces the target being flown ("replace"), or None
    target: str | None


class Where(NamedTuple):
    """Where a mission is, as the ground commands see it."""

    plan: tuple  #: the mission's plan
    index: int | None  #: the mode being flown, or last flown (None: none yet)
    flying: bool  #: a mode is being flown (False: before the first, or finished)
    status: str  #: "running", "complete" or "aborted"


def phase(where: Where) -> str:
    """``"start"``, ``"before"``, ``"turning"`` or ``"on target"`` (module docstring).

    ``where`` is where the mission stands: its plan, the mode index, flying.
    """
    if where.index is None:
        return "start"
    mode = where.plan[where.index]
    if mode in TURNING:
        return "turning" if where.flying or where.status == "aborted" else "on target"
    if mode in HOLDING:
        return "on target"
    return "before"


def base_plan(plan) -> tuple:
    """The modes of the first target's flight, up to its Mode 6-2 (without the hold).

    ``plan`` is the mission's plan, a sequence of mode names.
    """
    plan = tuple(plan)
    last = modes.TARGET_MODES[-1]
    return plan[: plan.index(last) + 1] if last in plan else plan


def _block_end(plan, index) -> int:
    """Index of the first mode after the target being flown (its move to the next)."""
    for k in range(index + 1, len(plan)):
        if plan[k] in modes.BETWEEN_TARGETS:
            return k
    return len(plan)


def _after_6_2(plan, index) -> int:
    """Index just after the Mode 6-2 of the target being flown (at or after ``index``)."""
    end = _block_end(plan, index)
    last = modes.TARGET_MODES[-1]
    for k in range(index, end):
        if plan[k] == last:
            return k + 1
    return end


def _next_target_modes(plan, how, cfg) -> tuple:
    """The modes that fly a next target by move ``how``, with the scenario's hold."""
    return modes.with_hold(modes.next_target_modes(base_plan(plan), how), cfg)


def replan(command: str, where: Where, cfg) -> Replan:
    """The plan after sequencer command ``command`` (:data:`SEQUENCER_COMMANDS`).

    ``where`` is where the mission is; ``cfg`` its scenario (the hold on
    target, ``sequencer.between_targets``).

    Raises
    ------
    Refused
        The command cannot be taken there (with the reason).
    """
    plan, i = tuple(where.plan), where.index
    at = phase(where)
    aborted = where.status == "aborted"
    if command not in SEQUENCER_COMMANDS:
        raise ValueError(f"not a sequencer command: {command!r}")
    if at == "start":
        if command == "target":
            return Replan(plan, False, "replace")
        if command == "hold":
            k = _after_6_2(plan, 0)
            return Replan(plan[:k] + (STANDBY,) + plan[k:], False, None)
        raise Refused(f"the mission has not begun: {command} needs a mode flown")
    mode = plan[i]
    keep = plan[: i + 1]
    if aborted and command in ("target", "hold", "proceed"):
        raise Refused(f"the sequencer has stopped (aborted in Mode {mode}): command reacquire "
                      f"or recycle first")
    if command == "target":
        if at == "before":
            return Replan(plan, False, "replace")
        if at == "turning":  # the target being flown first, then the new one
            k = _after_6_2(plan, i)
            end = _block_end(plan, i)
            block = tuple(m for m in plan[k:end] if m != STANDBY)
            return Replan(plan[:k] + block
                          + _next_target_modes(plan, cfg.sequencer.between_targets, cfg)
                          + plan[end:], False, "next")
        return Replan(keep + _next_target_modes(plan, cfg.sequencer.between_targets, cfg)
                      + plan[_block_end(plan, i):], where.flying, "next")
    if command == "hold":
        if at == "on target":
            if mode == STANDBY and where.flying:
                raise Refused("already holding on the target until a command")
            return Replan(keep + (STANDBY,) + plan[i + 1:], where.flying, None)
        k = _after_6_2(plan, i)
        if plan[k:k + 1] == (STANDBY,):
            raise Refused("the hold is already planned for when the target is reached")
        return Replan(plan[:k] + (STANDBY,) + plan[k:], False, None)
    if command == "proceed":
        if not (mode == STANDBY and where.flying):
            planned = STANDBY in plan[i + 1:_block_end(plan, i)]
            if planned:  # a hold planned for when the target is reached: dropped
                k = plan.index(STANDBY, i + 1)
                return Replan(plan[:k] + plan[k + 1:], False, None)
            raise Refused("not holding on a target: nothing to proceed from")
        return Replan(plan, True, None)
    # reacquire, recycle
    if at == "before":
        if command == "reacquire":
            if mode in ("1", "2"):  # Modes 1 and 2 again, then what followed them
                k = i + 1
                while k < len(plan) and plan[k] in ("1", "2"):
                    k += 1
                tail = plan[k:]
            else:
                tail = plan[i:]
            return Replan(keep + ("references", "1", "2") + tail, where.flying, None)
        first = base_plan(plan)
        before = first[: first.index(modes.TARGET_MODES[0])] if modes.TARGET_MODES[0] in first \
            else first
        k = next((j for j in range(i, len(plan)) if plan[j] == modes.TARGET_MODES[0]),
                 len(plan))
        return Replan(keep + ("restart",) + before + plan[k:], where.flying, None)
    return Replan(keep + _next_target_modes(plan, command, cfg) + plan[_block_end(plan, i):],
                  where.flying, "again")
