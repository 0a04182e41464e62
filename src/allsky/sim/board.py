"""The board: the one writer of the hardware between legs.

Between legs the hardware changes only by a few acts: a switch step, a
counter cleared or preset, a rate-command module's direction set, a
register 23 or 24 word loaded, a drift counter loaded, CPU 22 cleared or
stepped. Each is one method of :class:`Board` that writes the state's
arrays **and** journals the write in the same call, so the journal and the
hardware cannot disagree. Every register entry says who made it (``by``):
master sequencer 20 (:data:`SEQUENCER`), the ground, or a study that loads
its own estimates ("the Kalman filter").

The sequencer sees the state only through :attr:`Board.view`, whose arrays
are read-only views of the mission's: it reads them as the hardware's
outputs and changes them through the board. The frame loop, which writes
the state every frame, is the board's only peer; ``tests/sim/test_board.py``
forbids assigning into the state's arrays anywhere else outside ``sim/``.
"""

import numpy as np

from allsky import units
from allsky.computer import calibration_sequencer as cal19
from allsky.computer import cpu
from allsky.computer import word_registers as wr
from allsky.hardware import switch_bank, wiring
from allsky.hardware.dac import dac
from allsky.sim import journal
from allsky.sim import state as sim_state
from allsky.sim.record import python_of
from allsky.vocabulary import AXES

#: Who made a write when the caller does not say: the patent's sequencer.
SEQUENCER = "master sequencer 20"
#: Up/down counters 14, 16, 18 by axis (roll, pitch, yaw).
COUNTERS = ("14", "16", "18")
#: Drift counters 13, 15, 17 and drift DACs 7, 9, 11 by axis.
DRIFT_COUNTERS = journal.DRIFT_COUNTER
DRIFT_DACS = journal.DRIFT_DAC
#: Rate-command modules by the axis they turn: 120 roll, 128 yaw; and their slot in
#: ``State.rate_sign``.
RATE_COMMANDS = wiring.RATE_COMMAND_OF_AXIS
RATE_SIGN = wiring.RATE_SIGN_SLOT
#: CPU 22, whose working store a clear empties.
CPU = "22"
#: Every block the board writes, numeral -> what it is (the journal's ``register`` field).
BLOCKS = {"23": "register 23", "24": "register 24", CPU: "CPU 22",
          **{n: f"rate-command module {n}" for n in RATE_COMMANDS.values()},
          **{n: f"drift DAC {n}" for n in DRIFT_DACS},
          **{n: f"drift counter {n}" for n in DRIFT_COUNTERS},
          **{n: f"counter {n}" for n in COUNTERS}}


def read_only(state) -> sim_state.State:
    """``state`` with every array a read-only view of the same memory."""
    views = {}
    for name, a in state._asdict().items():
        v = a.view()
        v.flags.writeable = False
        views[name] = v
    return sim_state.State(**views)


def _axis_index(axis) -> int:
    if axis not in AXES:
        raise ValueError(f"axis {axis!r}: one of {AXES}")
    return AXES.index(axis)


class Board:
    """The hardware's writer between legs: each method writes and journals.

    Parameters
    ----------
    state : allsky.sim.state.State
        The mission's state, written in place.
    electronics : callable
        Returns the frame loop's current word lengths and scalings
        (:class:`allsky.sim.state.ElectronicsParams`; a ground command may amend them).
    note : callable
        ``note(kind, **fields)``: journals an entry at the mission's time and
        mode (:meth:`allsky.sim.mission.Mission.note`).
    pulse_weight_arcsec : float
        [arcsec] per converter pulse (counters 14, 16, 18).
    """

    def __init__(self, state, electronics, note, pulse_weight_arcsec):
        self._state = state
        self._electronics = electronics
        self._note = note
        self._pulse_arcsec = float(pulse_weight_arcsec)
        #: the state as read-only views (what the sequencer reads)
        self.view = read_only(state)

    # -- the journal entry every write makes ------------------------------------------
    def _register(self, register, word, value, unit, by, pulses=None, **extra):
        fields = {"register": register, "word": word, "value": float(value), "unit": unit}
        if pulses is not None:
            fields["pulses"] = int(pulses)
        fields.update(extra)
        fields["by"] = by
        self._note("register", **fields)

    def _drift_lsb_deg_h(self) -> float:
        return self._electronics().drift_lsb_arcsec_s / units.DEG_H2ARCSEC_S

    # -- switches ---------------------------------------------------------------------
    def switch(self, close=(), open_=(), step="", waits_for="", by=SEQUENCER):
        """Operate the switch bank (coupled pairs move together) and journal what moved.

        ``close`` and ``open_`` are switch numbers (1-19); ``step`` says what
        the sequencer had waited for (or the recovery that did it),
        ``waits_for`` what it waits for next. Opening S4-S6 ends a drift
        count: the drift counters' content is journaled; closing S1-S3 puts
        it on the drift DACs: each DAC's output, and the count it could not
        apply if beyond its full scale.

        ``by`` says who made the write (the journal's ``by``).
        """
        bank = self._state.switches
        before = bank.copy()
        switch_bank.operate(bank, close=close, open_=open_)
        moved_close = [k for k in range(1, len(bank)) if bank[k] and not before[k]
                       and k not in switch_bank.SELECTORS]
        moved_open = [k for k in range(1, len(bank)) if before[k] and not bank[k]
                      and k not in switch_bank.SELECTORS]
        if not (moved_close or moved_open):
            return
        self._note("switch", close=moved_close, open=moved_open, step=step,
                   waits_for=waits_for)
        lsb = self._drift_lsb_deg_h()
        bits = self._electronics().drift_dac_bits
        for a, axis in enumerate(AXES):
            counted = int(self._state.drift_counters[a])
            if wiring.ROUTING.drift_count_switch[a] in moved_open:
                self._register(DRIFT_COUNTERS[a], axis, counted * lsb, "deg/h", by,
                               pulses=counted)
            if wiring.ROUTING.drift_switch[a] in moved_close:
                # The DAC's code: the count, clipped to its word (dac.py, as Python).
                applied = int(python_of(dac)(counted, bits, 1))
                self._register(DRIFT_DACS[a], axis, applied * lsb, "deg/h", by,
                               pulses=applied, counted_pulses=counted)

    # -- counters ---------------------------------------------------------------------
    def clear_counters(self, by=SEQUENCER):
        """Clear up/down counters 14, 16, 18.

        ``by`` says who made the write (the journal's ``by``).
        """
        self._state.counters[:] = 0
        for numeral, axis in zip(COUNTERS, AXES):
            self._register(numeral, axis, 0.0, "arcsec", by, pulses=0)

    def preset_counters(self, arcsec, by=SEQUENCER):
        """Preset counters to the nearest pulse of ``arcsec`` (axis -> [arcsec]).

        ``by`` says who made the write (the journal's ``by``).
        """
        for axis, value in arcsec.items():
            a = _axis_index(axis)
            pulses = round(float(value) / self._pulse_arcsec)
            self._state.counters[a] = pulses
            self._register(COUNTERS[a], axis, pulses * self._pulse_arcsec, "arcsec", by,
                           pulses=pulses)

    def load_drift(self, pulses, by=SEQUENCER):
        """Load drift counters 13, 15, 17 with ``pulses`` (axis -> count).

        Each count is clipped to the counter's word; the drift DACs apply it
        while S1-S3 are closed.

        ``by`` says who made the write (the journal's ``by``).
        """
        bits = self._electronics().drift_counter_bits
        hi = (1 << (bits - 1)) - 1
        lsb = self._drift_lsb_deg_h()
        for axis, code in pulses.items():
            a = _axis_index(axis)
            code = min(max(int(code), -hi - 1), hi)
            self._state.drift_counters[a] = code
            self._register(DRIFT_COUNTERS[a], axis, code * lsb, "deg/h", by, pulses=code)

    def clear_drift(self, by=SEQUENCER):
        """Clear drift counters 13, 15, 17 (before the Mode 3 count).

        ``by`` says who made the write (the journal's ``by``).
        """
        self.load_drift(dict.fromkeys(AXES, 0), by=by)

    # -- rate-command modules -----------------------------------------------------------
    def set_rate_sign(self, axis, sign, by=SEQUENCER):
        """Set a rate-command module's direction: ``sign`` +1 or -1.

        Module 120 for ``axis`` "roll", 128 for "yaw"; ``by`` who set it.
        """
        if axis not in RATE_SIGN:
            raise ValueError(f"rate-command axis {axis!r}: one of {tuple(RATE_SIGN)}")
        if sign not in (1, -1):
            raise ValueError(f"rate-command direction {sign!r}: +1 or -1")
        self._state.rate_sign[RATE_SIGN[axis]] = sign
        self._register(RATE_COMMANDS[axis], axis, float(sign), "-", by)

    # -- registers ----------------------------------------------------------------------
    def load_word23(self, words, by=SEQUENCER):
        """Load words of register 23, ``words``: name -> value.

        The names are those of :data:`~allsky.computer.word_registers.WORD23`;
        ``by`` who loaded them.
        """
        for name, value in words.items():
            if name not in wr.WORD23:
                raise ValueError(f"register 23 has no word {name!r}: {tuple(wr.WORD23)}")
            self._state.word23[wr.WORD23[name]] = value
            self._register("23", name, float(self._state.word23[wr.WORD23[name]]), "-", by)

    def neutral_word23(self, by=SEQUENCER):
        """Load register 23 with its neutral words (no calibration).

        ``by`` says who made the write (the journal's ``by``).
        """
        neutral = wr.neutral_computed()
        self.load_word23({name: float(neutral[k]) for name, k in wr.WORD23.items()}, by=by)

    def load_word24(self, roll_deg=None, yaw_deg=None, by=SEQUENCER):
        """Load register 24's programmed ``roll_deg`` and/or ``yaw_deg`` [deg].

        The register holds them in arcsec; None leaves a word as it is;
        ``by`` who loaded them.
        """
        for word, value, slot in (("roll", roll_deg, wr.PROGRAMMED_ROLL),
                                  ("yaw", yaw_deg, wr.PROGRAMMED_YAW)):
            if value is None:
                continue
            self._state.word24[slot] = value * units.DEG2ARCSEC
            self._register("24", word, value, "deg", by)

    def calibrate(self, axis, turns, by=SEQUENCER) -> np.ndarray:
        """Calibration sequencer 19: counters 14/16/18 -> register 23 for ``axis``'s turn.

        ``turns`` is the signed whole turns flown (the rate command's sign
        times their number). Returns the counted angles [arcsec], roll,
        pitch, yaw; the words of the turn are journaled.

        ``by`` says who made the write (the journal's ``by``).
        """
        s = self._state
        counts = cal19.calibrate(axis, s.switches, s.counters, self._pulse_arcsec, turns,
                                 s.word23)
        for name in cal19.WORDS_OF_TURN[axis]:
            self._register("23", name, float(s.word23[wr.WORD23[name]]), "-", by)
        return counts

    # -- CPU 22 -------------------------------------------------------------------------
    def clear_cpu(self, by=SEQUENCER):
        """Clear CPU 22's working store.

        ``by`` says who made the write (the journal's ``by``).
        """
        self._state.cpu[:] = 0.0
        self._register(CPU, "all", 0.0, "-", by)

    def cpu_step(self, axis, counter_arcsec):
        """CPU 22 forms ``axis``'s error from a counter's content ``counter_arcsec``.

        The computer's own work on its store (as it does every step of a
        leg), not a load: no entry.
        """
        s = self._state
        cpu.target_step(_axis_index(axis), float(counter_arcsec), s.word23, s.word24, s.cpu)
