"""What the product promises of command logs, tried on random logs (hypothesis).

(a) A log flown twice gives the same summary and telemetry, bit for bit.
(b) A commanded fault flies exactly as its ``[[faults]]`` twin, the entry with
    ``start_s`` at the time the command acted and its ``duration_s``: the same
    summary (but for the ``ground_command`` entries of the journal) and the
    same telemetry bytes.
(c) Commands at one mission time act in the order given, each completely:
    ``proceed`` from a hold and ``end`` at one instant finish the mission
    before the session ends.

Times are drawn on the frame grid and off it; fault kinds with random fields
and durations; several commands at one instant.
"""

import json

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from allsky import clock
from allsky.config import scenario_from_dict
from allsky.config.scenario import load_scenario
from allsky.sim import commands
from allsky.sim.mission import Mission

AXES = st.sampled_from(("roll", "pitch", "yaw"))
#: [s] The default mission flies about 1300 s; commands inside it.
TIMES = st.one_of(st.integers(1, 130_000).map(lambda n: n / 100),  # on the 0.01 s grid
                  st.floats(0.001, 1300.0).map(lambda t: round(t, 4)))  # and off it
DURATIONS = st.one_of(st.none(), st.floats(0.005, 300.0).map(lambda d: round(d, 3)))


def _with_duration(fields, duration):
    return fields if duration is None else {**fields, "duration_s": duration}


FAULTS = st.builds(_with_duration, st.one_of(
    st.builds(lambda a, s: {"fault_kind": "gyro_bias_step", "axis": a, "size_deg_h": s},
              AXES, st.floats(-5.0, 5.0).filter(lambda s: abs(s) > 1e-3).map(
                  lambda s: round(s, 3))),
    st.builds(lambda a, s: {"fault_kind": "gyro_scale_factor_step", "axis": a,
                            "size_ppm": s}, AXES, st.integers(-5000, 5000).filter(bool)),
    st.builds(lambda a: {"fault_kind": "gyro_stuck", "axis": a}, AXES),
    st.builds(lambda a: {"fault_kind": "gyro_dead", "axis": a}, AXES),
    st.just({"fault_kind": "sun_sensor_blind"}),
    st.just({"fault_kind": "tracker_dropout"}),
    st.builds(lambda o: {"fault_kind": "tracker_stray_light", "offset_deg": o},
              st.floats(-5.0, 5.0).map(lambda o: round(o, 2))),
    st.builds(lambda a, s: {"fault_kind": "jet_stuck_open", "axis": a, "sign": s},
              AXES, st.sampled_from((-1, 1))),
    st.builds(lambda a, s: {"fault_kind": "jet_failed_off", "axis": a, "sign": s},
              AXES, st.sampled_from((-1, 1))),
    st.builds(lambda r, b: {"fault_kind": "counter_upset", "register": r, "bit": b},
              st.sampled_from(("14", "16", "18", "25", "26", "27")), st.integers(0, 10)),
    st.builds(lambda r: {"fault_kind": "propellant_leak", "rate_kg_s": r,
                         "torque_n_m": [0.0, 0.0, 0.0]},
              st.floats(1e-5, 1e-3).map(lambda r: round(r, 6)))), DURATIONS)


def _flown(m):
    """The summary as JSON data, and the telemetry's bytes."""
    s = json.loads(json.dumps(m.summary()))
    return s, np.ascontiguousarray(m.telemetry()).tobytes()


def _fly_log(cfg, log):
    m = Mission(cfg)
    station = commands.fly_log(m, commands.validate_log(log, cfg))
    return m, station


def _timed(times, faults):
    """A log of fault commands at ``times`` (several may share one instant)."""
    return [{"t_s": t, "kind": "fault", **f} for t, f in sorted(zip(times, faults),
                                                               key=lambda tf: tf[0])]


SETTINGS = settings(max_examples=12, deadline=None, derandomize=True,
                    suppress_health_check=[HealthCheck.too_slow])


@SETTINGS
@given(st.lists(TIMES, min_size=1, max_size=3), st.lists(FAULTS, min_size=3, max_size=3),
       st.booleans())
def test_a_commanded_fault_flies_as_its_faults_twin(times, faults, same_instant):
    """(a) and (b): the log flown twice; its faults as [[faults]] from the start."""
    if same_instant:
        times = [times[0]] * len(times)
    cfg = load_scenario()
    log = _timed(times, faults[:len(times)])
    m, station = _fly_log(cfg, log)
    once = _flown(m)
    assert _flown(_fly_log(cfg, log)[0]) == once  # (a)
    # The twin: each fault from the start, at the time its command acted.
    data = cfg.as_dict()
    data["faults"] = [{"kind": c["fault_kind"],  # (as a file holds it: lists)
                       **{k: v for k, v in c.items() if k not in ("t_s", "kind", "fault_kind")},
                       "start_s": c["t_s"]}
                      for c in json.loads(json.dumps(station.log))]
    twin = Mission(scenario_from_dict(data))
    twin.run()
    summary, tlm = _flown(twin)
    commanded = dict(once[0])
    commanded["events"] = [e for e in commanded["events"] if e["kind"] != "ground_command"]
    assert commanded == summary
    assert once[1] == tlm


@SETTINGS
@given(st.lists(TIMES, min_size=2, max_size=4),
       st.lists(st.sampled_from(("tracker_window", "bright_gate", "fault", "clear_fault",
                                 "reacquire", "recycle")), min_size=4, max_size=4),
       FAULTS)
def test_a_log_of_every_command_kind_flies_twice_the_same(times, kinds, fault):
    """(a) for a log of any commands; a command the mission refuses where it stands is
    refused twice the same way."""
    cfg = load_scenario()
    made = {"tracker_window": {"magnitude_window": [-1.2, 0.2]},
            "bright_gate": {"enabled": True}, "fault": fault, "clear_fault": {"fault": 0},
            "reacquire": {}, "recycle": {}}
    log = [{"t_s": t, "kind": k, **made[k]} for t, k in sorted(zip(times, kinds))]
    outcomes = []
    for _ in range(2):
        m = Mission(cfg)
        try:
            commands.fly_log(m, commands.validate_log(log, cfg))
        except commands.Refused as e:
            outcomes.append(("refused", str(e), _flown(m)))
            continue
        outcomes.append(("flown", "", _flown(m)))
    assert outcomes[0] == outcomes[1]


def test_proceed_and_end_at_one_instant_finish_the_mission_first():
    """(c): ``hold`` on the target, then ``proceed`` and ``end`` at one mission time: the
    hold ends and the mission completes before the session ends, as live."""
    cfg = load_scenario()
    plain = Mission(cfg)
    plain.run()
    at = plain.timeline[-1].end_s - 50.0  # in Mode 6-2
    log = [{"t_s": at, "kind": "hold"}, {"t_s": at + 100.0, "kind": "proceed"},
           {"t_s": at + 100.0, "kind": "end"}]
    m, station = _fly_log(cfg, log)
    assert m.status == "complete"
    kinds = [e["kind"] for e in m.journal.events]
    ends = [i for i, e in enumerate(m.journal.events) if e["kind"] == "ground_command"]
    assert kinds[-1] == "ground_command" and m.journal.events[-1]["command"] == "end"
    # Between proceed and end: the hold's mode ended, at the same instant.
    between = m.journal.events[ends[-2] + 1:ends[-1]]
    assert any(e["kind"] == "mode_end" for e in between)
    assert {e["t_s"] for e in m.journal.events[ends[-2]:]} == {station.log[-1]["t_s"]}
    assert clock.frame_at(m.params.clock, station.log[-1]["t_s"]) == m.frame
