"""Mission snapshots (``Mission.snapshot``/``from_snapshot``) and state files (allsky.apps.states).

Truth: a mission resumed from a snapshot or a file flies on bit for bit as
the mission that was never stopped (the default mission of conftest.py);
the file layout is STATE_FORMAT 3 (one JSON ``history`` string, the state
arrays as ``state_<field>``), so a file written that way by hand loads too.
"""

import json
import re

import numpy as np
import pytest

from allsky.apps import states
from allsky.sim import state as sim_state
from allsky.sim.mission import STATE_FORMAT, Mission


def assert_same_state(a, b):
    for name in sim_state.State._fields:
        np.testing.assert_array_equal(getattr(a.state, name), getattr(b.state, name), name)


def test_resumed_from_a_snapshot_flies_on_bit_for_bit(saved_states):
    m = states.load(saved_states["6-1"], telemetry=False)
    history, arrays = m.snapshot()
    json.dumps(history)  # the history is plain data
    again = Mission.from_snapshot(history, arrays, telemetry=False)
    m.run()
    # The snapshot holds copies: flying m on left it, and it resumes a second time.
    assert Mission.from_snapshot(history, arrays, telemetry=False).next_mode == 5
    again.run()
    assert_same_state(again, saved_states["mission"])
    assert again.summary() == saved_states["mission"].summary()


def test_file_layout_is_state_format_4(saved_states):
    assert STATE_FORMAT == 4
    with np.load(saved_states["4"], allow_pickle=False) as z:
        assert set(z.files) == {"history"} | {f"state_{k}" for k in sim_state.State._fields}
        history = json.loads(str(z["history"]))
    assert history["format"] == 4 and history["next_mode"] == 3
    assert [r[0] for r in history["timeline"]] == ["1", "2", "3"]


def test_a_file_written_in_that_layout_by_hand_loads(saved_states, tmp_path):
    """A format-3 file written by other code (np.savez of the history JSON and state_ arrays)."""
    history, arrays = states.load(saved_states["5"], telemetry=False).snapshot()
    path = tmp_path / "by_hand.npz"
    np.savez(path, history=np.array(json.dumps(history)),
             **{f"state_{k}": v for k, v in arrays.items()})
    m = states.load(path, telemetry=False)
    m.run()
    assert_same_state(m, saved_states["mission"])


def test_save_replaces_the_file_whole_or_not_at_all(saved_states, tmp_path, monkeypatch):
    path = tmp_path / "s.npz"
    m = states.load(saved_states["3"], telemetry=False)
    assert states.save(m, path) == path
    before = path.read_bytes()

    def broken(f, **arrays):
        f.write(b"PK\x03\x04 half an archive")
        raise OSError("disk full")

    monkeypatch.setattr(states.np, "savez", broken)
    from allsky.apps.output import OutputError

    with pytest.raises(OutputError, match="--save-dir: cannot write .*s.npz: disk full"):
        states.save(m, path)
    assert path.read_bytes() == before  # the old file, intact
    assert [p.name for p in tmp_path.iterdir()] == ["s.npz"]  # no temporary left behind


def _written(tmp_path, history, arrays, name="edited.npz"):
    """A state file in the layout of format 3, with ``history`` and ``arrays`` as given."""
    path = tmp_path / name
    np.savez(path, history=np.array(json.dumps(history)),
             **{f"state_{k}": v for k, v in arrays.items()})
    return path


@pytest.fixture()
def before_6_1(saved_states):
    """History and arrays of the default mission saved before Mode 6-1 (copies to edit)."""
    return states.load(saved_states["6-1"], telemetry=False).snapshot()


@pytest.mark.parametrize("content, words", [
    (b"", "an empty file"),
    (b"not a state", "not an .npz archive"),
    (b"PK\x03\x04 torn", "a damaged .npz archive (BadZipFile"),
])
def test_load_refuses_a_file_that_is_not_a_state(tmp_path, content, words):
    path = tmp_path / "bad.npz"
    path.write_bytes(content)
    with pytest.raises(states.StateError, match=re.escape(words)):
        states.load(path)


def test_load_refuses_another_format(saved_states, tmp_path):
    history, arrays = states.load(saved_states["2"], telemetry=False).snapshot()
    path = _written(tmp_path, {**history, "format": 2}, arrays, "v2.npz")
    with pytest.raises(states.StateError, match=r"^format 2, not 4$"):
        states.load(path)
    with pytest.raises(ValueError, match="format 2, not 4"):
        Mission.from_snapshot({**history, "format": 2}, arrays)


def _edit_history(**changes):
    def edit(history, arrays):
        history.update(changes)
    return edit


def _edit_array(name, value, index=0):
    def edit(history, arrays):
        arrays[name] = arrays[name].copy()
        arrays[name][index] = value
    return edit


def _replace_array(name, value):
    def edit(history, arrays):
        arrays[name] = value
    return edit


def _edit_scenario(section, key, value):
    def edit(history, arrays):
        history["scenario"][section][key] = value
    return edit


@pytest.mark.parametrize("edit, words", [
    (_edit_history(next_mode=99), "next_mode = 99 is not a mode of the plan (0..7)"),
    (_edit_history(next_mode=-1), "next_mode = -1 is not a mode of the plan"),
    (_edit_history(next_mode="5"), "next_mode = '5' is not a mode of the plan"),
    (_edit_history(next_mode=7), "status = 'running' with next_mode = 7 of 7 modes"),
    (_edit_history(plan=["1", "2", "3", "4", "5", "6-1", "6-3"]),
     "plan ['1', '2', '3', '4', '5', '6-1', '6-3'] is not a plan (legacy: 1 2 3 4 5 6-1 6-2"),
    (_edit_history(plan="legacy"), "plan 'legacy' is not a plan"),
    (_edit_history(status="paused"), "status = 'paused' is not one of running, complete, aborted"),
    (_edit_history(timeline=[["1", 0.0, 1.0, "x"]]), "timeline must list the 5 modes flown"),
    (_edit_history(leg_count=-1), "leg_count = -1 is not a count"),
    (_edit_history(counted_arcsec={"roll": [1.0, None, 2.0]}), "counted_arcsec = "),
    (_edit_history(programmed_roll_deg=float("nan")), "programmed_roll_deg = nan is not a finite"),
    (_edit_history(format=4.0), "format 4.0, not 4"),
    (_edit_history(format=3), "format 3, not 4"),  # a file of the summed clock
    (_edit_scenario("gyro", "arw_deg_rt_h", -1), ("its scenario: gyro.arw_deg_rt_h = -1.0: must "
                                                  "be >= 0")),
    (_edit_scenario("mission", "frame_s", 1e-12), ("its scenario: mission.frame_s = 1e-12: must "
                                                  "be >= 0.0001")),
    (_edit_array("propellant_kg", -0.5), "state_propellant_kg = -0.5: must be within 0..4 kg"),
    (_edit_array("propellant_kg", 4.5), "state_propellant_kg = 4.5: must be within 0..4 kg"),
    (_edit_array("x", np.nan, 5), "state_x holds nan: the state is finite"),
    (_edit_array("word23", np.inf, 2), "state_word23 holds inf"),
    (_edit_array("x", 1e308, 0), "state_x: quaternion [1e+308, "),
    (_edit_array("switches", 3, 7), ("state_switches: S7 = 3 (an on/off switch is 0 or 1, a "
                                    "selector 0, 1 or 2)")),
    (_edit_array("switches", 2, 4), "state_switches: S4 = 2"),
    (_edit_array("pwpf_out", 5, 1), "state_pwpf_out = [0, 5, 0]: each must be one of -1, 0, 1"),
    (_edit_array("frame", -1), "state_frame (the mission clock) must be >= 0"),
    (_replace_array("x", np.zeros(6)), ("state_x is float64 of shape (6,), not float64 of shape "
                                       "(7,)")),
    (_replace_array("counters", np.zeros(3)), ("state_counters is float64 of shape (3,), not "
                                              "int64 of shape (3,)")),
    (_replace_array("rng", np.ones(1, dtype=np.uint32)), "state_rng is uint32"),
    # Field by field against the snapshot's keys: journal entries, the journal buffer, the star.
    (lambda h, a: h["events"][0].pop("kind"), "events[0].kind = None is not a journal kind"),
    (lambda h, a: h["events"][1].update(kind=["x"]), "events[1].kind = ['x'] is not"),
    (lambda h, a: h["events"].append(7), "is not a journal entry"),
    (lambda h, a: h["events"][0].update(t_s="0"), "events[0].t_s = '0': a finite time"),
    (_edit_history(events={}), "events = {} is not a list of journal entries"),
    (_edit_array("journal_n", 10**6), "state_journal_n = [1000000, 0]: rows filled within"),
    (_edit_array("journal_n", -1, 1), "rows lost >= 0"),
    (_edit_array("locked_star", 10**6), "state_locked_star = 1000000: -1 (none) or a star"),
    (_edit_array("locked_star", -2), "state_locked_star = -2"),
    (_edit_history(extra_key=1), "history: unknown key 'extra_key'"),
    (lambda h, a: h.pop("events"), "history: no events"),
    (_edit_history(targets=[1]), "targets = [1] is not a list of target records"),
    (_edit_history(hold=[1]), "hold = [1] is not a table"),
    (_edit_history(locked_star_name=5), "locked_star_name = 5 is not a name"),
])
def test_load_refuses_a_state_no_mission_saves(tmp_path, before_6_1, edit, words):
    history, arrays = before_6_1
    history = json.loads(json.dumps(history))
    edit(history, arrays)
    with pytest.raises(states.StateError) as e:
        states.load(_written(tmp_path, history, arrays))
    assert words in str(e.value) and "\n" not in str(e.value)


def test_load_refuses_missing_and_extra_arrays(tmp_path, before_6_1):
    history, arrays = before_6_1
    del arrays["cpu"]
    with pytest.raises(states.StateError, match="no state array state_cpu"):
        states.load(_written(tmp_path, history, arrays))
    path = tmp_path / "extra.npz"
    np.savez(path, history=np.array(json.dumps(history)), extra=np.zeros(2))
    with pytest.raises(states.StateError, match="unexpected member 'extra'"):
        states.load(path)
    np.savez(path, state_x=np.zeros(7))
    with pytest.raises(states.StateError, match="no history in the archive"):
        states.load(path)
    np.savez(path, history=np.zeros(3))
    with pytest.raises(states.StateError, match="history is a float64 array of shape"):
        states.load(path)


@pytest.mark.parametrize("make, words", [
    (lambda p: p.write_bytes(b""), "an empty file"),
    (lambda p: p.mkdir(), "cannot read it: a directory, not a file"),
    (lambda p: None, "cannot read it: no such file"),
])
def test_step_from_a_bad_file_exits_2_in_one_line(capsys, tmp_path, make, words):
    from allsky.apps.cli import main

    path = tmp_path / "s.npz"
    make(path)
    assert main(["step", "--no-pause", "--from", str(path)]) == 2
    err = capsys.readouterr().err
    assert err == f"allsky: error: --from {path}: not a saved allsky mission state ({words})\n"


def test_step_from_a_state_of_past_the_plan_exits_2(capsys, tmp_path, before_6_1):
    from allsky.apps.cli import main

    history, arrays = before_6_1
    path = _written(tmp_path, {**history, "next_mode": 99}, arrays)
    assert main(["step", "--no-pause", "--from", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"allsky: error: --from {path}: ") and err.count("\n") == 1
    assert "next_mode = 99 is not a mode of the plan (0..7)" in err
