"""Stages of the frame loop (allsky.sim.frame_loop), each in a tiny harness of its own.

Truth: the connections of SPEC section 3 (US 4,012,018, Fig. 2) - which
switch puts which signal on which control amplifier or summing amplifier -
and, for the position sums, the written-out expressions the loop used
before it read the wiring table, to the last bit (including -0.0)::

    amp 31:  S12 * tracker_yaw + S9 * dac28
    amp 32: (S13 * tracker_pitch + S14 * sun_pitch) + S10 * dac29
    amp 33:  S15 * sun_yaw + S11 * dac30
"""

import itertools

import numpy as np
import pytest

from allsky.config.scenario import load_scenario
from allsky.hardware.control_amp import ControlParams
from allsky.hardware.switch_bank import new_bank, operate
from allsky.hardware.updown_counter import WRAP
from allsky.hardware.vfc import VfcParams
from allsky.hardware.wiring import N_POSITION_SOURCES, ROUTING
from allsky.sequencer.dither import DitherParams
from allsky.sequencer.legs import PROGRAM_MODE1, PROGRAM_NONE
from allsky.sim import frame_loop
from allsky.sim.mission import Mission
from allsky.sim.state import ElectronicsParams

LSB_ARCSEC = 0.25  # register / DAC 28-30 step (scenario default)
RATE_CMD_ARCSEC_S = 1.5 * 3600.0  # modules 120, 128: 1.5 deg/s (patent)
EL = ElectronicsParams(counter_bits=28, drift_counter_bits=16, overflow_mode=WRAP,
                       drift_dac_bits=12, drift_lsb_arcsec_s=0.5, register_bits=16,
                       register_lsb_arcsec=LSB_ARCSEC, rate_command_arcsec_s=RATE_CMD_ARCSEC_S,
                       computer_step_frames=1)
N_ROUTES = len(ROUTING.position_routes)
REGISTERS = np.array([100, -200, 300], dtype=np.int64)  # DACs 28/29/30: 25", -50", 75"
FINE = np.array([11.0, 22.0, 1.0])  # sun sensor 104: pitch, yaw [arcsec], present
TRK = np.array([33.0, 44.0, 1.0])  # star tracker 105: yaw, pitch [arcsec], present
LINE = np.array([1.0, 2.0, 3.0])  # lines 130/131 (and pitch's loop rate) [arcsec/s]


def wire(bank, rate_sign=(1, 1)):
    """The leg's gates and position gains read from ``bank`` (frame_loop.wire_leg)."""
    gates, gain = np.full((frame_loop.N_GATES, 3), np.nan), np.full(N_ROUTES, np.nan)
    frame_loop.wire_leg(ROUTING, EL, bank, np.array(rate_sign, dtype=np.int64), gates, gain)
    return gates, gain


def route(*closed, registers=REGISTERS, fine=FINE, trk=TRK):
    """Tiny harness: the route stage with switches ``closed``; returns (pos, rate)."""
    bank = new_bank()
    bank[list(closed)] = 1
    _, gain = wire(bank)
    pos, rate = np.full(3, np.nan), np.full(3, np.nan)
    frame_loop.route(EL, ROUTING.position_routes, gain, registers, fine, trk, LINE,
                     np.zeros(N_POSITION_SOURCES), pos, rate)
    return pos, rate


# -- route: S9-S15 onto control amplifiers 31-33 ----------------------------------------

def test_only_s12_puts_the_tracker_yaw_on_amplifier_31():
    pos, rate = route(12)
    assert pos.tolist() == [33.0, 0.0, 0.0]
    assert rate.tolist() == LINE.tolist()  # the rate inputs are lines 130/131 always


def test_s9_adds_dac_28():
    pos, _ = route(12, 9)
    assert pos.tolist() == [33.0 + 100 * LSB_ARCSEC, 0.0, 0.0]


@pytest.mark.parametrize("switch, axis, value", [
    (9, 0, 100 * LSB_ARCSEC),  # roll DAC 28 -> 31
    (10, 1, -200 * LSB_ARCSEC),  # pitch DAC 29 -> 32
    (11, 2, 300 * LSB_ARCSEC),  # yaw DAC 30 -> 33
    (12, 0, TRK[0]),  # tracker yaw -> 31
    (13, 1, TRK[1]),  # tracker pitch -> 32
    (14, 1, FINE[0]),  # sun pitch -> 32
    (15, 2, FINE[1]),  # sun yaw -> 33
])
def test_each_position_switch_alone_feeds_its_own_amplifier_only(switch, axis, value):
    pos, _ = route(switch)
    expect = [0.0, 0.0, 0.0]
    expect[axis] = value
    assert pos.tolist() == expect


def test_all_open_puts_nothing_on_the_amplifiers():
    pos, _ = route()
    assert pos.tolist() == [0.0, 0.0, 0.0]


def test_dacs_28_to_30_clip_at_their_word_length():
    pos, _ = route(9, 10, 11, registers=np.array([1 << 20, -(1 << 20), 5], dtype=np.int64))
    full = (1 << 15) * LSB_ARCSEC  # 16-bit DAC
    assert pos.tolist() == [(full - LSB_ARCSEC), -full, 5 * LSB_ARCSEC]


def _bits(x):
    return np.array(x, dtype=np.float64).view(np.int64).tolist()


# Sources that make the order of the sums and the sign of zero show: -0.0,
# values that round differently as (a + b) + c and a + (b + c).
AWKWARD = [(-0.0, -0.0, -0.0, -0.0, -0.0, -0.0, -0.0),
           (-1.0, -2.0, -3.0, -4.0, -5.0, -6.0, -7.0),
           (0.1, 1e16, 1.0, 0.3, 0.2, -1e16, 0.7),
           (-0.0, 1e16, -1e16, 3.0, 5e-324, 1.0, -2.5)]


@pytest.mark.parametrize("src", AWKWARD)
def test_position_sums_round_like_the_written_out_expressions(src):
    trk_yaw, trk_pitch, sun_pitch, sun_yaw, d28, d29, d30 = src
    routes = ROUTING.position_routes
    for closed in itertools.product((0, 1), repeat=7):
        bank = new_bank()
        s9, s10, s11, s12, s13, s14, s15 = closed
        bank[9:16] = closed
        _, gain = wire(bank)
        pos = np.full(3, np.nan)
        frame_loop.route_positions(routes, gain, np.array(src), pos)
        expect = [s12 * trk_yaw + s9 * d28,
                  s13 * trk_pitch + s14 * sun_pitch + s10 * d29,
                  s15 * sun_yaw + s11 * d30]
        assert _bits(pos) == _bits(expect), closed


def test_position_routes_are_grouped_by_axis():
    """route_positions sums an axis's rows in one run: rows must not interleave axes."""
    axes = ROUTING.position_routes[:, 2].tolist()
    assert axes == sorted(axes)


def test_the_gains_follow_the_bank():
    bank = new_bank()
    operate(bank, close=(1, 5, 12, 10, 17, 19))
    gates, gain = wire(bank, rate_sign=(1, -1))
    assert gates[frame_loop.GATE_DRIFT].tolist() == [1.0, 0.0, 0.0]
    assert gates[frame_loop.GATE_DRIFT_COUNT].tolist() == [0.0, 1.0, 0.0]
    assert gates[frame_loop.GATE_COMMAND].tolist() == [0.0, 0.0, 1.0]
    # Modules 120 and 128 keep their command (and direction) with the switch open.
    assert gates[frame_loop.COMMAND_ARCSEC_S].tolist() == [RATE_CMD_ARCSEC_S, 0.0,
                                                           -RATE_CMD_ARCSEC_S]
    assert gates[frame_loop.GATE_RATE_MODE].tolist() == [0.0, 0.0, 1.0]
    closed = {int(k) for k, g in zip(ROUTING.position_routes[:, 0], gain) if g == 1.0}
    assert closed == {10, 12}
    assert set(gain.tolist()) == {0.0, 1.0}


# -- sum_and_count: S1-S6, S16, S17 ---------------------------------------------------------

VFC = VfcParams(pulse_weight_arcsec=0.5, max_rate_pps=1e9)
DT_S = 0.25  # binary fractions throughout: pulse counts come out exact


def sum_and_count(closed, gyro, drift_counters=(0, 0, 0), rate_sign=(1, 1), frames=1):
    """Tiny harness: summing amplifiers, converters and counters for ``frames`` frames."""
    bank = new_bank()
    operate(bank, close=closed)
    gates, _ = wire(bank, rate_sign)
    drift = np.array(drift_counters, dtype=np.int64)
    counters = np.zeros(3, dtype=np.int64)
    comp, line = np.zeros(3), np.zeros(3)
    for _ in range(frames):
        frame_loop.sum_and_count(EL, VFC, DT_S, gates, np.array(gyro, dtype=float), drift,
                                 counters, np.zeros(3), np.zeros(6, dtype=np.int64), comp, line)
    return comp, line, counters, drift


def test_s16_puts_the_roll_rate_command_on_line_130_only():
    comp, line, _, _ = sum_and_count((16, 18), [100.0, 100.0, 100.0])
    assert comp.tolist() == [100.0, 100.0, 100.0]  # converters see the vehicle's rate
    assert line.tolist() == [100.0 - RATE_CMD_ARCSEC_S, 100.0, 100.0]


def test_s17_puts_the_yaw_rate_command_with_module_128s_direction():
    _, line, _, _ = sum_and_count((17, 19), [0.0, 0.0, 0.0], rate_sign=(1, -1))
    assert line.tolist() == [0.0, 0.0, RATE_CMD_ARCSEC_S]


def test_s1_to_s3_subtract_the_drift_dacs():
    # Drift DAC code 4 at 0.5 "/s per count: 2 "/s subtracted from each axis it is switched into.
    comp, line, _, _ = sum_and_count((1, 3), [10.0, 10.0, 10.0], drift_counters=(4, 4, 4))
    assert comp.tolist() == [8.0, 10.0, 8.0]
    assert line.tolist() == comp.tolist()


def test_s4_to_s6_gate_the_drift_counters():
    # 10 "/s for 4 frames of 0.25 s: 10", 20 pulses of 0.5" on every counter 14/16/18.
    _, _, counters, drift = sum_and_count((5,), [10.0, 10.0, 10.0], frames=4)
    assert counters.tolist() == [20, 20, 20]
    assert drift.tolist() == [0, 20, 0]


# -- control: S18/S19 hold the integral ---------------------------------------------------

CONTROL = ControlParams(np.full(3, 1e-3), np.full(3, 5e-4), np.full(3, 500.0), 10.0, 20.0,
                        30.0)
NO_DITHER = DitherParams(np.zeros(3), np.ones(3), np.zeros((3, 3)), np.zeros(3))


def control_integral(closed, program=PROGRAM_NONE, frames=10):
    bank = new_bank()
    operate(bank, close=closed)
    gates, _ = wire(bank)
    integral = np.zeros(3)
    volts = np.zeros(3)
    for _ in range(frames):
        frame_loop.control(CONTROL, NO_DITHER, gates, program, False, 0.0, DT_S,
                           np.full(3, 10.0), np.zeros(3), integral, np.zeros(3), np.zeros(3),
                           volts)
    return integral


def test_s18_holds_the_roll_integral_at_zero():
    # 10" for 10 frames of 0.25 s with T_i = 20 s: 1.25" on every integrating axis.
    assert control_integral((16, 18)) == pytest.approx([0.0, 1.25, 1.25])
    assert control_integral((17, 19)) == pytest.approx([1.25, 1.25, 0.0])
    assert control_integral(()) == pytest.approx([1.25, 1.25, 1.25])


def test_the_mode_1_controller_holds_every_integral():
    assert control_integral((), program=PROGRAM_MODE1).tolist() == [0.0, 0.0, 0.0]


# -- the loop is compiled with its arrays declared not to alias (jit.njit_noalias) ----------

def _array_leaves(value, path="", out=None):
    """``(path, array)`` of every array in ``value``, through nested (named) tuples."""
    out = [] if out is None else out
    if isinstance(value, np.ndarray):
        out.append((path, value))
    elif isinstance(value, tuple):
        for name, v in zip(getattr(value, "_fields", None) or range(len(value)), value):
            _array_leaves(v, f"{path}.{name}", out)
    return out


@pytest.mark.parametrize("case", ["jets", "wheels", "fault", "dither"])
def test_no_array_the_loop_writes_shares_memory_with_another(monkeypatch, case):
    # njit_noalias promises LLVM that no two array arguments overlap; the promise holds
    # only if the mission never hands the loop an array that it writes (state, leg,
    # buffers) beside another view of the same memory.
    from allsky.config import scenario_from_dict
    from allsky.sim.mission import DITHER_PLAN, LEGACY_PLAN

    data = load_scenario("stuck-jet-roll-calibration" if case == "fault" else None).as_dict()
    if case == "wheels":
        data["actuators"]["kind"] = "wheels"
    overlaps, legs = set(), [0]
    original = frame_loop.run_leg

    def checked(*args):
        legs[0] += 1
        arrays = _array_leaves(args)
        written = {id(a) for _, a in _array_leaves(args[1:])}
        for i, (path_a, a) in enumerate(arrays):
            for path_b, b in arrays[i + 1:]:
                if (id(a) in written or id(b) in written) and a.size and b.size \
                        and np.shares_memory(a, b):
                    overlaps.add((path_a, path_b))
        return original(*args)

    monkeypatch.setattr(frame_loop, "run_leg", checked)
    Mission(scenario_from_dict(data), plan=DITHER_PLAN if case == "dither" else LEGACY_PLAN
            ).run()
    assert legs[0] > 5 and not overlaps, sorted(overlaps)
