"""The replay page's Python side: its data block, event log, HTML file and commands.

The page in a real browser is tests/apps/test_replay_browser.py.
"""

import base64
import hashlib
import json
import re
from pathlib import Path

import numpy as np
import pytest

from allsky.apps import replay, replay_events, telemetry_files
from allsky.apps.cli import main
from allsky.hardware.wiring import SELECTORS
from allsky.sequencer import modes
from allsky.sim.telemetry import INDEX, switch_closed

AXES = ("roll", "pitch", "yaw")


@pytest.fixture(scope="module")
def flown(saved_states):
    m = saved_states["mission"]
    return m.telemetry(), m.summary(), m.cfg


@pytest.fixture(scope="module")
def data(flown):
    table, summary, cfg = flown
    return replay.replay_data(table, summary, cfg)


def _undelta(d):
    return np.cumsum(np.asarray(d, dtype=np.int64))


def _run_values(runs, n):
    out = np.empty(n)
    for k, (row, value) in enumerate(runs):
        end = runs[k + 1][0] if k + 1 < len(runs) else n
        out[row:end] = value
    return out


def test_exact_columns_survive_the_encoding_at_every_row(flown, data):
    """Mode, switches, selector, counters and valves decode to the telemetry exactly."""
    table, _, _ = flown
    cols, n = data["columns"], len(table)
    assert cols["n"] == n
    t_ms = _undelta(cols["t_ms"])
    assert np.array_equal(t_ms, np.round(table[:, INDEX["time"]] * 1000).astype(np.int64))
    for name in replay.EXACT:
        assert np.array_equal(_undelta(cols["exact"][name]), table[:, INDEX[name]]), name
    for name in replay.RUNS:
        assert np.array_equal(_run_values(cols["runs"][name], n), table[:, INDEX[name]]), name
    selector = np.array([int(c) for c in cols["selector"]])
    assert np.array_equal(selector, table[:, INDEX["s7_s8"]])
    for k, name in enumerate(("valve_roll", "valve_pitch", "valve_yaw")):
        valves = np.array([int(c) - 1 for c in cols["valves"][k]])
        assert np.array_equal(valves, table[:, INDEX[name]])


def test_continuous_columns_within_their_rounding(flown, data):
    table, _, _ = flown
    for name, scale in replay.CONTINUOUS.items():
        got = _undelta(data["columns"]["cont"][name]["d"]) / scale
        assert np.max(np.abs(got - table[:, INDEX[name]])) <= 0.5 / scale + 1e-9, name


def test_long_missions_thin_only_the_continuous_columns(flown, monkeypatch):
    table, summary, cfg = flown
    monkeypatch.setattr(replay, "MAX_CONTINUOUS_ROWS", 1000)
    cols = replay.replay_data(table, summary, cfg)["columns"]
    assert cols["stride"] == int(np.ceil(len(table) / 1000))
    assert len(cols["cont"]["q_w"]["d"]) == len(range(0, len(table), cols["stride"]))
    assert np.array_equal(_undelta(cols["exact"]["counter14"]), table[:, INDEX["counter14"]])
    assert len(cols["selector"]) == len(table)


def test_every_switch_change_is_logged_with_a_reason_from_the_mode_table(flown, data):
    table, summary, _ = flown
    masks = table[:, INDEX["switches"]].astype(np.int64)
    changes = int(np.count_nonzero(np.diff(masks))) + int(masks[0] != 0)
    switch_events = [e for e in data["events"] if e["kind"] == "switch"]
    assert len(switch_events) == changes
    for e in switch_events:
        assert "no switch step" not in e["reason"], e
        row = int(np.searchsorted(table[:, INDEX["time"]], e["t_s"]))
        for k in e["close"]:
            assert switch_closed(table, k)[row]
        for k in e["open"]:
            assert not switch_closed(table, k)[row]
    flown_modes = [e["mode"] for e in data["events"] if e["kind"] == "mode"]
    assert flown_modes == [r["mode"] for r in summary["modes"]]
    times = [e["t_s"] for e in data["events"]]
    assert times == sorted(times)


def test_the_switch_reason_names_the_wait_that_ended(data):
    """Mode 2: S12 closes once the star is in the window, the rate command off."""
    e = next(e for e in data["events"] if e["kind"] == "switch" and 12 in e["close"]
             and e["mode"] == "2")
    assert e["open"] == [16, 18]
    assert "star in the magnitude window" in e["reason"]
    assert e["waiting"] == "locked on Sun and star"


def test_an_unmatched_change_is_still_logged(flown):
    table, summary, _ = flown
    t = table.copy()
    row = len(t) // 2
    t[row:, INDEX["switches"]] = t[row:, INDEX["switches"]].astype(np.int64) ^ (1 << 5)
    ev = replay_events.events(t, summary["modes"])
    odd = [e for e in ev if e["kind"] == "switch" and "no switch step" in e["reason"]]
    assert odd and odd[0]["t_s"] == pytest.approx(t[row, INDEX["time"]])


@pytest.mark.parametrize("mode", [m.name for m in modes.MODE_TABLE])
def test_every_mode_has_one_plain_sentence(mode):
    text = replay_events.mode_sentence(mode)
    assert text.endswith(".") and text.count(". ") == 0 and "{" not in text


def test_registers_23_and_24_follow_the_timeline(data, flown):
    _, summary, _ = flown
    ends = {r["mode"]: r["end_s"] for r in summary["modes"]}
    words = data["registers"]["23"]
    assert words[0]["sf_roll"] == 1.0 and words[0]["t_s"] == 0.0
    assert [w["t_s"] for w in words[1:]] == [ends["4"], ends["5"]]
    cal = summary["calibration"]
    assert words[1]["sf_roll"] == cal["scale_factor"]["roll"] and words[1]["sf_yaw"] == 1.0
    assert words[2]["sf_yaw"] == cal["scale_factor"]["yaw"]
    assert words[2]["yaw_into_roll"] == cal["cross_coupling"]["yaw_into_roll"]
    (load,) = data["registers"]["24"]
    assert load["roll_deg"] == summary["target"]["programmed_roll_deg"]
    assert load["t_s"] == next(r["start_s"] for r in summary["modes"] if r["mode"] == "6-1")


def test_the_diagram_is_read_from_the_layout_and_wiring_tables(data):
    from allsky.apps import diagram_layout
    from allsky.hardware import wiring

    g = data["diagram"]
    assert set(g["boxes"]) == set(diagram_layout.BOXES)
    drawn = sorted(k for line in g["lines"] for k in line["switches"])
    assert drawn == [s.number for s in wiring.SWITCHES]  # each switch on exactly one line
    for k in SELECTORS:
        assert g["switches"][k - 1]["selector"]


def _page(data):
    return replay.render_html(data)


def test_the_page_is_one_file_that_asks_for_nothing(data):
    page = _page(data)
    csp = re.search(r'http-equiv="Content-Security-Policy" content="([^"]+)"', page).group(1)
    assert "default-src 'none'" in csp and "connect-src 'none'" in csp
    assert "unsafe-inline" not in csp and "unsafe-eval" not in csp
    scripts = re.findall(r"<script>(.*?)</script>", page, flags=re.DOTALL)
    styles = re.findall(r"<style>(.*?)</style>", page, flags=re.DOTALL)
    assert len(scripts) == 1 and len(styles) == 1
    for text in scripts + styles:
        digest = base64.b64encode(hashlib.sha256(text.encode()).digest()).decode()
        assert f"'sha256-{digest}'" in csp
    assert not re.search(r"""(src|href)\s*=\s*["'](?!data:)""", page)
    assert not re.search(r"https?://(?!www\.w3\.org/2000/svg)", page)
    block = re.search(r'<script type="application/json" id="allsky-data">(.*?)</script>', page,
                      flags=re.DOTALL).group(1)
    assert json.loads(block)["format"] == replay.DATA_FORMAT


def test_the_default_mission_page_is_small(data):
    assert len(_page(data).encode()) <= 6e6


def test_replay_without_a_summary(flown):
    table, _, cfg = flown
    d = replay.replay_data(table, None, cfg)
    assert not d["registers"]["known"] and d["summary"] is None
    assert [r["mode"] for r in d["timeline"]] == list(modes.LEGACY_PLAN)
    assert "{" not in d["timeline"][2]["exit"]  # exit texts filled from the scenario


def test_replay_command_writes_the_page(flown, tmp_path, capsys):
    table, summary, _ = flown
    tlm = tmp_path / "tlm.csv"
    telemetry_files.write(tlm, table)
    js = tmp_path / "summary.json"
    js.write_text(json.dumps(summary))
    out = tmp_path / "mission.html"
    assert main(["replay", str(tlm), "--summary", str(js), "--html", str(out)]) == 0
    assert "wrote replay" in capsys.readouterr().out
    page = out.read_text()
    assert page.startswith("<!DOCTYPE html>") and "window.allsky" in page


@pytest.mark.parametrize("case", ["missing telemetry", "bad suffix", "missing dir",
                                  "missing summary", "bad summary", "not a summary"])
def test_replay_command_bad_paths_exit_2(flown, tmp_path, capsys, case):
    table, _, _ = flown
    tlm = tmp_path / "tlm.csv"
    telemetry_files.write(tlm, table[:50])
    bad = tmp_path / "bad.json"
    bad.write_text("{not json" if case == "bad summary" else "[1, 2]")
    args = {"missing telemetry": [str(tmp_path / "none.csv"), "--html", str(tmp_path / "a.html")],
            "bad suffix": [str(tlm), "--html", str(tmp_path / "a.txt")],
            "missing dir": [str(tlm), "--html", str(tmp_path / "no" / "a.html")],
            "missing summary": [str(tlm), "--summary", str(tmp_path / "no.json"), "--html",
                                str(tmp_path / "a.html")],
            "bad summary": [str(tlm), "--summary", str(bad), "--html", str(tmp_path / "a.html")],
            "not a summary": [str(tlm), "--summary", str(bad), "--html",
                              str(tmp_path / "a.html")]}[case]
    assert main(["replay", *args]) == 2
    err = capsys.readouterr().err
    assert err.startswith("allsky: error:") and err.count("\n") == 1
    assert not (tmp_path / "a.html").exists()


def test_run_html_bad_path_exits_2_before_flying(tmp_path, capsys):
    assert main(["run", "--html", str(tmp_path / "x.png"), "--quiet"]) == 2
    assert "--html" in capsys.readouterr().err


def test_notes_say_what_the_interval_hides(data):
    text = " ".join(data["notes"])
    assert "shorter than 0.1 s" in text and "S7/S8" in text


# -- several targets: reacquire and recycle ---------------------------------------------

THREE_TARGETS = Path(__file__).resolve().parents[2] / "docs" / "examples" / "three_targets.toml"
#: Pulses counted between the last telemetry row of a turn and its end (a few at most).
LATE_PULSES = 10


@pytest.fixture(scope="module", params=["reacquire", "recycle"])
def three(request):
    """A three-target mission flown mode by mode, with register 23 after each mode."""
    from allsky.config import load_scenario
    from allsky.sim.mission import Mission

    cfg = load_scenario(THREE_TARGETS, [f'sequencer.between_targets="{request.param}"',
                                        "target.hold_s=60"])
    m = Mission(cfg)
    stored = []  # (end_s, register 23) after each mode that wrote it
    while not m.finished:
        before = m.state.word23.copy()
        r = m.run_mode()
        if not np.array_equal(before, m.state.word23):
            stored.append((r.end_s, m.state.word23.copy()))
    assert m.status == "complete", m.abort_reason
    table, summary = m.telemetry(), m.summary()
    return request.param, table, summary, cfg, stored, replay.replay_data(table, summary, cfg)


def test_register_23_holds_what_each_calibration_stored(three):
    """One word set per calibration flown, in force from the end of its turn."""
    how, _, summary, cfg, stored, d = three
    words = d["registers"]["23"]
    assert words[0]["source"] == "start"
    assert [w["t_s"] for w in words[1:]] == [t for t, _ in stored]
    assert len(stored) == (2 if how == "reacquire" else 6)  # Modes 4 and 5, once per target
    lsb = cfg.electronics.vfc_pulse_weight_arcsec / (360 * 3600)  # a pulse in a word
    for w, (_, truth) in zip(words[1:], stored):
        got = np.array([w[k] for k in replay.WORD23])
        assert np.all(np.abs(got - truth[list(replay.WORD23.values())]) <= LATE_PULSES * lsb), w
    assert [words[-1][k] for k in replay.WORD23] == list(stored[-1][1][list(
        replay.WORD23.values())])
    # The summary holds the last words written; the earlier ones come from the counters.
    assert {w["source"] for w in words[-2:]} == {"summary"}
    assert {w["source"] for w in words[1:-2]} <= {"counters"}
    cal = summary["calibration"]
    assert words[-1]["sf_roll"] == cal["scale_factor"]["roll"]
    assert words[-1]["yaw_into_roll"] == cal["cross_coupling"]["yaw_into_roll"]
    # In every Mode 6 register 23 holds the calibration of its own target's cycle.
    for r in summary["modes"]:
        if r["mode"] == "6-1":
            in_force = [w for w in words if w["t_s"] <= r["start_s"]][-1]
            assert in_force["source"] != "start" and in_force["sf_roll"] != 1.0
    if how == "recycle":
        assert "\u2248" in " ".join(d["notes"])


def test_register_24_holds_each_targets_angles(three):
    _, _, summary, _, _, d = three
    loads = d["registers"]["24"]
    starts = [r["start_s"] for r in summary["modes"] if r["mode"] == "6-1"]
    assert [p["t_s"] for p in loads] == starts
    assert [p["target"] for p in loads] == [t["name"] for t in summary["targets"]]
    for p, tgt in zip(loads, summary["targets"]):
        assert (p["roll_deg"], p["yaw_deg"]) == (tgt["programmed_roll_deg"],
                                                 tgt["programmed_yaw_deg"])


def test_every_target_is_drawn_with_the_times_it_was_flown(three):
    _, table, summary, cfg, _, d = three
    targets = d["sky"]["targets"]
    assert [t["name"] for t in targets] == [t["name"] for t in summary["targets"]]
    from allsky.sim.mission import target_inertial

    for k, tgt in enumerate(targets):
        assert np.allclose(tgt["vec"], target_inertial(cfg, k))
        assert tgt["start_s"] == summary["targets"][k]["start_s"]
    assert targets[-1]["end_s"] == table[-1, INDEX["time"]]
    # The target shown: through each target's Mode 6-2 and hold, and at the hand-over.
    flights = [r for r in summary["modes"] if r["mode"] == "6-2"]
    for k, r in enumerate(flights):
        for t_s in (r["start_s"], 0.5 * (r["start_s"] + r["end_s"]), r["end_s"]):
            assert replay.target_at(targets, t_s)["name"] == targets[k]["name"]
    assert replay.target_at(targets, targets[1]["start_s"] - 0.05) == targets[0]
    assert replay.target_at(targets, targets[1]["start_s"]) == targets[1]
    # Without the summary: the scenario's targets, each begun by the first mode after a 6-2.
    bare = replay.replay_data(table, None, cfg)["sky"]["targets"]
    assert [t["name"] for t in bare] == [t["name"] for t in targets]
    interval = d["config"]["interval_s"]
    for a, b in zip(bare, targets):
        assert a["start_s"] == pytest.approx(b["start_s"], abs=interval + 1e-9)


def test_the_log_follows_each_mode_as_often_as_it_was_flown(three):
    how, table, summary, _, _, d = three
    flown = [e["mode"] for e in d["events"] if e["kind"] == "mode"]
    assert flown == [r["mode"] for r in summary["modes"]]  # "reacquire"/"recycle" included
    assert how in flown
    # Calibration sequencer 19 runs at the end of each Mode 4 and 5 flown, once each.
    t = table[:, INDEX["time"]]
    ends = [r["end_s"] for r in summary["modes"] if r["mode"] in ("4", "5")]
    cal = [e["t_s"] for e in d["events"]
           if e["kind"] == "action" and e["text"].startswith("calibration sequencer 19")]
    assert cal == [float(t[np.searchsorted(t, end + 1e-9) - 1]) for end in ends]
    assert not [e for e in d["events"] if "no switch step" in e.get("reason", "")]
    # At the hand-over row: the mode of no duration, its action and switches, then Mode 1.
    k = next(i for i, e in enumerate(d["events"]) if e["kind"] == "mode" and e["mode"] == how)
    kinds = [(e["kind"], e["mode"]) for e in d["events"][k:k + 4]]
    assert kinds[0] == ("mode", how) and kinds[-1] == ("mode", "1")
    assert ("switch", how) in kinds


def test_the_bitmask_holds_no_selector_bits(flown, three):
    """S7/S8 are read from the s7_s8 column, never from the switch bitmask."""
    for table in (flown[0], three[1]):
        masks = table[:, INDEX["switches"]].astype(np.int64)
        for k in SELECTORS:
            assert not np.any(masks >> (k - 1) & 1)
        assert set(np.unique(table[:, INDEX["s7_s8"]])) <= {0.0, 1.0, 2.0}


def test_a_withheld_calibration_shows_as_written_then_cleared(flown):
    """calibration.apply false: the words are written at the ends of Modes 4 and 5, then
    Mode 6-1 clears register 23 (the summary holds the cleared words)."""
    table, summary, cfg = flown
    neutral = {"roll": 1.0, "yaw": 1.0}
    withheld = {**summary, "calibration_applied": False,
                "calibration": {**summary["calibration"], "scale_factor": neutral,
                                "cross_coupling": dict.fromkeys(
                                    summary["calibration"]["cross_coupling"], 0.0)}}
    words = replay.replay_data(table, withheld, cfg)["registers"]["23"]
    assert [w["source"] for w in words] == ["start", "counters", "counters", "withheld"]
    lsb = cfg.electronics.vfc_pulse_weight_arcsec / (360 * 3600)
    cal = summary["calibration"]
    assert words[2]["sf_roll"] == pytest.approx(cal["scale_factor"]["roll"], abs=LATE_PULSES * lsb)
    assert words[2]["sf_yaw"] == pytest.approx(cal["scale_factor"]["yaw"], abs=LATE_PULSES * lsb)
    assert words[3]["sf_roll"] == 1.0 and words[3]["t_s"] == next(
        r["start_s"] for r in summary["modes"] if r["mode"] == "6-1")
