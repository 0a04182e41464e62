"""The mode table of master sequencer 20 against SPEC section 4, and its interpreter.

Truth: the switch actions and exits of SPEC.md section 4 (patent US 4,012,018,
Modes 1 to 6-2, written out below per mode), the telemetry codes of
docs/telemetry.md (1 ... 5, 6.1, 6.2; 7 for the dither comparison mode), and
the calibration arithmetic of SPEC section 4: a counted angle equal to the
true 360 deg turn gives a scale factor of exactly 1 and no cross-coupling.
"""

import numpy as np
import pytest

from allsky.computer import word_registers as wr
from allsky.computer.calibration_sequencer import FULL_TURN_ARCSEC
from allsky.config.scenario import load_scenario
from allsky.sequencer import legs, modes
from allsky.sequencer import master_sequencer as ms
from allsky.sim import frame_loop
from allsky.sim.mission import DITHER_PLAN, LEGACY_PLAN, Mission

#: SPEC section 4, column "switch actions", as (opened, closed) per switch step in order.
#: Mode 4 and 6-1 also open S12 for the turn (closed since Mode 2; the patent closes it
#: again at the re-acquisition, and 6-1 opens it explicitly); the dither mode flies in the
#: hold that ends Mode 3 and operates no switch.
SPEC_SWITCH_ACTIONS = {
    "1": [((), (14, 15))],
    "2": [((), (16, 18)), ((16, 18), (12,))],
    "3": [((), (4, 5, 6)), ((4, 5, 6), (1, 2, 3))],
    "4": [((12,), (16, 18)), ((16, 18), (12,))],
    "5": [((14,), (13,)), ((15,), (17, 19)), ((17, 19), (15,)), ((13,), (14,))],
    "6-1": [((12,), (16, 18)), ((16, 18), (9,))],
    "6-2": [((14, 15), (10, 17, 19)), ((17, 19), (11,))],
    "dither": [],
}
#: Switches closed at each mode's end (SPEC section 4 followed from an all-open bank).
SPEC_CLOSED_AT_END = {
    "1": {14, 15},
    "2": {12, 14, 15},
    "3": {1, 2, 3, 12, 14, 15},
    "4": {1, 2, 3, 12, 14, 15},
    "5": {1, 2, 3, 12, 14, 15},
    "dither": {1, 2, 3, 12, 14, 15},
    "6-1": {1, 2, 3, 9, 14, 15},
    "6-2": {1, 2, 3, 9, 10, 11},
}
TELEMETRY_CODES = {"1": 1.0, "2": 2.0, "3": 3.0, "4": 4.0, "5": 5.0, "6-1": 6.1, "6-2": 6.2,
                   "hold": 6.3, "reacquire": 6.4, "recycle": 6.5, "direct": 6.6,
                   "standby": 6.7, "references": 6.8, "restart": 6.9, "dither": 7.0}


def test_every_mode_of_every_plan_is_in_the_table():
    assert modes.PLANS == {"legacy": LEGACY_PLAN, "dither": DITHER_PLAN}
    for plan in modes.PLANS.values():
        assert set(plan) <= set(modes.BY_NAME), plan
    assert LEGACY_PLAN == ("1", "2", "3", "4", "5", "6-1", "6-2")
    assert DITHER_PLAN == ("1", "2", "3", "dither", "6-1", "6-2")


def test_codes_are_the_telemetry_codes_and_every_mode_has_a_title():
    assert modes.MODE_CODE == TELEMETRY_CODES
    assert all(modes.MODE_TITLE[name] for name in modes.BY_NAME)


@pytest.mark.parametrize("name", sorted(SPEC_SWITCH_ACTIONS))
def test_switch_actions_are_the_specs(name):
    got = [(tuple(sorted(s.open_)), tuple(sorted(s.close)))
           for s in modes.BY_NAME[name].steps if isinstance(s, modes.Operate)]
    assert got == SPEC_SWITCH_ACTIONS[name]


def test_switch_set_at_each_mode_end_is_the_specs():
    for plan in modes.PLANS.values():
        for name, closed in modes.closed_after(plan).items():
            assert set(closed) == SPEC_CLOSED_AT_END[name], name


def test_every_action_is_a_documented_function_and_every_word_is_known():
    modes.check()
    for name, f in ms.ACTIONS.items():
        assert f.__name__ == name and f.__doc__, name
    for table in (modes.PROGRAMS, modes.WATCHES, modes.SIGNALS):
        codes = [t.code for t in table.values()]
        assert len(set(codes)) == len(codes)
    assert {t.code for t in modes.SIGNALS.values()} == set(range(legs.N_SIGNALS))
    assert modes.signal_mask(modes.OPTICAL) == legs.SETTLE_OPTICAL


@pytest.mark.parametrize("bad, words", [
    (modes.Wait("x", "none", "handover", ("sun yaw", "sun pitch")), "2 signals"),
    (modes.Wait("x", "none", "settle"), "0 signals"),
    (modes.Wait("x", "none", "elapsed", hold="forever"), "unknown duration"),
    (modes.Wait("x", "warp", "settle", ("sun yaw",)), "unknown program"),
    (modes.Do("reboot"), "unknown action"),
    (modes.Operate(), "no switch"),
    (modes.Wait("x", "none", "settle", ("sun yaw",), carry_settle=True), "no wait before timed"),
])
def test_check_refuses_a_step_outside_the_vocabulary(bad, words):
    table = (modes.Mode("x", 9.0, "test", (bad,), "done"),)
    with pytest.raises(ValueError, match=words):
        modes.check(table)


def test_a_carried_settle_time_needs_a_wait_that_timed_the_same_signals():
    timed = modes.Wait("count", "none", "elapsed", modes.OPTICAL, hold="drift count")
    carry = modes.Wait("x", "none", "settle", modes.OPTICAL, carry_settle=True)
    # Its steps pass; only the plans, which name modes of the real table, are missing.
    with pytest.raises(ValueError, match="names modes not in the table"):
        modes.check((modes.Mode("x", 9.0, "test", (timed, modes.Operate(close=(1,)), carry),
                                "d"),))
    other = modes.Wait("x", "none", "settle", ("sun yaw",), carry_settle=True)
    with pytest.raises(ValueError, match="no wait before timed"):
        modes.check((modes.Mode("x", 9.0, "test", (timed, other), "d"),))


def test_timeouts_come_from_the_scenario(default_cfg):
    for name in LEGACY_PLAN:
        assert modes.timeout_s(default_cfg, name) == default_cfg.sequencer.timeout_s[name]
    d = default_cfg.dither
    assert modes.timeout_s(default_cfg, "dither") == d.lead_in_s + d.record_s + 300.0


def test_a_plan_with_a_mode_not_in_the_table_is_refused(default_cfg):
    with pytest.raises(ValueError, match="unknown mode"):
        Mission(default_cfg, plan=("1", "7"))


class FakeLegs:
    """Stands in for ``Mission.leg``: records each leg and the switches closed at its start.

    The calibration roll of Mode 4 is answered with counter 14 holding exactly
    the full turn, the counters 16/18 nothing.
    """

    def __init__(self, m):
        self.m, self.calls = m, []

    def __call__(self, what, program, watch, mask=0, signal=0, blank_s=0.0, hold_s=None,
                 on_timeout=None, record_rows=0, carry_settle=False):
        from allsky.hardware.switch_bank import closed

        self.calls.append({"what": what, "program": program, "watch": watch, "mask": mask,
                           "signal": signal, "blank_s": blank_s, "hold_s": hold_s,
                           "closed": set(closed(self.m.state.switches))})
        if what == "star re-acquired after a full roll":
            self.m.state.counters[:] = [round(FULL_TURN_ARCSEC / self.m.pulse_weight_arcsec),
                                        0, 0]
        return np.empty((0, frame_loop.N_REC))


def test_the_interpreter_runs_the_legs_of_the_table_in_order():
    cfg = load_scenario()
    m = Mission(cfg, telemetry=False)
    fake = m.leg = FakeLegs(m)
    exits = [ms.run_mode(m, name) for name in ("1", "2", "3", "4")]
    assert exits[2] == f"drift counted over {cfg.sequencer.drift_count_s:g} s; S1-S3 closed"
    optical = ((1 << legs.SIG_SUN_PITCH) | (1 << legs.SIG_SUN_YAW)
               | (1 << legs.SIG_TRACKER_YAW))
    settle, blank = cfg.sequencer.settle_time_s, cfg.sequencer.tracker_blanking_s
    expected = [
        # Mode 1: the sun-acquisition controller until sun pitch and yaw settle.
        (legs.PROGRAM_MODE1, legs.WATCH_SETTLE, optical & 3, 0, 0.0, settle, set()),
        # Mode 2: roll on S16+S18 until the tracker yaw hands over, then lock on S12.
        (legs.PROGRAM_NONE, legs.WATCH_HANDOVER, 0, legs.SIG_TRACKER_YAW, 0.0, settle,
         {14, 15, 16, 18}),
        (legs.PROGRAM_NONE, legs.WATCH_SETTLE, optical, 0, 0.0, settle, {12, 14, 15}),
        # Mode 3: count drift through S4-S6 for the drift interval (timing how long the
        # optical errors stay settled), then compensate.
        (legs.PROGRAM_NONE, legs.WATCH_ELAPSED, optical, 0, 0.0, cfg.sequencer.drift_count_s,
         {4, 5, 6, 12, 14, 15}),
        (legs.PROGRAM_NONE, legs.WATCH_SETTLE, optical, 0, 0.0, settle, {1, 2, 3, 12, 14, 15}),
        # Mode 4: the blanked roll, then the settle on Sun and star.
        (legs.PROGRAM_NONE, legs.WATCH_HANDOVER, 0, legs.SIG_TRACKER_YAW, blank, settle,
         {1, 2, 3, 14, 15, 16, 18}),
        (legs.PROGRAM_NONE, legs.WATCH_SETTLE, optical, 0, 0.0, settle, {1, 2, 3, 12, 14, 15}),
    ]
    got = [(c["program"], c["watch"], c["mask"], c["signal"], c["blank_s"], c["hold_s"],
            c["closed"]) for c in fake.calls]
    assert got == expected
    # Calibration sequencer 19 at the end of Mode 4: counted = true turn -> factor 1, no
    # cross-coupling; the counts are kept for the report.
    w = m.state.word23
    assert w[wr.SF_ROLL] == pytest.approx(1.0, abs=1e-12)
    assert w[wr.ROLL_INTO_PITCH] == 0.0 and w[wr.ROLL_INTO_YAW] == 0.0
    assert m.counted_arcsec["roll"] == pytest.approx([FULL_TURN_ARCSEC, 0.0, 0.0])
    assert m.state.rate_sign[ms.RATE_SIGN["roll"]] == 1


def test_mode_6_1_loads_register_24_and_withholds_calibration_on_request():
    cfg = load_scenario(overrides=["calibration.apply=false"])
    m = Mission(cfg, telemetry=False)
    m.board.switch(close=(1, 2, 3, 12, 14, 15))
    m.state.word23[wr.SF_ROLL] = 1.01
    fake = m.leg = FakeLegs(m)
    ms.run_mode(m, "6-1")
    assert m.state.word24[wr.PROGRAMMED_ROLL] == m.programmed_roll_deg * 3600.0
    assert m.state.word24[wr.PROGRAMMED_YAW] == m.programmed_yaw_deg * 3600.0
    np.testing.assert_array_equal(m.state.word23, wr.neutral_computed())
    # S1-S3 opened with the calibration; the roll on S16+S18 with S12 open.
    assert fake.calls[0]["closed"] == {14, 15, 16, 18}
    assert [c["program"] for c in fake.calls] == [legs.PROGRAM_TARGET_ROLL] * 2
    sign = 1 if m.programmed_roll_deg >= 0 else -1
    assert m.state.rate_sign[ms.RATE_SIGN["roll"]] == sign
