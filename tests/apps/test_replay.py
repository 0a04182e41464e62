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

from allsky.apps import events as event_words
from allsky.apps import replay, telemetry_files
from allsky.apps.cli import main
from allsky.computer.word_registers import WORD23
from allsky.hardware.wiring import SELECTORS
from allsky.sequencer import modes
from allsky.sim.telemetry import INDEX

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
    return replay.undelta(d)


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
    assert len(_undelta(cols["cont"]["q_w"]["d"])) == len(range(0, len(table), cols["stride"]))
    assert np.array_equal(_undelta(cols["exact"]["counter14"]), table[:, INDEX["counter14"]])
    assert len(cols["selector"]) == len(table)


def _bank_from_journal(journal, times, frame_s):
    """The switch bitmask at each telemetry row, from the journal's switch operations.

    A row at time T is written by the frame that ends at T; an operation
    between legs at t acts from the frame that starts at t, so the row shows
    the operations of t <= T - one frame.
    """
    ops = [e for e in journal if e["kind"] == "switch"]
    out, mask, k = np.empty(len(times), dtype=np.int64), 0, 0
    for i, t in enumerate(times):
        while k < len(ops) and ops[k]["t_s"] < t - 0.5 * frame_s:
            for s in ops[k]["close"]:
                mask |= 1 << (s - 1)
            for s in ops[k]["open"]:
                mask &= ~(1 << (s - 1))
            k += 1
        out[i] = mask
    return out


def test_the_journal_switch_operations_give_the_telemetry_bank_at_every_row(flown, data):
    """Two records of one flight agree: the loop's bitmask and the sequencer's journal."""
    table, summary, cfg = flown
    bank = _bank_from_journal(summary["events"], table[:, INDEX["time"]], cfg.mission.frame_s)
    assert np.array_equal(bank, table[:, INDEX["switches"]].astype(np.int64))
    switch_rows = [e for e in data["events"] if e["kind"] == "switch"]
    assert len(switch_rows) == len([e for e in summary["events"] if e["kind"] == "switch"])
    for e in switch_rows:
        assert e["reason"].startswith(("after \u00ab", "start of Mode")), e
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


def test_the_log_is_the_journal_in_words(flown, data):
    """Every row of the page's log is an entry of the journal, at its own time."""
    _, summary, _ = flown
    journal = [(e["t_s"], e["mode"]) for e in summary["events"]]
    for row in data["events"]:
        if row["kind"] != "warning":  # the summary's warnings, at the time each names
            assert (row["t_s"], row["mode"]) in journal, row
    assert data["journal"] == summary["events"]


@pytest.mark.parametrize("mode", [m.name for m in modes.MODE_TABLE])
def test_every_mode_has_one_plain_sentence(mode):
    text = event_words.mode_sentence(mode)
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


def test_every_frame_telemetry_fits_in_6_mb():
    """The default mission recorded at every frame (10x the rows) still makes a page <= 6 MB."""
    from allsky.config import load_scenario
    from allsky.sim.mission import Mission

    cfg = load_scenario(overrides=["mission.telemetry_every_frames=1"])
    m = Mission(cfg)
    m.run()
    table = m.telemetry()
    assert len(table) > 130_000
    page = replay.render_html(replay.replay_data(table, m.summary(), cfg))
    assert len(page.encode()) <= 6e6


@pytest.mark.parametrize("ints", [[], [5], [1, 1, 1, 1], [0, 0, 3, 3, 3, 3, 2, -7, -7, -7],
                                  list(range(0, 50, 10)) + [40] * 9 + [41, 43]])
def test_the_delta_encoding_round_trips(ints):
    """Deltas with runs of equal deltas as [delta, count] decode to the integers exactly."""
    encoded = replay._delta(ints)
    assert replay.undelta(encoded).tolist() == list(ints)
    assert all(e[1] >= 3 for e in encoded if isinstance(e, list))


def test_every_fault_kind_marks_a_box_holding_its_block():
    """The vocabulary's numerals for each fault kind are drawn in the box that holds them."""
    from allsky.apps import diagram_layout
    from allsky.vocabulary import AXES, FAULT_KINDS

    for kind in FAULT_KINDS:
        specs = ([{"kind": kind.name, "axis": a} for a in AXES] if "axis" in kind.fields
                 else [{"kind": kind.name, "register": r} for r in ("13", "16", "27")]
                 if "register" in kind.fields else [{"kind": kind.name}])
        for spec in specs:
            boxes = replay.fault_boxes(spec)
            assert boxes and set(boxes) <= set(diagram_layout.BOXES), spec
            numerals = [n for b in boxes for n in replay._first_numeral_block(b).numerals]
            if "axis" in spec and len(kind.blocks) == 3:
                assert kind.blocks[AXES.index(spec["axis"])] in numerals
            elif "register" in spec:
                assert spec["register"] in numerals
            elif kind.blocks != ("",):
                assert set(kind.blocks) <= set(numerals)
            else:
                assert boxes == [diagram_layout.VEHICLE_BOX]  # the tank
    assert replay.fault_boxes({"kind": "gyro_dead", "axis": "pitch"}) == ["1"]  # gyro 2


def test_the_page_carries_the_ending_faults_star_and_warnings_from_the_journal():
    """Mariner 4's dust glints without recovery: each fault's onset and end, the star in the
    slit, the abort."""
    from allsky.config import load_scenario
    from allsky.sim.mission import Mission

    cfg = load_scenario("mariner4-dust-glints", ["sequencer.recovery=false"])
    m = Mission(cfg)
    m.run()
    summary, table = m.summary(), m.telemetry()
    d = replay.replay_data(table, summary, cfg, replay.describe_scenario("mariner4-dust-glints"))
    journal = summary["events"]
    onsets = [e for e in journal if e["kind"] == "fault" and e["active"]]
    assert [(f["start_s"], f["kind"]) for f in d["faults"]] == [
        (e["t_s"], e["fault_kind"]) for e in onsets]
    for f in d["faults"]:
        ends = [e["t_s"] for e in journal if e["kind"] == "fault" and not e["active"]
                and e["fault"] == f["index"]]
        assert f["end_s"] == (ends[0] if ends else None)
        assert f["boxes"] == ["105"]
    assert d["faults"][-1]["end_s"] is None  # the last glint lasts past the abort
    assert [(e["t_s"], e["star"]) for e in d["tracker"]] == [
        (e["t_s"], e["star"]) for e in journal if e["kind"] == "star_lock"]
    abort = next(e for e in journal if e["kind"] == "abort")
    end = d["ending"]
    assert end["status"] == "aborted" and end["reason"] == summary["abort_reason"]
    assert end["t_s"] == pytest.approx(min(abort["t_s"], table[-1, INDEX["time"]]))
    assert end["propellant_kg"] == summary["end"]["propellant_kg"]
    assert d["mission"]["name"] == "mariner4-dust-glints"
    assert d["mission"]["title"].startswith("Mariner 4")
    assert "ABORTED" in replay.page_title(d)


def test_warnings_are_placed_at_the_times_they_are_about():
    """A clipped DAC at S1's closing, the tumble where Mode 6-2 declared the target reached;
    the page's warnings are the summary's, read from its journal, not parsed from text."""
    from allsky.config import load_scenario
    from allsky.sim.mission import Mission

    clipped = load_scenario(None, ["gyro.drift_deg_h=[4.0,0.0,0.0]",
                                   "electronics.integrator_drift_deg_h=[2.0,0.0,0.0]"])
    tumbling = load_scenario("gyro-failure-to-target", [])
    for cfg, count in ((clipped, 1), (tumbling, 2)):
        summary = Mission(cfg, telemetry=False).run()
        got = replay._warnings(summary, cfg)
        assert [w["text"] for w in got] == summary["warnings"] and len(got) == count
        if cfg is clipped:
            at = next(e["t_s"] for e in summary["events"]
                      if e["kind"] == "switch" and 1 in e["close"])
        else:
            at = next(r["end_s"] for r in summary["modes"] if r["mode"] == "6-2")
        assert [w["t_s"] for w in got] == [at] * count
    assert replay._warnings({"warnings": ["an older summary"]}, clipped) == []


def test_describe_scenario_reads_the_files_comment():
    d = replay.describe_scenario("voyager1-wrong-star", ["target.hold_s=60"])
    assert d["name"] == "voyager1-wrong-star" and d["title"].startswith("Voyager 1-like")
    assert "Rigil Kentaurus" in d["description"] and d["overrides"] == ["target.hold_s=60"]
    default = replay.describe_scenario()
    assert default["name"] == "default" and default["title"].startswith("Default allsky")


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
    """One word set per calibration flown, in force from the end of its turn, exactly."""
    how, _, summary, _, stored, d = three
    words = d["registers"]["23"]
    assert words[0]["source"] == "start"
    assert [w["t_s"] for w in words[1:]] == [t for t, _ in stored]
    assert len(stored) == (2 if how == "reacquire" else 6)  # Modes 4 and 5, once per target
    for w, (_, truth) in zip(words[1:], stored):
        assert [w[k] for k in WORD23] == list(truth[list(WORD23.values())]), w
        assert w["source"] == "journal"
    cal = summary["calibration"]
    assert words[-1]["sf_roll"] == cal["scale_factor"]["roll"]
    assert words[-1]["yaw_into_roll"] == cal["cross_coupling"]["yaw_into_roll"]
    # In every Mode 6 register 23 holds the calibration of its own target's cycle.
    for r in summary["modes"]:
        if r["mode"] == "6-1":
            in_force = [w for w in words if w["t_s"] <= r["start_s"]][-1]
            assert in_force["source"] != "start" and in_force["sf_roll"] != 1.0


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
    how, _, summary, _, _, d = three
    flown = [e["mode"] for e in d["events"] if e["kind"] == "mode"]
    assert flown == [r["mode"] for r in summary["modes"]]  # "reacquire"/"recycle" included
    assert how in flown
    # Calibration sequencer 19 runs at the end of each Mode 4 and 5 flown, once each.
    ends = [r["end_s"] for r in summary["modes"] if r["mode"] in ("4", "5")]
    cal = [e["t_s"] for e in d["events"]
           if e["kind"] == "action" and e["text"].startswith("calibration sequencer 19")]
    assert cal == ends
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


def test_a_withheld_calibration_shows_as_written_then_cleared():
    """calibration.apply false: the words are written at the ends of Modes 4 and 5, then
    Mode 6-1 clears register 23 (the summary holds the cleared words)."""
    from allsky.config import load_scenario
    from allsky.sim.mission import Mission

    m = Mission(load_scenario(overrides=["calibration.apply=false"]), telemetry=True)
    m.run()
    summary, written = m.summary(), {}
    words = replay.replay_data(m.telemetry(), summary, m.cfg)["registers"]["23"]
    assert [w["source"] for w in words] == ["start", "journal", "journal", "withheld"]
    assert words[1]["written"] == ["roll_into_pitch", "roll_into_yaw", "sf_roll"]
    assert words[2]["written"] == sorted(WORD23) and words[3]["written"] == []
    for e in summary["events"]:
        if e["kind"] == "register" and e["register"] == "23" and e["mode"] in ("4", "5"):
            written[e["word"]] = e["value"]
    assert words[2]["sf_roll"] == written["sf_roll"] != 1.0
    assert words[2]["sf_yaw"] == written["sf_yaw"] != 1.0
    assert words[3]["sf_roll"] == 1.0 and words[3]["t_s"] == next(
        r["start_s"] for r in summary["modes"] if r["mode"] == "6-1")
    assert summary["calibration"]["scale_factor"] == {"roll": 1.0, "yaw": 1.0}
