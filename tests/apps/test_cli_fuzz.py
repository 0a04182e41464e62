"""The command line against damaged and arbitrary files: an answer, never a traceback.

Every file the CLI reads besides a scenario -- telemetry for ``allsky plot``
(CSV and Parquet), a mission state for ``allsky step --from``, a campaign's
manifest and results for ``allsky montecarlo --resume`` -- is fed arbitrary
bytes and mutations of a valid file. Whatever the content, ``main`` returns
0, 1 or 2 and raises nothing, and exit 2 comes with exactly one line
``allsky: error: ...`` on stderr. (Scenario files have their own property
test in tests/apps/test_cli_config.py.)

Drawing the figures, flying the modes and flying campaign runs are replaced
by stubs: the readers are under test, and a valid file must not cost a
mission's worth of time per example.
"""

import io
import itertools
import json

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from allsky.apps import campaign, plots, states, telemetry_files
from allsky.apps.cli import main
from allsky.config import load_scenario
from allsky.sim.mission import Mission, ModeRecord
from allsky.sim.telemetry import COLUMNS
from allsky.studies import montecarlo

FUZZ = settings(max_examples=40, deadline=None, derandomize=True,
                suppress_health_check=[HealthCheck.function_scoped_fixture,
                                       HealthCheck.too_slow])
_names = itertools.count()

JUNK_CELLS = ["", "nan", "inf", "-inf", "1e999", "abc", "9", "-1", "0.5", "1e308", "6.15",
              "1_0", " 1", "\x00", "é", '"', "1,2"]
JUNK_JSON = [None, True, 0, -3, 1.5, 1e308, "twelve", "", [], {}, [1, 2], {"a": 1}, 2**70,
             "6-3", ["1", "2"], "legacy"]


def _fresh(tmp_path, name):
    d = tmp_path / f"{next(_names)}"
    d.mkdir()
    return d / name


def _answered(capsys, argv):
    """Run ``main``; check the code and, for exit 2, the single error line."""
    code = main(argv)
    _, err = capsys.readouterr()
    assert code in (0, 1, 2), (code, err)
    if code == 2:
        assert err.startswith("allsky: error:") and err.count("\n") == 1, err
    return code


# -- byte-level damage, shared by every file kind -------------------------------------------

@st.composite
def damaged(draw, valid: bytes):
    """``valid`` with a few bytes flipped, inserted or cut, or truncated."""
    data = bytearray(valid)
    for _ in range(draw(st.integers(1, 3))):
        kind = draw(st.sampled_from(["flip", "insert", "cut", "truncate"]))
        at = draw(st.integers(0, max(len(data) - 1, 0)))
        if kind == "flip" and data:
            data[at] ^= 1 << draw(st.integers(0, 7))
        elif kind == "insert":
            data[at:at] = draw(st.binary(min_size=1, max_size=8))
        elif kind == "cut":
            del data[at:at + draw(st.integers(1, 64))]
        else:
            del data[at:]
    return bytes(data)


def any_bytes_or_damaged(valid: bytes):
    return st.one_of(st.binary(max_size=600), damaged(valid),
                     st.binary(max_size=64).map(lambda b: valid[:8] + b + valid[-8:]))


# -- allsky plot: telemetry, CSV and Parquet ---------------------------------------------------

@pytest.fixture(scope="module")
def telemetry(saved_states):
    """Thirty rows of the default mission's telemetry."""
    return saved_states["mission"].telemetry()[100:130].copy()


@pytest.fixture()
def no_drawing(monkeypatch):
    monkeypatch.setattr(plots, "write_plots", lambda table, out, summary=None, progress=False:
                        plots.PlotSet([], {}))


@st.composite
def csv_texts(draw, table):
    """The CSV of ``table`` with cells replaced, lines dropped, duplicated or swapped."""
    rows = [line.split(",") for line in _csv(table).decode().splitlines()]
    for _ in range(draw(st.integers(1, 4))):
        kind = draw(st.sampled_from(["cell", "cell", "drop", "duplicate", "swap", "header"]))
        r = draw(st.integers(0, len(rows) - 1))
        if kind == "cell" and rows[r]:
            rows[r][draw(st.integers(0, len(rows[r]) - 1))] = draw(
                st.one_of(st.sampled_from(JUNK_CELLS), st.text(max_size=6)))
        elif kind == "drop":
            del rows[r]
        elif kind == "duplicate":
            rows.insert(r, list(rows[r]))
        elif kind == "swap":
            s = draw(st.integers(0, len(rows) - 1))
            rows[r], rows[s] = rows[s], rows[r]
        elif kind == "header" and rows:
            rows[0] = draw(st.permutations(rows[0]))[: draw(st.integers(0, len(rows[0])))]
        if not rows:
            break
    return ("\n".join(",".join(r) for r in rows) + "\n").encode("utf-8", "surrogatepass")


def _csv(table) -> bytes:
    buf = io.StringIO()
    buf.write(",".join(telemetry_files.header()) + "\n")
    for row in table:
        buf.write(",".join(repr(float(v)) for v in row) + "\n")
    return buf.getvalue().encode()


def _parquet(table, names=None) -> bytes:
    sink = pa.BufferOutputStream()
    names = names or telemetry_files.header()
    pq.write_table(pa.Table.from_arrays([pa.array(table[:, i]) for i in range(table.shape[1])],
                                        names=names), sink)
    return sink.getvalue().to_pybytes()


@st.composite
def parquet_files(draw, table):
    """The Parquet of ``table`` with values, rows or columns changed."""
    t = table.copy()
    names = telemetry_files.header()
    for _ in range(draw(st.integers(1, 3))):
        kind = draw(st.sampled_from(["value", "value", "shuffle", "rename", "drop_row"]))
        if kind == "value":
            t[draw(st.integers(0, len(t) - 1)), draw(st.integers(0, len(COLUMNS) - 1))] = draw(
                st.sampled_from([np.nan, np.inf, -1.0, 9.0, 0.5, 1e308, 2.0**19, 6.15]))
        elif kind == "shuffle":
            t = t[draw(st.permutations(range(len(t))))]
        elif kind == "rename":
            names = list(names)
            names[draw(st.integers(0, len(names) - 1))] = draw(st.text(max_size=8))
        elif len(t) > 1:
            t = np.delete(t, draw(st.integers(0, len(t) - 1)), axis=0)
    try:
        return _parquet(t, names)
    except (pa.ArrowException, ValueError):  # names pyarrow itself refuses
        return _parquet(t)


@FUZZ
@given(data=st.data())
def test_plot_answers_any_csv(capsys, tmp_path, telemetry, no_drawing, data):
    valid = _csv(telemetry)
    content = data.draw(st.one_of(any_bytes_or_damaged(valid), csv_texts(telemetry),
                                  st.just(_parquet(telemetry))))
    path = _fresh(tmp_path, "t.csv")
    path.write_bytes(content)
    _answered(capsys, ["plot", str(path), "--out", str(path.parent)])


@FUZZ
@given(data=st.data())
def test_plot_answers_any_parquet(capsys, tmp_path, telemetry, no_drawing, data):
    valid = _parquet(telemetry)
    content = data.draw(st.one_of(any_bytes_or_damaged(valid), parquet_files(telemetry),
                                  st.just(_csv(telemetry))))
    path = _fresh(tmp_path, "t.parquet")
    path.write_bytes(content)
    _answered(capsys, ["plot", str(path), "--out", str(path.parent)])


# -- allsky step --from: mission states ---------------------------------------------------------

@pytest.fixture()
def modes_not_flown(monkeypatch):
    """Each mode ends at once: the state file is what is under test, not the flight."""
    def run_mode(m, hooks=None):
        name = m.plan[m.next_mode]
        t = m.now_s()
        rec = ModeRecord(name, t, t, "not flown in this test")
        m.timeline.append(rec)
        m.next_mode += 1
        if m.next_mode == len(m.plan):
            m.status = "complete"
        return rec

    monkeypatch.setattr(Mission, "run_mode", run_mode)


def _npz(history, arrays) -> bytes:
    buf = io.BytesIO()
    np.savez(buf, history=np.array(json.dumps(history)),
             **{states.ARRAY_PREFIX + k: v for k, v in arrays.items()})
    return buf.getvalue()


@st.composite
def state_files(draw, history, arrays):
    """A saved state with history entries or arrays replaced."""
    h = json.loads(json.dumps(history))
    a = {k: v.copy() for k, v in arrays.items()}
    for _ in range(draw(st.integers(1, 3))):
        kind = draw(st.sampled_from(["history", "scenario", "array", "value", "drop"]))
        if kind == "history":
            h[draw(st.sampled_from(sorted(h)))] = draw(st.sampled_from(JUNK_JSON))
        elif kind == "scenario":
            sec = draw(st.sampled_from(sorted(h["scenario"])))
            if isinstance(h["scenario"][sec], dict) and h["scenario"][sec]:
                key = draw(st.sampled_from(sorted(h["scenario"][sec])))
                h["scenario"][sec][key] = draw(st.sampled_from(JUNK_JSON))
        elif kind == "array":
            a[draw(st.sampled_from(sorted(a)))] = np.zeros(
                draw(st.integers(0, 8)), dtype=draw(st.sampled_from(["f8", "i8", "u1", "f4"])))
        elif kind == "value":
            name = draw(st.sampled_from(sorted(a)))
            if a[name].size:
                a[name].flat[draw(st.integers(0, a[name].size - 1))] = draw(st.sampled_from(
                    [0, 1, 2, 3, -1, 255] if a[name].dtype.kind in "iu"
                    else [np.nan, np.inf, -1.0, 1e308, 0.0, 5.0]))
        else:
            a.pop(draw(st.sampled_from(sorted(a))), None)
    return _npz(h, a)


@FUZZ
@given(data=st.data())
def test_step_answers_any_state_file(capsys, tmp_path, saved_states, modes_not_flown, data):
    history, arrays = states.load(saved_states["6-1"], telemetry=False).snapshot()
    valid = _npz(history, arrays)
    content = data.draw(st.one_of(any_bytes_or_damaged(valid), state_files(history, arrays)))
    path = _fresh(tmp_path, "s.npz")
    path.write_bytes(content)
    _answered(capsys, ["step", "--no-pause", "--from", str(path)])


# -- allsky montecarlo --resume: manifest and results -----------------------------------------

def _stub_row(cfg, run, seed):
    row = dict.fromkeys(montecarlo.columns(cfg))
    # "aborted": a run flown (a campaign of rows that all raised exits 3, a defect).
    return {**row, "run": int(run), "seed": int(seed), "status": "aborted",
            "abort_reason": "not flown in this test"}


@pytest.fixture()
def runs_not_flown(monkeypatch):
    monkeypatch.setattr(montecarlo, "fly_one", _stub_row)
    monkeypatch.setattr(campaign, "plot_histograms", lambda rows, path: None)


@pytest.fixture(scope="module")
def recorded_campaign(tmp_path_factory):
    """A campaign of 3 stub runs of the default scenario: its manifest and results bytes."""
    out = tmp_path_factory.mktemp("campaign") / "c"
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(montecarlo, "fly_one", _stub_row)
        campaign.run_recorded(load_scenario(), runs=3, workers=1, out=out)
    return (out / campaign.MANIFEST).read_bytes(), (out / campaign.RESULTS).read_bytes()


@st.composite
def manifests(draw, valid: bytes):
    """The manifest with entries replaced (``runs`` kept small when it stays a count)."""
    m = json.loads(valid)
    key = draw(st.sampled_from(sorted(m)))
    m[key] = draw(st.one_of(st.sampled_from(JUNK_JSON), st.integers(-5, 12)))
    return json.dumps(m).encode()


@st.composite
def results_files(draw, valid: bytes):
    """The results with lines dropped, repeated or swapped and cells replaced."""
    lines = valid.decode().splitlines()
    for _ in range(draw(st.integers(1, 3))):
        kind = draw(st.sampled_from(["cell", "cell", "drop", "duplicate", "swap", "torn"]))
        r = draw(st.integers(0, len(lines) - 1))
        if kind == "cell":
            cells = lines[r].split(",")
            cells[draw(st.integers(0, len(cells) - 1))] = draw(
                st.one_of(st.sampled_from(JUNK_CELLS + ["3", "-1", "13", "done", "complete"]),
                          st.text(max_size=5)))
            lines[r] = ",".join(cells)
        elif kind == "drop":
            del lines[r]
        elif kind == "duplicate":
            lines.insert(r, lines[r])
        elif kind == "swap":
            s = draw(st.integers(0, len(lines) - 1))
            lines[r], lines[s] = lines[s], lines[r]
        else:
            lines[r] = lines[r][: len(lines[r]) // 2]
        if not lines:
            break
    return "\n".join(lines).encode("utf-8", "surrogatepass") + draw(st.sampled_from([b"\n", b""]))


def _runs_stay_small(manifest: bytes) -> bool:
    """A damaged manifest can ask, validly, for millions of runs: not here."""
    try:
        runs = json.loads(manifest).get("runs")
    except (ValueError, AttributeError):
        return True
    return not (isinstance(runs, int) and runs > 20)


@FUZZ
@given(data=st.data())
def test_resume_answers_any_manifest(capsys, tmp_path, recorded_campaign, runs_not_flown, data):
    manifest, results = recorded_campaign
    content = data.draw(st.one_of(any_bytes_or_damaged(manifest), manifests(manifest))
                        .filter(_runs_stay_small))
    out = _fresh(tmp_path, "c")
    out.mkdir()
    (out / campaign.MANIFEST).write_bytes(content)
    (out / campaign.RESULTS).write_bytes(results)
    _answered(capsys, ["montecarlo", "--out", str(out), "--resume", "--workers", "1", "--quiet"])


@FUZZ
@given(data=st.data())
def test_resume_answers_any_results(capsys, tmp_path, recorded_campaign, runs_not_flown, data):
    manifest, results = recorded_campaign
    content = data.draw(st.one_of(any_bytes_or_damaged(results), results_files(results)))
    out = _fresh(tmp_path, "c")
    out.mkdir()
    (out / campaign.MANIFEST).write_bytes(manifest)
    (out / campaign.RESULTS).write_bytes(content)
    _answered(capsys, ["montecarlo", "--out", str(out), "--resume", "--workers", "1", "--quiet"])


# -- allsky plot and replay: --summary files ---------------------------------------------------

@st.composite
def damaged_summaries(draw, summary):
    """``summary`` with fields replaced by junk, removed, or its nesting changed."""
    s = json.loads(json.dumps(summary))
    for _ in range(draw(st.integers(1, 3))):
        path, node = [], s
        while isinstance(node, dict | list) and node and draw(st.booleans()):
            key = draw(st.sampled_from(sorted(node) if isinstance(node, dict)
                                       else list(range(len(node)))))
            path.append(key)
            node = node[key]
        if not path:
            s = draw(st.sampled_from(JUNK_JSON))
            break
        parent = s
        for key in path[:-1]:
            parent = parent[key]
        if draw(st.booleans()) and isinstance(parent, dict):
            del parent[path[-1]]
        else:
            parent[path[-1]] = draw(st.one_of(st.sampled_from(JUNK_JSON),
                                              st.text(max_size=6)))
    return s


@pytest.fixture(scope="module")
def flown_summary(saved_states):
    return saved_states["mission"].summary()


@FUZZ
@given(data=st.data())
def test_plot_and_replay_answer_any_summary(capsys, tmp_path, telemetry, flown_summary, data):
    """A damaged summary is refused in one line (exit 2) or drawn; never an internal error."""
    tlm = _fresh(tmp_path, "t.csv")
    tlm.write_bytes(_csv(telemetry))
    s = data.draw(damaged_summaries(flown_summary))
    path = tlm.with_name("s.json")
    path.write_text(json.dumps(s))
    _answered(capsys, ["plot", str(tlm), "--summary", str(path), "--out",
                       str(tlm.with_name("figs")), "--quiet"])
    _answered(capsys, ["replay", str(tlm), "--summary", str(path), "--html",
                       str(tlm.with_name("r.html")), "--quiet"])
