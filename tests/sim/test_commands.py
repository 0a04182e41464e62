"""Ground commands (allsky.sim.commands): exact, applied where the flight stands, saved.

The truths here are the simulator's own promises, checked bit for bit: a
flight paused anywhere is the flight not paused; a fault commanded at a
frame boundary is the scenario's ``[[faults]]`` entry starting there; a
session flown in slices of any length, commanded at their boundaries, is
flown again exactly from its log.
"""

import json

import numpy as np
import pytest

from allsky.config import ConfigError, load_scenario, scenario_from_dict
from allsky.sim import commands as C
from allsky.sim.mission import Mission
from allsky.sim.telemetry import INDEX


def same_bits(a, b) -> bool:
    return a.shape == b.shape and np.array_equal(a.view(np.uint64), b.view(np.uint64))


def without_commands(summary) -> dict:
    out = dict(summary)
    out["events"] = [e for e in summary["events"] if e["kind"] != "ground_command"]
    return json.loads(json.dumps(out))


@pytest.fixture(scope="module")
def cfg():
    return load_scenario()


@pytest.fixture(scope="module")
def plain(cfg):
    m = Mission(cfg)
    m.run()
    return m


def live(cfg, plan, seed=0, end_after_s=None, scenario=None):
    """A live-like session: slices of random length, ``plan`` [(t_s, command)] sent then.

    Returns the mission and its station. A command is applied at the first
    boundary at or after its time, as a live session applies what the page
    sent meanwhile.
    """
    rng = np.random.default_rng(seed)
    m = Mission(scenario or cfg)
    station = C.Station(m)
    todo = list(plan)

    def pause_at(mm):
        return mm.now_s() + rng.uniform(0.01, 20.0)

    def boundary(mm, where):
        while todo and (mm.now_s() >= todo[0][0] or where == "finished"):
            _, command = todo.pop(0)
            station.apply(C.validate(command, mm.cfg))
            if command["kind"] == "end":
                raise C.Ended
        if where == "finished":
            return bool(todo) or not mm.finished
        if end_after_s is not None and mm.now_s() >= end_after_s and not todo:
            station.apply({"kind": "end"})
            raise C.Ended
        return True

    C.fly(m, boundary, pause_at)
    return m, station


def test_a_flight_paused_at_random_boundaries_is_the_flight(cfg, plain):
    m, station = live(cfg, [], seed=3)
    assert station.log == [] and m.status == "complete"
    assert m.summary() == plain.summary()
    assert same_bits(m.telemetry(), plain.telemetry())


def test_the_loop_with_faults_flies_the_fault_free_mission_until_the_onset(cfg, plain):
    """The general frame loop (faults in the scenario) against the plain one, bit for bit."""
    onset = 640.0
    fault = f'{{kind="gyro_scale_factor_step", axis="roll", size_ppm=300, start_s={onset}}}'
    scenario = load_scenario(overrides=[f"faults=[{fault}]"])
    m = Mission(scenario)
    m.run()
    a, b = plain.telemetry(), m.telemetry()
    before = a[:, INDEX["time"]] <= onset
    assert before.sum() > 6000
    assert same_bits(a[before], b[: before.sum()])
    assert not same_bits(a[~before][:100], b[before.sum():][:100])  # the fault acts after
    events = [e for e in plain.journal.events if e["t_s"] < onset]
    assert m.journal.events[: len(events)] == events


@pytest.mark.parametrize("fault", [
    {"fault_kind": "tracker_dropout", "duration_s": 30.0},
    {"fault_kind": "gyro_bias_step", "axis": "pitch", "size_deg_h": 0.5},
    {"fault_kind": "wrong_star", "star": "Achernar"},
])
def test_a_commanded_fault_is_the_scenario_s_fault_from_that_time(cfg, fault):
    """Summary and telemetry: the command's flight is the ``[[faults]]`` entry's."""
    m, station = live(cfg, [(341.0, {"kind": "fault", **fault})], seed=5)
    t_s = station.log[0]["t_s"]
    assert 341.0 <= t_s < 341.0 + 21.0
    entry = {"kind": fault["fault_kind"], **{k: v for k, v in fault.items()
                                            if k != "fault_kind"}, "start_s": t_s}
    data = cfg.as_dict()
    data["faults"] = [entry]
    twin = Mission(scenario_from_dict(data))
    twin.run()
    assert without_commands(m.summary()) == without_commands(twin.summary())
    assert same_bits(m.telemetry(), twin.telemetry())
    (command,) = [e for e in m.journal.events if e["kind"] == "ground_command"]
    assert command["t_s"] == t_s and command["fault"] == 0
    onset = [e for e in m.journal.events if e["kind"] == "fault" and e["active"]]
    assert onset[0]["t_s"] == t_s  # acts from the frame that starts at the boundary


def test_a_session_is_flown_again_exactly_from_its_log(cfg, tmp_path):
    """Faults set and cleared, the tracker, a new target, the sequencer: replayed bit for bit."""
    plan = [(120.0, {"kind": "speed", "speed": 50}),
            (300.0, {"kind": "fault", "fault_kind": "gyro_bias_step", "axis": "pitch",
                      "size_deg_h": 0.2}),
            (325.0, {"kind": "clear_fault", "fault": 0}),
            (450.0, {"kind": "bright_gate", "enabled": True}),
            (460.0, {"kind": "pause"}), (460.0, {"kind": "resume"}),
            (700.0, {"kind": "target", "star": "Vega"}),
            (1200.0, {"kind": "hold"}),
            (1500.0, {"kind": "tracker_window", "magnitude_window": [-1.5, 1.0]}),
            (1600.0, {"kind": "proceed"})]
    m, station = live(cfg, plan, seed=11)
    assert [c["kind"] for c in station.log] == [k["kind"] for _, k in plan] + ["end"] \
        or [c["kind"] for c in station.log] == [k["kind"] for _, k in plan]
    path = tmp_path / "session.toml"
    path.write_text(C.log_text(station.log, cfg.as_dict(), "a test"))
    scenario, commands = C.read_log(path)
    again_cfg = scenario_from_dict(scenario)
    assert again_cfg == cfg
    logged = C.validate_log(commands, again_cfg)
    assert [c["t_s"] for c in logged] == [c["t_s"] for c in station.log]  # exact floats
    again = Mission(again_cfg)
    C.fly_log(again, logged)
    assert again.summary() == m.summary()
    assert same_bits(again.telemetry(), m.telemetry())
    texts = [e["text"] for e in m.journal.events if e["kind"] == "ground_command"]
    assert "new target Vega" in texts and "clear fault 0" in texts
    assert m.summary()["targets"][0]["name"] == "Vega"  # uploaded before Mode 6


def test_clearing_a_fault_ends_it_at_the_boundary(cfg):
    m, station = live(cfg, [(300.0, {"kind": "fault", "fault_kind": "gyro_dead",
                                     "axis": "yaw"}),
                            (330.0, {"kind": "clear_fault", "fault": 0})], seed=2,
                      end_after_s=400.0)
    cleared = station.log[1]["t_s"]
    ends = [e for e in m.journal.events if e["kind"] == "fault" and not e["active"]]
    assert [e["t_s"] for e in ends] == [cleared]
    fault = m.cfg.faults[0]
    assert fault["start_s"] + fault["duration_s"] <= cleared


def test_a_hold_holds_on_target_until_proceed(cfg):
    m, station = live(cfg, [(900.0, {"kind": "hold"}), (1700.0, {"kind": "proceed"})], seed=4)
    modes = [r.mode for r in m.timeline]
    assert modes[-2:] == ["6-2", "standby"] and m.status == "complete"
    standby = m.timeline[-1]
    assert standby.exit.startswith("ended by ground command: proceed")
    assert standby.end_s == station.log[1]["t_s"]
    hold = m.summary()["targets"][0]["hold"]  # measured when the command ended it
    assert hold["hold_s"] == pytest.approx(standby.end_s - standby.start_s)


def test_reacquire_in_mode_4_flies_modes_1_and_2_then_mode_4_again(cfg):
    m, _ = live(cfg, [(400.0, {"kind": "reacquire"})], seed=6)
    modes = [r.mode for r in m.timeline]
    assert modes == ["1", "2", "3", "4", "references", "1", "2", "4", "5", "6-1", "6-2"]
    assert m.timeline[3].exit == "ended by ground command: reacquire the Sun and the star"
    assert m.status == "complete" and len(m.summary()["targets"]) == 1


def test_reacquire_on_target_flies_the_target_again(cfg):
    m, _ = live(cfg, [(1200.0, {"kind": "hold"}), (1400.0, {"kind": "reacquire"})], seed=8)
    modes = [r.mode for r in m.timeline]
    assert modes[6:] == ["6-2", "standby", "reacquire", "1", "2", "6-1", "6-2"]
    names = [t["name"] for t in m.summary()["targets"]]
    assert names == ["Sirius", "Sirius"] and m.status == "complete"


def test_an_aborted_mission_is_recovered_by_command():
    """Mariner 4's dust without recovery: the first glint aborts Mode 2 (the star given up
    after 0.5 s); gate off and reacquire: complete."""
    cfg = load_scenario("mariner4-dust-glints", ["sequencer.recovery=false"])
    m, _ = live(cfg, [(2000.0, {"kind": "bright_gate", "enabled": False}),
                      (2000.0, {"kind": "reacquire"})], seed=1)
    modes = [r.mode for r in m.timeline]
    assert modes[:2] == ["1", "2"] and "aborted" in m.timeline[1].exit
    assert modes[2:] == ["references", "1", "2", "3", "4", "5", "6-1", "6-2"]
    assert m.status == "complete" and m.abort_reason is None
    assert any(e["kind"] == "abort" for e in m.journal.events)  # the journal keeps it


def test_a_window_that_leaves_the_wrong_star_out_loses_it_and_reacquire_finds_canopus():
    """A window wide enough for Regulus: Mode 2 locks it. Narrowed, it is lost; reacquire."""
    cfg = load_scenario(overrides=["star_tracker.magnitude_window=[-1.5, 1.5]"])
    m, station = live(cfg, [(255.0, {"kind": "tracker_window",
                                     "magnitude_window": [-1.0, -0.3]}),
                            (255.0, {"kind": "reacquire"})], seed=9)
    assert m.timeline[2].mode == "3" and m.timeline[2].exit.startswith("ended by ground")
    at = station.log[0]["t_s"]
    lost = [e for e in m.journal.events if e["kind"] == "star_lock" and e["t_s"] == at]
    assert [(e["star"], e["previous"]) for e in lost] == [(None, "Regulus")]
    locks = [e["star"] for e in m.journal.events if e["kind"] == "star_lock" and e["t_s"] > at
             and e["star"]]
    assert locks[0] == "Canopus" and m.summary()["locked_star"] == "Canopus"
    assert m.status == "complete"


@pytest.mark.parametrize("command, where, rule", [
    ({"kind": "warp"}, "command.kind", "must be one of"),
    ({"kind": "fault"}, "command.fault_kind", "missing"),
    ({"kind": "fault", "fault_kind": "gyro_dead"}, "command.axis", "missing"),
    ({"kind": "fault", "fault_kind": "gyro_dead", "axis": "up"}, "command.axis", "one of"),
    ({"kind": "fault", "fault_kind": "gyro_dead", "axis": "yaw", "start_s": 3},
     "command.start_s", "starts when it is applied"),
    ({"kind": "speed", "speed": 0}, "command.speed", "(0, 10000]"),
    ({"kind": "target"}, "command", "star, or ra_deg and dec_deg"),
    ({"kind": "target", "star": "Vegaa"}, "command.star", "not in the PyEphem"),
    ({"kind": "tracker_window", "magnitude_window": [1, -1]}, "command.magnitude_window", ""),
    ({"kind": "hold", "duration_s": 5}, "command.duration_s", "unknown field"),
])
def test_bad_commands_name_the_field(cfg, command, where, rule):
    with pytest.raises(ConfigError) as e:
        C.validate(command, cfg)
    assert str(e.value).startswith(where) and rule in str(e.value)


@pytest.mark.parametrize("commands, where", [
    ([{"t_s": 5.0, "kind": "hold"}], "commands[0]"),
    ([{"t_s": 5.0, "kind": "pause"}, {"t_s": 4.0, "kind": "resume"}], "commands[1].t_s"),
    ([{"t_s": 5.0, "kind": "end"}, {"t_s": 6.0, "kind": "pause"}], "commands[1]"),
    ([{"kind": "pause"}], "commands[0].t_s"),
])
def test_bad_logs_are_refused(cfg, commands, where):
    with pytest.raises(ConfigError) as e:
        C.validate_log(commands, cfg)
    assert str(e.value).startswith(where)


def test_refused_commands_leave_no_trace(cfg):
    m = Mission(cfg, telemetry=False)
    station = C.Station(m)
    with pytest.raises(C.Refused, match="has not begun"):
        station.apply({"kind": "reacquire"})
    m.run_mode()
    before = len(m.journal)
    for command, why in (({"kind": "proceed"}, "nothing to proceed"),
                         ({"kind": "clear_fault", "fault": 0}, "no fault 0"),
                         ({"kind": "resume"}, "not paused")):
        with pytest.raises(C.Refused, match=why):
            station.apply(C.validate(command, cfg))
    assert len(m.journal) == before and station.log == []


def test_a_ninth_fault_is_refused(cfg):
    data = cfg.as_dict()
    data["faults"] = [{"kind": "sun_sensor_blind", "start_s": 4000.0}] * 8
    m = Mission(scenario_from_dict(data))
    with pytest.raises(C.Refused, match="8 faults already"):
        C.Station(m).apply({"kind": "fault", "fault_kind": "tracker_dropout"})
