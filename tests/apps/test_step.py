"""``allsky step``: the stops, their content, resuming, and the interactive session.

Truth: the switch states at the end of each mode are the switch table of
SPEC section 4 (patent US 4,012,018, col. 5-8); a stepped mission must end
bit for bit where a straight-through mission ends.
"""

import json
import re
import sys

import numpy as np
import pytest

from allsky import units
from allsky.apps import cli, states, step
from allsky.sim.mission import Mission
from allsky.sim.recorder import FORMAT

#: Switches closed at the end of each mode (SPEC section 4's switch actions).
CLOSED_AT_END = {
    "1": {14, 15},
    "2": {12, 14, 15},
    "3": {1, 2, 3, 12, 14, 15},
    "4": {1, 2, 3, 12, 14, 15},
    "5": {1, 2, 3, 12, 14, 15},
    "6-1": {1, 2, 3, 9, 14, 15},
    "6-2": {1, 2, 3, 9, 10, 11},
}
MODE_ORDER = ["1", "2", "3", "4", "5", "6-1", "6-2"]
STOP_RE = re.compile(r"^== Stop (\d+) - t = ([\d.]+) s - end of Mode (\S+) ", re.MULTILINE)
CLOSED_RE = re.compile(r"^  closed: (.*); S7/S8", re.MULTILINE)


def stops_in(text):
    """(number, time, mode, closed switch set) of each mode-end stop printed."""
    out = []
    for block in re.split(r"(?m)^(?===)", text):
        head = STOP_RE.match(block)
        if head:
            n, t, mode = head.groups()
            c = CLOSED_RE.search(block).group(1)
            out.append((int(n), float(t), mode,
                        set() if c == "none" else {int(k[1:]) for k in c.split()}))
    return out


def test_no_pause_prints_every_mode_end_in_order_with_the_spec_switches(capsys, tmp_path):
    out = tmp_path / "stops.json"
    code = cli.main(["step", "--no-pause", "--json", str(out)])
    text = capsys.readouterr().out
    assert code == 0
    stops = stops_in(text)
    assert [s[2] for s in stops] == MODE_ORDER
    assert [s[0] for s in stops] == list(range(1, 8))
    times = [s[1] for s in stops]
    assert times == sorted(times)
    for _, _, mode, closed in stops:
        assert closed == CLOSED_AT_END[mode], mode
    # The report follows the last stop.
    assert "allsky mission: complete" in text
    assert text.index("allsky mission: complete") > text.rindex("== Stop 7")
    data = json.loads(out.read_text())
    assert [s["mode"] for s in data["stops"]] == MODE_ORDER
    for s in data["stops"]:
        assert {k for k, v in s["switches"].items() if v} == {f"S{k}" for k in
                                                            CLOSED_AT_END[s["mode"]]}
    assert data["summary"]["status"] == "complete"


def test_stepping_does_not_change_the_flight(default_cfg, saved_states):
    straight = saved_states["mission"]
    m = Mission(default_cfg, telemetry=False)
    shown = step.step_mission(m, lambda snap: None)
    assert [s["mode"] for s in shown] == MODE_ORDER
    for a, b in zip(m.state, straight.state):
        np.testing.assert_array_equal(a, b)


def test_snapshot_reads_the_hardware(saved_states):
    """Values at the end of Mode 5 against the state arrays they come from."""
    m = states.load(saved_states["6-1"], telemetry=False)
    m._mode = "5"
    snap = step.snapshot(m, "every", "test")
    s, el = m.state, m.params.electronics
    assert snap["counters_pulses"] == {"14": s.counters[0], "16": s.counters[1],
                                       "18": s.counters[2]}
    assert snap["drift_counters_pulses"]["13"] == s.drift_counters[0]
    # Drift DAC 7: count x pulse weight / drift interval, in deg/h.
    lsb_deg_h = el.drift_lsb_arcsec_s * units.HOUR_S / units.DEG2ARCSEC
    assert snap["drift_dacs_deg_h"]["7"] == pytest.approx(s.drift_counters[0] * lsb_deg_h)
    # Register 23 holds the calibration of Modes 4 and 5.
    truth = m.summary()["truth"]
    assert snap["register23"]["scale_factor"]["roll"] == pytest.approx(
        truth["scale_factor"]["roll"], abs=2e-4)
    # Noise-free optics: locked on Sun and star, inside the 50" settle bound.
    assert snap["sun_sensor"]["present"] and snap["star_tracker"]["present"]
    assert abs(snap["sun_sensor"]["pitch_arcsec"]) < 50
    assert abs(snap["star_tracker"]["yaw_arcsec"]) < 50
    assert snap["propellant_used_kg"] == pytest.approx(
        m.cfg.jets.propellant_kg - s.propellant_kg[0])
    json.dumps(snap)  # serialisable as it stands


def test_looking_does_not_draw_from_the_noise_generator(saved_states):
    m = states.load(saved_states["4"], telemetry=False)
    m._mode = "3"
    before = m.state.rng.copy()
    step.snapshot(m, "every", "test")
    np.testing.assert_array_equal(m.state.rng, before)


def test_until_ends_the_session_at_that_mode_and_saved_state_resumes(capsys, tmp_path,
                                                                     saved_states):
    code = cli.main(["step", "--no-pause", "--until", "3", "--save-dir", str(tmp_path)])
    text = capsys.readouterr().out
    assert code == 0
    assert [s[2] for s in stops_in(text)] == ["3"]  # no stop shown before the end of Mode 3
    assert "before Mode 4" in text
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "after_mode_1.npz", "after_mode_2.npz", "after_mode_3.npz"]

    out = tmp_path / "rest.json"
    code = cli.main(["step", "--no-pause", "--from", str(tmp_path / "after_mode_3.npz"),
                     "--json", str(out)])
    text = capsys.readouterr().out
    assert code == 0
    assert [s[2] for s in stops_in(text)] == ["4", "5", "6-1", "6-2"]
    resumed = json.loads(out.read_text())["summary"]
    straight = json.loads(json.dumps(saved_states["mission"].summary()))
    assert resumed == straight


@pytest.mark.parametrize("argv, words", [
    (["step", "--from", "missing.npz"], "missing.npz"),
    (["step", "--until", "9"], "--until 9"),
    (["step", "--every", "-1"], "--every"),
    (["step", "--every", "nan"], "--every"),
])
def test_bad_step_input_exits_2_naming_it(capsys, argv, words):
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert words in err
    assert not err.rstrip().endswith(":")  # a whole sentence, not a dangling "key:"


def test_from_refuses_a_scenario_or_overrides(capsys, saved_states):
    assert cli.main(["step", "--from", str(saved_states["3"]), "--set", "mission.seed=2"]) == 2
    assert "--from" in capsys.readouterr().err


def test_from_refuses_a_file_that_is_not_a_state(capsys, tmp_path):
    bad = tmp_path / "bad.npz"
    bad.write_text("not a state")
    assert cli.main(["step", "--from", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "not a saved allsky mission state" in err
    assert not err.rstrip().endswith(":")


def test_interactive_session_in_a_terminal(tmp_path):
    """Drive ``allsky step`` in a pseudo-terminal as a person would: Enter, Enter, q."""
    pexpect = pytest.importorskip("pexpect")
    tlm = tmp_path / "tlm.csv"
    child = pexpect.spawn(sys.executable, ["-m", "allsky", "step", "--telemetry", str(tlm)],
                          encoding="utf-8", timeout=180, dimensions=(50, 160))
    child.expect(r"== Stop 1 - t = [\d.]+ s - end of Mode 1 ")
    child.expect(r"q \+ Enter to stop here > ")
    child.sendline("")
    child.expect(r"== Stop 2 - t = [\d.]+ s - end of Mode 2 ")
    child.expect(r"closed: S12 S14 S15;")
    child.expect(r"> ")
    child.sendline("q")
    child.expect(r"Stepping ended at t = [\d.]+ s, before Mode 3")
    child.expect("allsky mission: not finished")
    child.expect(pexpect.EOF)
    child.close()
    assert child.exitstatus == 0
    rows = tlm.read_text().splitlines()
    assert rows[0].startswith(f"# allsky telemetry format {FORMAT}; rows ")
    assert rows[1].startswith("time [s],mode [-]")
    last_t = float(rows[-1].split(",")[0])
    assert 100.0 < last_t < 600.0  # the flight so far: Modes 1 and 2 only


def test_pauses_every_n_seconds_do_not_change_the_flight(default_cfg, saved_states):
    """Stopping inside legs (``--every``) resumes each leg exactly: same final state."""
    straight = saved_states["mission"]
    m = Mission(default_cfg, telemetry=False)
    shown = step.step_mission(m, lambda snap: None, every_s=97.0)
    inside = [s for s in shown if s["kind"] == "every"]
    ends = [s["mode"] for s in shown if s["kind"] == "mode end"]
    assert ends == MODE_ORDER
    # One stop per multiple of 97 s that falls inside a leg, on the frame.
    assert len(inside) >= int(straight.now_s() // 97.0) - 2
    for s in inside:
        k = round(s["time_s"] / 97.0)
        assert s["time_s"] == pytest.approx(97.0 * k, abs=0.011)
        assert s["reason"].startswith("waiting for: ")
    for name in m.state._fields:
        if name != "leg_clock":  # the progress of the last leg when it was paused
            np.testing.assert_array_equal(getattr(m.state, name), getattr(straight.state, name))


def test_every_and_until_print_inside_stops_only_from_that_mode(capsys):
    code = cli.main(["step", "--no-pause", "--every", "50", "--until", "2"])
    text = capsys.readouterr().out
    assert code == 0
    inside = re.findall(r"^== Stop \d+ - t = ([\d.]+) s - inside Mode (\S+) ", text, re.MULTILINE)
    assert inside and all(mode == "2" for _, mode in inside)
    assert all(float(t) % 50.0 < 0.011 or float(t) % 50.0 > 49.989 for t, _ in inside)
    assert [s[2] for s in stops_in(text)] == ["2"]


def test_step_telemetry_as_parquet_holds_the_flight_so_far(tmp_path, capsys):
    from allsky.apps import telemetry_files

    path = tmp_path / "t.parquet"
    assert cli.main(["step", "--no-pause", "--until", "2", "--telemetry", str(path)]) == 0
    table, _ = telemetry_files.read(path)
    t_end = float(stops_in(capsys.readouterr().out)[-1][1])
    assert table[-1, 0] == pytest.approx(t_end, abs=0.1)
    assert set(table[:, 1]) == {1.0, 2.0}  # mode codes of Modes 1 and 2 only
