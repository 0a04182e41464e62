"""The historical commands docs/ground_control.md re-enacts, flown from their logs.

Each log of ``docs/examples/`` is flown over its packaged scenario (as
``allsky run SCENARIO --commands LOG`` does) and its outcome checked against
the document's words: the mission recovers, on Canopus, at the time and
pointing error the document quotes. The classroom walk-through likewise.
"""

from pathlib import Path

import pytest

from allsky.config import load_scenario
from allsky.sim import commands
from allsky.sim.mission import Mission

ROOT = Path(__file__).resolve().parents[2]
DOC = " ".join((ROOT / "docs" / "ground_control.md").read_text().split())


def fly(scenario, log, overrides=()):
    cfg = load_scenario(scenario, overrides)
    _, raw = commands.read_log(ROOT / "docs" / "examples" / log)
    m = Mission(cfg)
    station = commands.fly_log(m, commands.validate_log(raw, cfg))
    return m, station


@pytest.mark.parametrize("scenario, log, overrides, acted_s, modes", [
    ("mariner4-dust-glints", "mariner4-gate-off.toml", (), [1900.0],
     ["5", "6-1", "6-2"]),
    ("mariner4-star-hopping", "mariner4-step-on.toml",
     ("star_tracker.cone_angle_check_deg=0",), [200.0, 200.0],
     ["references", "1", "2", "3", "4"]),
    ("voyager1-wrong-star", "voyager1-back-to-canopus.toml", (), [700.0, 700.0],
     ["restart", "1", "2", "3", "4", "5", "6-1", "6-2"]),
])
def test_each_historical_command_log_recovers_the_mission(scenario, log, overrides, acted_s,
                                                          modes):
    m, station = fly(scenario, log, overrides)
    assert [round(c["t_s"], 1) for c in station.log] == acted_s
    flown = [r.mode for r in m.timeline]
    after = flown[flown.index(modes[0]):]
    assert after[: len(modes)] == modes
    summary = m.summary()
    assert summary["status"] == "complete" and summary["locked_star"] == "Canopus"
    end = summary["end"]
    assert f"complete on Canopus at {end['t_s']:.1f} s" in DOC or \
        f"complete at {end['t_s']:.1f} s, {end['true_pointing_error_arcsec']:.1f}″ off" in DOC
    assert f"{end['true_pointing_error_arcsec']:.1f}″ off" in DOC


def test_mariner_star_hopping_locks_wrong_objects_and_steps_on_to_canopus_by_command():
    m, station = fly("mariner4-star-hopping", "mariner4-star-hopping.toml",
                     ("star_tracker.cone_angle_check_deg=0",))
    s = m.summary()
    locks = [(e["t_s"], e["star"]) for e in s["events"]
             if e["kind"] == "star_lock" and e["mode"] == "2" and e["star"]]
    wrong = [k for _, k in locks if k != "Canopus"]
    assert wrong == ["stray light", "Regulus"]  # two wrong objects locked ...
    stepped = [c["t_s"] for c in station.log if c["kind"] == "step_on"]
    assert [round(t, 1) for t in stepped] == [195.0, 222.0]  # ... each stepped over
    assert [t for t, k in locks if k != "Canopus"] < stepped  # each locked before its step
    assert locks[-1][1] == "Canopus" and locks[-1][0] > stepped[-1]
    assert s["status"] == "complete" and s["locked_star"] == "Canopus" and not s["warnings"]
    end = s["end"]
    assert f"complete at {end['t_s']:.1f} s, {end['true_pointing_error_arcsec']:.1f}″ off" in DOC
    for t, k in locks:
        assert f"{k} at {t:.1f} s" in DOC or f"Canopus at {t:.1f} s" in DOC or \
            f"Earth at {t:.1f} s" in DOC


def test_step_on_needs_something_held():
    cfg = load_scenario()
    m = Mission(cfg)
    with pytest.raises(commands.Refused, match="holds nothing"):
        commands.fly_log(m, commands.validate_log([{"t_s": 0.0, "kind": "step_on"}], cfg))


def test_the_classroom_walk_through(tmp_path):
    cfg = load_scenario()
    log = [{"t_s": 310.0, "kind": "fault", "fault_kind": "tracker_dropout", "duration_s": 20.0},
           {"t_s": 400.0, "kind": "reacquire"}]
    m = Mission(cfg)
    commands.fly_log(m, commands.validate_log(log, cfg))
    aborted = m.timeline[2]
    assert aborted.mode == "3" and aborted.exit.startswith("aborted: Mode 3: star lost")
    assert f"Mode 3 aborts at {aborted.end_s:.1f} s" in DOC
    assert f"`{aborted.exit[len('aborted: '):]}`" in DOC.replace("` `", "")
    s = m.summary()
    assert s["status"] == "complete"
    assert (f"completes on Sirius at {s['mission_time_s']:.1f} s, "
            f"{s['end']['true_pointing_error_arcsec']:.1f}″ off") in DOC
