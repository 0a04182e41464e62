"""The wiring of the block diagram: what every switch S1-S19 connects.

The bank: S1, S2, S3, S4, S5, S6, S7, S8, S9, S10, S11, S12, S13, S14, S15,
S16, S17, S18, S19; lines 130 and 131; selectors 122 and 123 joined by the
dashed line 132.

This table is the one place that says which block feeds which, through
which switch (US 4,012,018, Fig. 2; SPEC section 3). The frame loop routes
its signals through the index arrays derived below (:data:`ROUTING`); the
documentation, the figures' labels and the step display read the same
table, so the wiring is written exactly once.

Each :class:`Switch` names its source and destination by patent numeral and
port. Ports of a destination:

``drift``
    the drift DAC's output, subtracted in a summing amplifier (S1-S3);
``drift_count``
    a converter's pulses, counted by a drift counter (S4-S6);
``counter_read`` / ``register_write``
    the selectors S7/S8 of computer 111, stepped together by computer
    sequencer 21 (contacts 121/125/127 and 124/126/128);
``position``
    a position input of a control amplifier (S9-S15);
``rate_command``
    a rate-command module into a summing amplifier (S16, S17);
``rate_mode``
    the summing amplifier's line 130/131 into a control amplifier (S18,
    S19). The model wires these lines permanently as the loops' rate
    damping (docs/assumptions.md); closing S18/S19, always together with
    S16/S17, turns the amplifier into a rate follower: its position
    integral is held at zero.
"""

from typing import NamedTuple

import numpy as np

from allsky.vocabulary import AXES

ROLL, PITCH, YAW = 0, 1, 2
NONE = -1  #: no axis / no switch in the index arrays


class Switch(NamedTuple):
    """One switch of the bank and the connection it makes when closed."""

    number: int  #: k of Sk
    source: str  #: numeral of the source block
    source_port: str  #: which output of the source ("" = its only output)
    destination: str  #: numeral of the destination block
    port: str  #: which input of the destination (see the module docstring)
    axis: int  #: ROLL, PITCH or YAW
    coupled_with: int  #: number of the mechanically coupled switch (0 = none)
    selector: bool  #: True for the single-pole three-position selectors S7/S8
    text: str  #: the connection in words, for tables and labels


def _s(number, source, source_port, destination, port, axis, text, coupled_with=0,
       selector=False):
    return Switch(number, source, source_port, destination, port, axis, coupled_with,
                  selector, text)


#: The switch bank, S1 to S19, in the patent's numbering.
SWITCHES = (
    _s(1, "7", "", "4", "drift", ROLL, "roll drift DAC 7 -> summing amplifier 4"),
    _s(2, "9", "", "5", "drift", PITCH, "pitch drift DAC 9 -> summing amplifier 5"),
    _s(3, "11", "", "6", "drift", YAW, "yaw drift DAC 11 -> summing amplifier 6"),
    _s(4, "8", "", "13", "drift_count", ROLL, "roll VFC 8 -> roll drift counter 13"),
    _s(5, "10", "", "15", "drift_count", PITCH, "pitch VFC 10 -> pitch drift counter 15"),
    _s(6, "12", "", "17", "drift_count", YAW, "yaw VFC 12 -> yaw drift counter 17"),
    _s(7, "14/16/18", "", "22", "counter_read", NONE,
       "counters 14/16/18 -> CPU 22 (selector 122, contacts 121/125/127)",
       coupled_with=8, selector=True),
    _s(8, "22", "", "25/26/27", "register_write", NONE,
       "CPU 22 -> storage registers 25/26/27 (selector 123, contacts 124/126/128)",
       coupled_with=7, selector=True),
    _s(9, "28", "", "31", "position", ROLL, "roll DAC 28 -> control amplifier 31"),
    _s(10, "29", "", "32", "position", PITCH, "pitch DAC 29 -> control amplifier 32"),
    _s(11, "30", "", "33", "position", YAW, "yaw DAC 30 -> control amplifier 33"),
    _s(12, "105", "yaw", "31", "position", ROLL,
       "star tracker 105 yaw output -> control amplifier 31"),
    _s(13, "105", "pitch", "32", "position", PITCH,
       "star tracker 105 pitch output -> control amplifier 32"),
    _s(14, "104", "pitch", "32", "position", PITCH,
       "sun sensor 104 pitch output -> control amplifier 32"),
    _s(15, "104", "yaw", "33", "position", YAW,
       "sun sensor 104 yaw output -> control amplifier 33"),
    _s(16, "120", "", "4", "rate_command", ROLL,
       "roll rate-command module 120 -> summing amplifier 4", coupled_with=18),
    _s(17, "128", "", "6", "rate_command", YAW,
       "yaw rate-command module 128 -> summing amplifier 6", coupled_with=19),
    _s(18, "4", "line 130", "31", "rate_mode", ROLL,
       "summing amplifier 4, line 130 -> control amplifier 31 (rate command followed)",
       coupled_with=16),
    _s(19, "6", "line 131", "33", "rate_mode", YAW,
       "summing amplifier 6, line 131 -> control amplifier 33 (rate command followed)",
       coupled_with=17),
)
N_SWITCHES = len(SWITCHES)
#: Switch number -> its record.
BY_NUMBER = {s.number: s for s in SWITCHES}
#: The mechanically coupled pairs (dashed line 132 joins S7 and S8), each pair once.
COUPLED_PAIRS = tuple((s.number, s.coupled_with) for s in SWITCHES
                      if s.coupled_with and s.number < s.coupled_with)
#: The selectors, whose bank entry holds an axis instead of open/closed.
SELECTORS = tuple(s.number for s in SWITCHES if s.selector)

#: Sources a position route can carry, in the order of the loop's source vector.
POSITION_SOURCES = (("105", "yaw"), ("105", "pitch"), ("104", "pitch"), ("104", "yaw"),
                    ("28", ""), ("29", ""), ("30", ""))
SRC_TRACKER_YAW, SRC_TRACKER_PITCH, SRC_SUN_PITCH, SRC_SUN_YAW = 0, 1, 2, 3
SRC_DAC = 4  #: DACs 28, 29, 30 are sources SRC_DAC + axis
N_POSITION_SOURCES = len(POSITION_SOURCES)


def _per_axis(port) -> np.ndarray:
    """Switch number on ``port`` for each axis (NONE where the axis has none)."""
    out = np.full(3, NONE, dtype=np.int64)
    for s in SWITCHES:
        if s.port == port:
            out[s.axis] = s.number
    return out


def _position_routes() -> np.ndarray:
    """(switch, source index, axis) of every position input, in table order per axis."""
    rows = [(s.number, POSITION_SOURCES.index((s.source, s.source_port)), s.axis)
            for axis in range(3) for s in _position_order(axis)]
    return np.array(rows, dtype=np.int64).reshape(-1, 3)


def _position_order(axis):
    """Position switches of ``axis``: optical inputs first, then the register's DAC.

    The order is the order in which the loop adds the inputs (it fixes the
    rounding of the sum).
    """
    sw = [s for s in SWITCHES if s.port == "position" and s.axis == axis]
    return sorted(sw, key=lambda s: (s.source in ("28", "29", "30"), s.number))


#: The rate-command modules in table order; ``State.rate_sign`` holds their directions.
RATE_COMMAND_MODULES = tuple(s.source for s in SWITCHES if s.port == "rate_command")
#: Rate-command module by the axis it turns ("roll": 120, "yaw": 128), and its slot in
#: ``State.rate_sign``.
RATE_COMMAND_OF_AXIS = {AXES[s.axis]: s.source for s in SWITCHES
                        if s.port == "rate_command"}
RATE_SIGN_SLOT = {axis: RATE_COMMAND_MODULES.index(n) for axis, n in RATE_COMMAND_OF_AXIS.items()}


def _rate_command_module() -> np.ndarray:
    """Index into :data:`RATE_COMMAND_MODULES` of each axis's module (NONE where none)."""
    out = np.full(3, NONE, dtype=np.int64)
    for s in SWITCHES:
        if s.port == "rate_command":
            out[s.axis] = RATE_COMMAND_MODULES.index(s.source)
    return out


def _position_switches_from(source) -> np.ndarray:
    """Numbers of the position switches carrying an output of block ``source``."""
    return np.array([s.number for s in SWITCHES if s.port == "position" and s.source == source],
                    dtype=np.int64)


class Routing(NamedTuple):
    """The wiring as index arrays for the compiled frame loop."""

    drift_switch: np.ndarray  #: (3,) switch gating drift DAC -> summing amplifier, per axis
    drift_count_switch: np.ndarray  #: (3,) switch gating VFC -> drift counter, per axis
    rate_command_switch: np.ndarray  #: (3,) switch gating rate command -> summing amp (or NONE)
    rate_mode_switch: np.ndarray  #: (3,) switch putting the amplifier in rate mode (or NONE)
    position_routes: np.ndarray  #: (n, 3) int64 rows (switch, source index, axis)
    rate_command_module: np.ndarray  #: (3,) index into RATE_COMMAND_MODULES per axis (or NONE)
    sun_switches: np.ndarray  #: switches routing sun sensor 104 outputs (the Sun is in use)
    tracker_switches: np.ndarray  #: switches routing star tracker 105 outputs (the star in use)


#: The wiring table in the form the frame loop reads.
ROUTING = Routing(
    drift_switch=_per_axis("drift"),
    drift_count_switch=_per_axis("drift_count"),
    rate_command_switch=_per_axis("rate_command"),
    rate_mode_switch=_per_axis("rate_mode"),
    position_routes=_position_routes(),
    rate_command_module=_rate_command_module(),
    sun_switches=_position_switches_from("104"),
    tracker_switches=_position_switches_from("105"),
)


def label(number: int) -> str:
    """Short label of switch ``number`` for figures: ``"S12 tracker yaw -> 31"``."""
    s = BY_NUMBER[number]
    src = {"104": "sun", "105": "tracker"}.get(s.source, s.source)
    port = f" {s.source_port}" if s.source_port and not s.source_port.startswith("line") else ""
    return f"S{number} {src}{port} -> {s.destination}"
