"""The board: one writer of the hardware between legs, state and journal in one call.

Three promises. (1) Nothing outside ``sim/`` assigns into the state's arrays
(read from the source with ``ast``, through aliases too). (2) The view the
sequencer reads refuses writes. (3) Whatever the board is asked to do, in
any order, the hardware it leaves is the hardware its journal entries
describe: replaying the entries rebuilds registers 23 and 24, the counters,
the drift counters and the rate-command directions exactly (hypothesis).
"""

import ast
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from allsky.computer import word_registers as wr
from allsky.config import load_scenario
from allsky.hardware import switch_bank
from allsky.sim import board
from allsky.sim.mission import Mission
from allsky.sim.state import State
from allsky.vocabulary import AXES

SRC = Path(__file__).resolve().parents[2] / "src" / "allsky"
FIELDS = set(State._fields)


def _writes_into_state(tree):
    """``X.<field>[...] = ...`` (or ``+=``), and the same through a name bound to one."""
    aliases = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Assign) and isinstance(node.value, ast.Attribute) \
                and node.value.attr in FIELDS:
            aliases |= {t.id for t in node.targets if isinstance(t, ast.Name)}
    found = []
    for node in ast.walk(tree):
        targets = (node.targets if isinstance(node, ast.Assign)
                   else [node.target] if isinstance(node, ast.AugAssign) else [])
        for t in targets:
            if not isinstance(t, ast.Subscript):
                continue
            v = t.value
            if (isinstance(v, ast.Attribute) and v.attr in FIELDS) or \
                    (isinstance(v, ast.Name) and v.id in aliases):
                found.append(node.lineno)
    return found


def test_nothing_outside_sim_assigns_into_the_state():
    found = []
    for path in sorted(SRC.rglob("*.py")):
        where = path.relative_to(SRC)
        if where.parts[0] == "sim":
            continue
        for line in _writes_into_state(ast.parse(path.read_text())):
            found.append(f"{where}:{line}")
    assert not found, f"state written outside sim/ (use the board): {found}"


def test_the_rule_finds_a_write():
    """The rule is not vacuous: it finds a direct write and one through an alias."""
    assert _writes_into_state(ast.parse("m.state.word23[0] = 1.0"))
    assert _writes_into_state(ast.parse("w = m.view.word23\nw[2] += 1.0"))
    assert not _writes_into_state(ast.parse("w = m.view.word23\nx = w[2]"))


def test_the_sequencer_s_view_is_read_only():
    m = Mission(load_scenario(), telemetry=False)
    with pytest.raises(ValueError, match="read-only"):
        m.view.word23[0] = 2.0
    m.board.load_word23({"sf_roll": 1.25})
    assert m.view.word23[wr.SF_ROLL] == 1.25  # a view of the same memory


def _replay(events, pulse_arcsec):
    """The hardware the register entries describe, rebuilt from them alone."""
    word23 = wr.neutral_computed()
    word24 = np.zeros(2)
    counters, drift, sign = np.zeros(3, np.int64), np.zeros(3, np.int64), np.ones(2, np.int64)
    for e in events:
        if e["kind"] != "register":
            continue
        r = e["register"]
        if r == "23":
            word23[wr.WORD23[e["word"]]] = e["value"]
        elif r == "24":
            word24[wr.PROGRAMMED_ROLL if e["word"] == "roll" else wr.PROGRAMMED_YAW] = \
                e["value"] * 3600.0
        elif r in board.COUNTERS:
            counters[board.COUNTERS.index(r)] = e["pulses"]
        elif r in board.DRIFT_COUNTERS:
            drift[board.DRIFT_COUNTERS.index(r)] = e["pulses"]
        elif r in board.RATE_COMMANDS.values():
            sign[board.RATE_SIGN[e["word"]]] = int(e["value"])
    return word23, word24, counters, drift, sign


_axis = st.sampled_from(AXES)
#: The bank's on/off switches (the selectors S7/S8 move with the computer's steps).
ON_OFF = tuple(k for k in range(1, switch_bank.N_SWITCHES + 1) if k not in switch_bank.SELECTORS)


def _with_mates(ks):
    return sorted({m for k in ks for m in (k, switch_bank.COUPLED.get(k, k))})

_calls = st.one_of(
    st.tuples(st.just("clear_counters")),
    st.tuples(st.just("clear_drift")),
    st.tuples(st.just("clear_cpu")),
    st.tuples(st.just("preset_counters"),
              st.dictionaries(_axis, st.floats(-1e5, 1e5), min_size=1)),
    st.tuples(st.just("load_drift"),
              st.dictionaries(_axis, st.integers(-(1 << 20), 1 << 20), min_size=1)),
    st.tuples(st.just("set_rate_sign"), st.sampled_from(("roll", "yaw")),
              st.sampled_from((1, -1))),
    st.tuples(st.just("load_word23"),
              st.dictionaries(st.sampled_from(tuple(wr.WORD23)), st.floats(-2.0, 2.0),
                              min_size=1)),
    st.tuples(st.just("load_word24"), st.one_of(st.none(), st.floats(-180, 180)),
              st.one_of(st.none(), st.floats(-180, 180))),
    st.tuples(st.just("neutral_word23")),
    st.tuples(st.just("switch"), st.lists(st.sampled_from(ON_OFF), max_size=3),
              st.lists(st.sampled_from(ON_OFF), max_size=3)),
)
_MISSION = Mission(load_scenario(), telemetry=False)


@settings(max_examples=60, deadline=None)
@given(st.lists(_calls, max_size=25), st.sampled_from(("master sequencer 20", "a study")))
def test_the_journal_is_the_hardware(calls, by):
    m = Mission.from_snapshot(*_MISSION.snapshot(), telemetry=False)
    start = len(m.journal)
    for name, *args in calls:
        if name == "switch":
            close = _with_mates(args[0])
            m.board.switch(close=close, open_=[
                k for k in _with_mates(args[1])
                if k not in close and switch_bank.COUPLED.get(k, k) not in close], by=by)
        else:
            getattr(m.board, name)(*args, by=by)
    new = m.journal.events[start:]
    word23, word24, counters, drift, sign = _replay(m.journal.events, m.pulse_weight_arcsec)
    assert np.array_equal(word23, m.view.word23)
    assert np.allclose(word24, m.view.word24, rtol=1e-15, atol=0)
    assert np.array_equal(counters, m.view.counters)
    assert np.array_equal(drift, m.view.drift_counters)
    assert np.array_equal(sign, m.view.rate_sign)
    assert all(e["by"] == by for e in new if e["kind"] == "register")
    if any(c[0] == "clear_cpu" for c in calls):
        assert not m.view.cpu.any()


def test_a_study_s_loads_are_journaled_as_its_own():
    """The Kalman filter's calibration is in the journal, by it, and agrees with the summary."""
    from allsky.studies import kalman_mekf

    m = Mission(load_scenario(), telemetry=False)
    params = np.zeros(12)
    params[0:3] = np.radians(np.array([1.0, -0.5, 0.25]) / 3600.0)  # [rad/s]: deg/h
    kalman_mekf.load(m, params)
    loads = [e for e in m.journal.of_kind("register") if e["by"] == "the Kalman filter"]
    assert {e["register"] for e in loads} == {"23", *board.DRIFT_COUNTERS}
    cal = m.calibration()
    words = {**cal["scale_factor"], **cal["cross_coupling"]}
    for e in loads:
        if e["register"] == "23":
            key = {"sf_roll": "roll", "sf_yaw": "yaw"}.get(e["word"], e["word"])
            assert e["value"] == words[key]
        else:
            axis = AXES[board.DRIFT_COUNTERS.index(e["register"])]
            assert e["value"] == pytest.approx(cal["drift_applied_deg_h"][axis], rel=1e-12)
            assert abs(e["value"] - [1.0, -0.5, 0.25][AXES.index(axis)]) < 0.01


def test_the_summary_s_fields_are_declared_and_checked():
    """A summary carries only declared fields, every one it must; a stray key is refused."""
    from allsky.sim import record

    m = Mission(load_scenario(), telemetry=False)
    summary = m.run()
    assert set(summary) <= set(record.SUMMARY_FIELD)
    assert {f.name for f in record.SUMMARY_FIELDS if f.always} <= set(summary)
    with pytest.raises(ValueError, match="undeclared"):
        record.check_summary({**summary, "pointing_eror": 1.0})
    with pytest.raises(ValueError, match="missing"):
        record.check_summary({k: v for k, v in summary.items() if k != "status"})


def test_what_readers_check_of_a_summary_is_declared():
    """apps/summaries checks a summary read back by a shape whose fields are all declared."""
    from allsky.apps import summaries
    from allsky.sim import record

    assert {k.rstrip("!") for k in summaries.SHAPE} <= set(record.SUMMARY_FIELD)
