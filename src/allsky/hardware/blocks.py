"""The block table: each numeral of US 4,012,018, its block and the code for it.

One row per block (or per group of like blocks, listed roll, pitch, yaw):
the patent's reference numerals, what the block is, the modules and
functions of ``allsky`` that implement it, and its inputs and outputs with
units. Numerals are read from the patent's text (seed 002): Fig. 2, the
block diagram of the three channels and computer 111 (blocks 1-36, 39-41,
sun sensor 104, star tracker 105, rate-command modules 120 and 128, the
contacts and selectors 121-128 of S7/S8, lines 130, 131 and the dashed
line 132), and Fig. 1, the vehicle drawing (vehicle 100, ports 102/103,
jets 106/107, gas tank 108, bulkhead 109, control electronics module 110).
The patent uses 128 twice: the yaw rate-command module and the yaw contact
of S8. What each switch S1-S19 connects is the wiring table,
:mod:`allsky.hardware.wiring`.

``docs/blocks.md`` and the boxes of the block-diagram figure are generated
from this table; modules are named by their dotted path, so this table
imports none of them.
"""

from typing import NamedTuple

#: Kinds of row, in the order the documentation lists them, with their headings.
KINDS = {
    "block": "Blocks of the block diagram (Fig. 2)",
    "selector": "Selectors S7/S8: contacts and selector arms (Fig. 2)",
    "line": "Lines (Fig. 2)",
    "vehicle": "The vehicle drawing (Fig. 1)",
    "undrawn": "Parts the patent does not draw",
}


class Block(NamedTuple):
    """One row of the block table."""

    numerals: tuple  #: the patent's reference numerals (strings); () for undrawn parts
    name: str  #: what the block is
    label: str  #: short name for figures
    modules: tuple  #: dotted module paths implementing it; () when there is no code
    functions: tuple  #: names (functions, tables) in those modules
    io: str  #: inputs -> outputs [units], or why there is no code
    kind: str  #: key of :data:`KINDS`


def _b(numerals, name, label, modules, functions, io, kind="block"):
    return Block(tuple(numerals.split()), name, label, tuple(modules.split()),
                 tuple(functions.split()), io, kind)


#: The block table.
BLOCKS = (
    _b("1 2 3", "rate gyros (roll, pitch, yaw)", "Rate gyros", "allsky.hardware.gyro",
       "gyro_output", "body-angle increment of the frame [rad] -> rate [arcsec/s]"),
    _b("4 5 6", "summing amplifiers", "Summing amps", "allsky.hardware.summing_amp",
       "summing_amp", "gyro rate, drift, rate command [arcsec/s] -> converter input, "
       "line rate [arcsec/s]"),
    _b("7 9 11", "drift DACs", "Drift DACs", "allsky.hardware.dac", "dac",
       "drift-counter content [pulses] -> mean drift rate [arcsec/s]"),
    _b("8 10 12", "voltage-to-frequency converters", "V/F converters", "allsky.hardware.vfc",
       "vfc", "rate [arcsec/s] -> pulses in the frame [pulses]"),
    _b("13 15 17", "drift up/down counters", "Drift counters",
       "allsky.hardware.updown_counter", "count",
       "pulses (through S4-S6) -> content [pulses], overflow flag"),
    _b("14 16 18", "up/down counters", "Up/down counters", "allsky.hardware.updown_counter",
       "count", "pulses -> content [pulses], overflow flag"),
    _b("19", "calibration sequencer", "Calibration seq.",
       "allsky.computer.calibration_sequencer", "calibrate",
       "counters 14/16/18 through S7 [pulses] -> register 23 [-]"),
    _b("20", "master sequencer (mode table and its interpreter)", "Master seq.",
       "allsky.sequencer.master_sequencer allsky.sequencer.modes", "run_mode MODE_TABLE",
       "watched error signals [arcsec] -> switch actions S1-S6, S9-S19, legs"),
    _b("21", "computer sequencer", "Computer seq.", "allsky.computer.computer_sequencer",
       "sequencer_step", "frame number -> selector position S7/S8 (axis or -1)"),
    _b("22", "CPU", "CPU", "allsky.computer.cpu",
       "calibrate_roll calibrate_yaw target_step mode6_preset_arcsec",
       "counter [arcsec], registers 23/24 -> axis error [arcsec]"),
    _b("23", "computed word register", "Computed word", "allsky.computer.word_registers",
       "neutral_computed computed_as_dict", "scale factors and cross-coupling factors [-]"),
    _b("24", "programmed word register", "Programmed word", "allsky.computer.word_registers",
       "PROGRAMMED_ROLL PROGRAMMED_YAW", "programmed roll and yaw angles [arcsec]"),
    _b("25 26 27", "storage registers", "Storage registers",
       "allsky.hardware.storage_register", "store", "error [arcsec] -> code [LSB]"),
    _b("28 29 30", "axis DACs", "DACs", "allsky.hardware.dac", "dac",
       "register code [LSB] -> position input [arcsec]"),
    _b("31 32 33", "control amplifiers", "Control amps", "allsky.hardware.control_amp",
       "control_amp", "position [arcsec], rate [arcsec/s] -> command [V]"),
    _b("34 35 36", "pulse-width pulse-frequency modulators", "PWPF modulators",
       "allsky.hardware.pwpf", "pwpf_step", "command [V] -> valve command -1/0/+1"),
    _b("39 40 41", "jet couples", "Jets", "allsky.hardware.jets", "jets",
       "valve commands -> torque [N m], propellant used [kg]"),
    _b("104", "sun sensor", "Sun sensor", "allsky.hardware.sun_sensor", "sun_sensor",
       "Sun direction, body axes [-] -> pitch, yaw error [arcsec], Sun present"),
    _b("105", "star tracker", "Star tracker", "allsky.hardware.star_tracker", "star_tracker",
       "attitude quaternion [-] -> yaw, pitch error [arcsec], star present"),
    _b("111", "computer (19-24 together, serviced once a frame)", "Computer",
       "allsky.computer allsky.sim.frame_loop", "compute",
       "counters [pulses] -> storage registers 25-27 [LSB]"),
    _b("120 128", "rate-command modules (roll, yaw)", "Rate commands",
       "allsky.hardware.rate_command", "rate_command",
       "commanded rate, direction -> rate [arcsec/s]"),
    _b("121 125 127", "contacts of S7 (roll, pitch, yaw counter -> CPU 22)", "S7 contacts",
       "allsky.hardware.switch_bank", "select", "selector position 0/1/2", "selector"),
    _b("122", "selector arm of S7 (to CPU 22)", "S7 selector", "allsky.hardware.wiring",
       "SELECTORS", "selected axis 0/1/2", "selector"),
    _b("123", "selector arm of S8 (from CPU 22)", "S8 selector", "allsky.hardware.wiring",
       "SELECTORS", "selected axis 0/1/2", "selector"),
    _b("124 126 128", "contacts of S8 (CPU 22 -> roll, pitch, yaw storage register; the "
       "patent numbers the yaw contact 128, like the yaw rate-command module)", "S8 contacts",
       "allsky.hardware.switch_bank", "select", "selector position 0/1/2", "selector"),
    _b("130 131", "rate lines (summing amplifier 4, 6 -> control amplifier 31, 33, via S18, "
       "S19)", "Rate lines", "allsky.hardware.summing_amp", "summing_amp",
       "line rate = compensated rate - rate command [arcsec/s]", "line"),
    _b("132", "dashed line: S7 and S8 move together, stepped by computer sequencer 21",
       "Coupling S7/S8", "allsky.hardware.wiring", "COUPLED_PAIRS", "mechanical coupling",
       "line"),
    _b("100", "instrument-bearing space vehicle (rigid body)", "Vehicle: rigid body "
       "(attitude, body rates)", "allsky.vehicle.plant", "rk4_step",
       "torque [N m] -> attitude, body rate [rad/s], angle increment [rad]", "vehicle"),
    _b("102 103", "experiment-viewing ports of the instruments", "Ports", "", "",
       "no code: the instruments look along +x, the roll axis (docs/conventions.md)",
       "vehicle"),
    _b("106 107", "control jets of the vehicle drawing (each of jets 39-41 is one of them)",
       "Jets", "allsky.hardware.jets", "jets", "see jets 39-41", "vehicle"),
    _b("108", "control-jet gas tank", "Gas tank", "allsky.hardware.jets", "jets",
       "propellant remaining [kg] (State.propellant_kg), drawn by the firing jets",
       "vehicle"),
    _b("109", "bulkhead carrying the gyros, electronics module and computer", "Bulkhead",
       "", "", "no code: structure", "vehicle"),
    _b("110", "control electronics module (with computer 111, the three channels)",
       "Control electronics", "allsky.hardware", "",
       "the analogue blocks 1-18 and 25-36, one module each", "vehicle"),
    _b("", "Mode 1 sun-acquisition controller (a solar-pointing rocket's)", "Mode 1 controller",
       "allsky.hardware.sun_acquisition", "sun_acquisition",
       "coarse and fine Sun, gyro rates -> control-amplifier inputs [arcsec], [arcsec/s]",
       "undrawn"),
    _b("", "coarse sun eyes (Mode 1)", "Coarse sun eyes", "allsky.hardware.sun_sensor",
       "coarse_sun", "Sun direction, body axes [-] -> noisy Sun direction [-]", "undrawn"),
    _b("", "the per-frame loop, in diagram order", "Frame loop", "allsky.sim.frame_loop",
       "run_leg", "a leg (program, watch, timeout) -> exit code, leg time [s]", "undrawn"),
    _b("", "the mission runner (modes in sequence, snapshots to resume from)", "Mission",
       "allsky.sim.mission", "Mission run_mission", "scenario -> mission summary, telemetry",
       "undrawn"),
    _b("", "dither generator, feed-forward and detector (comparison mode, seed 000)", "Dither",
       "allsky.sequencer.dither allsky.sequencer.dither_mode",
       "dither_command fft_amplitude analyse dither_analysis",
       "dither command [arcsec], feed-forward [V]; record -> scale factors [-]", "undrawn"),
)
assert all(b.kind in KINDS for b in BLOCKS)


def by_numeral(numeral: str) -> tuple:
    """The rows that carry ``numeral`` (two for 128, which the patent uses twice)."""
    return tuple(b for b in BLOCKS if numeral in b.numerals)


def numerals() -> list:
    """Every numeral of the table, in table order, each once."""
    seen = []
    for b in BLOCKS:
        seen += [n for n in b.numerals if n not in seen]
    return seen
