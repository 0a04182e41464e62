"""Telemetry columns (allsky.sim.telemetry), their page and the CSV and Parquet files (apps).

Truth: the column list in docs/telemetry.md is generated from
``telemetry.COLUMNS`` and must equal what the code generates; the recorder
(:mod:`allsky.sim.recorder`) puts every value in the column its name says;
a file read back equals the table written, bit for bit.
"""

import csv
import itertools
import re
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from allsky import clock
from allsky.apps import telemetry_files
from allsky.apps.cli import main
from allsky.hardware import switch_bank
from allsky.sim import recorder, telemetry
from allsky.sim.mission import MODE_CODE
from allsky.sim.state import new_state
from allsky.vehicle import quaternion, sky

DOCS = Path(__file__).resolve().parents[2] / "docs"


@pytest.fixture(scope="module")
def table(saved_states):
    """Telemetry of the default mission (flown once per test session, conftest.py)."""
    return saved_states["mission"].telemetry()


def bits(a):
    """Bit patterns, so that equality means exactly equal (also -0.0 and nan)."""
    return np.ascontiguousarray(a, dtype=np.float64).view(np.int64)


# -- the columns and their documentation -------------------------------------------------

def test_columns_have_unique_names_a_unit_and_a_meaning():
    names = [c.name for c in telemetry.COLUMNS]
    assert len(set(names)) == len(names)
    for c in telemetry.COLUMNS:
        assert c.unit and c.meaning, c


def test_the_recorder_writes_every_value_under_its_name():
    s = new_state(np.array([0.5, 0.5, -0.5, 0.5]), [1e-3, -2e-3, 3e-3], 3.25)
    s.counters[:] = [14, 16, 18]
    s.drift_counters[:] = [13, 15, 17]
    s.registers[:] = [25, 26, 27]
    s.pwpf_out[:] = [1, 0, -1]
    s.cpu[:6] = [101.0, 102.0, 103.0, 104.0, 105.0, 106.0]
    switch_bank.operate(s.switches, close=(1, 14, 15, 16, 18))
    switch_bank.select(s.switches, 2)
    s.overflow[:] = [0, 1, 0, 0, 0, 1]
    s.frame[0] = 20
    tlm, rows = np.full((2, recorder.N_TLM), np.nan), np.zeros(1, dtype=np.int64)
    fine, trk, volts = np.array([9.0, 10.0, 1.0]), np.array([12.0, 13.0, 0.0]), np.array(
        [-0.5, 0.25, 2.0])
    s.target_inertial[:] = sky.radec_to_unit(30.0, -40.0)
    s.jet_on_s[:] = [1.25, 2.5, 3.75]
    hb, ub = np.array([0.5, -0.25, 0.125]), np.array([0.01, 0.02, -0.03])
    gyro = np.array([7.5, 0.0, -2.25])  # the gyros' outputs [arcsec/s]: a dead pitch gyro
    args = (clock.clock(0.625), s, 6.2, fine, trk, gyro, volts, hb, ub, 1)  # frame 20: 12.5 s
    recorder.record_telemetry(tlm, rows, 7, *args)  # frame 20: not a 7th
    assert rows[0] == 0
    recorder.record_telemetry(tlm, rows, 10, *args)
    assert rows[0] == 1
    row = dict(zip((c.name for c in telemetry.COLUMNS), tlm[0]))
    expect = {
        "time": 12.5, "mode": 6.2, "q_w": 0.5, "q_x": 0.5, "q_y": -0.5, "q_z": 0.5,
        "rate_x": 1e-3, "rate_y": -2e-3, "rate_z": 3e-3,
        "sun_pitch": 9.0, "sun_yaw": 10.0, "sun_present": 1.0,
        "tracker_yaw": 12.0, "tracker_pitch": 13.0, "star_present": 0.0,
        "counter14": 14, "counter16": 16, "counter18": 18,
        "drift_counter13": 13, "drift_counter15": 15, "drift_counter17": 17,
        "register25": 25, "register26": 26, "register27": 27,
        "valve_roll": 1, "valve_pitch": 0, "valve_yaw": -1,
        "amp31": -0.5, "amp32": 0.25, "amp33": 2.0,
        "error_roll": 104.0, "error_pitch": 105.0, "error_yaw": 106.0,
        "propellant": 3.25, "switches": switch_bank.bitmask(s.switches), "s7_s8": 2,
        "overflow": 0b100010,
        "corrected_roll": 101.0, "corrected_yaw": 102.0, "intermediate_pitch": 103.0,
        "wheel_h_x": 0.5, "wheel_h_y": -0.25, "wheel_h_z": 0.125,
        "wheel_torque_x": 0.01, "wheel_torque_y": 0.02, "wheel_torque_z": -0.03,
        "unloading": 1, "jet_on_roll": 1.25, "jet_on_pitch": 2.5, "jet_on_yaw": 3.75,
        "gyro_roll": 7.5, "gyro_pitch": 0.0, "gyro_yaw": -2.25,
    }
    true_error = row.pop("true_error")
    assert row == expect
    # The true error: the roll axis (first row of the body-from-inertial matrix) to the
    # target, by the vehicle's own quaternion helpers and the sky's separation.
    x_inertial = quaternion.dcm_body_from_inertial(s.x[0:4])[0]
    assert true_error == pytest.approx(
        sky.separation_deg(x_inertial, s.target_inertial) * 3600.0, abs=1e-6)
    assert np.isnan(tlm[1]).all()


def test_header_carries_the_units():
    h = telemetry.header()
    assert h[:3] == ["time [s]", "mode [-]", "q_w [-]"]
    assert "rate_x [rad/s]" in h and "propellant [kg]" in h and "amp31 [V]" in h


def test_committed_column_list_is_what_the_code_generates():
    committed = (DOCS / "telemetry.md").read_text()
    assert committed == telemetry_files.markdown(), (
        "docs/telemetry.md is out of date: run "
        "`python -m allsky.apps.telemetry_files --markdown > docs/telemetry.md`")


def test_column_list_names_every_column_with_unit_and_meaning():
    page = telemetry_files.markdown()
    for i, (c, h) in enumerate(zip(telemetry.COLUMNS, telemetry.header())):
        assert f"| {i} | `{h}` | {c.unit} | {c.kind} |" in page
        assert page.count(c.meaning) >= 1


def test_every_column_is_a_whole_record():
    """Kind, allowed values and the replay's encoding agree with one another."""
    for c in telemetry.COLUMNS:
        assert c.kind in (recorder.TIME, recorder.CODE, recorder.REAL, recorder.INTEGER,
                          recorder.FLAG, recorder.SET, recorder.BITMASK), c
        if c.kind in (recorder.FLAG, recorder.SET, recorder.BITMASK, recorder.CODE):
            assert c.allowed is not None, c
        if c.kind == recorder.FLAG:
            assert tuple(c.allowed) == (0, 1)
        if c.replay == recorder.EXACT:
            assert c.kind == recorder.INTEGER, c
        if isinstance(c.replay, float):
            assert c.kind == recorder.REAL and c.replay > 0, c
    assert set(telemetry_files.INTEGER_COLUMNS) == {
        c.name for c in telemetry.COLUMNS
        if c.kind in (recorder.INTEGER, recorder.FLAG, recorder.SET, recorder.BITMASK)}


def test_formats_only_append_columns():
    numbers = sorted(recorder.FORMATS)
    assert numbers == list(range(1, recorder.FORMAT + 1))
    for a, b in itertools.pairwise(numbers):
        old, new = recorder.FORMATS[a], recorder.FORMATS[b]
        assert new[:len(old)] == old and len(new) > len(old)
    assert recorder.FORMATS[recorder.FORMAT] == tuple(c.name for c in telemetry.COLUMNS)


def test_module_prints_the_column_list(capsys):
    assert telemetry_files.main(["--markdown"]) == 0
    assert capsys.readouterr().out == telemetry_files.markdown()


def test_mission_values_are_what_the_columns_say(table):
    col = telemetry.INDEX
    t = table[:, col["time"]]
    assert np.all(np.diff(t) > 0)
    assert set(np.unique(table[:, col["mode"]])) <= set(MODE_CODE.values())
    assert set(np.unique(table[:, col["mode"]])) >= {1.0, 2.0, 3.0, 4.0, 5.0, 6.1, 6.2}
    for name in ("valve_roll", "valve_pitch", "valve_yaw"):
        assert set(np.unique(table[:, col[name]])) <= {-1.0, 0.0, 1.0}
    for name in ("sun_present", "star_present"):
        assert set(np.unique(table[:, col[name]])) <= {0.0, 1.0}
    assert set(np.unique(table[:, col["s7_s8"]])) <= {0.0, 1.0, 2.0}
    q = table[:, col["q_w"]:col["q_z"] + 1]
    assert np.allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-9)
    prop = table[:, col["propellant"]]
    assert np.all(np.diff(prop) <= 0) and prop[0] <= 4.0
    # Mode 3 counts drift with S4-S6 closed and nothing else of them before it.
    mask = table[:, col["switches"]].astype(np.int64)
    assert np.all(mask < (1 << switch_bank.N_SWITCHES))
    assert not np.any(mask & ((1 << 6) | (1 << 7)))  # S7, S8 are not in the bitmask
    s4 = telemetry.switch_closed(table, 4)
    assert s4.any() and np.all(table[s4, col["mode"]] == 3.0)


# -- files ---------------------------------------------------------------------------------

@pytest.mark.parametrize("suffix", [".csv", ".parquet", ".CSV"])
def test_mission_telemetry_round_trips_exactly(tmp_path, table, suffix):
    path = telemetry_files.write(tmp_path / f"t{suffix}", table)
    back, names = telemetry_files.read(path)
    assert names == telemetry.header()
    assert back.shape == table.shape
    assert np.array_equal(bits(back), bits(table))


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_awkward_values_round_trip_exactly(tmp_path, suffix):
    rng = np.random.default_rng(3)
    t = rng.standard_normal((7, len(telemetry.COLUMNS))) * 10.0 ** rng.integers(-300, 300,
                                                                               (7, 1))
    t[0, :5] = [-0.0, 5e-324, 1.7976931348623157e308, 2.0 ** 53 + 2, 0.1]
    t[1, 0] = np.nan
    t[2, 0] = -np.inf
    back, _ = telemetry_files.read(telemetry_files.write(tmp_path / f"a{suffix}", t),
                                   check=False)
    assert np.array_equal(bits(back), bits(t))


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_empty_table_round_trips(tmp_path, suffix):
    back, _ = telemetry_files.read(telemetry_files.write(tmp_path / f"e{suffix}",
                                             np.empty((0, len(telemetry.COLUMNS)))))
    assert back.shape == (0, len(telemetry.COLUMNS))


def test_parquet_columns_are_float64_with_units_in_names(tmp_path, table):
    t = pq.read_table(telemetry_files.write(tmp_path / "t.parquet", table[:50]))
    assert t.column_names == telemetry.header()
    assert all(f.type == pa.float64() for f in t.schema)


@pytest.mark.parametrize("name", ["t.txt", "t.json", "t", "t.csv.gz", "t.parq"])
def test_other_suffixes_are_refused_by_name(tmp_path, name):
    suffix = Path(name).suffix
    with pytest.raises(telemetry_files.TelemetryError, match="use .csv or .parquet") as e:
        telemetry_files.write(tmp_path / name, np.zeros((1, len(telemetry.COLUMNS))))
    assert (repr(suffix) if suffix else "no suffix") in str(e.value)
    assert not (tmp_path / name).exists()
    with pytest.raises(telemetry_files.TelemetryError, match="use .csv or .parquet"):
        telemetry_files.read(tmp_path / name)


def _drop_csv_column(src, dst, name):
    first, *lines = src.read_text().splitlines()
    rows = [line.split(",") for line in lines]
    k = rows[0].index(name)
    dst.write_text(first + "\n" + "\n".join(",".join(r[:k] + r[k + 1:]) for r in rows) + "\n")


def test_csv_without_a_documented_column_is_refused_naming_it(tmp_path, table):
    src = telemetry_files.write(tmp_path / "full.csv", table[:20])
    _drop_csv_column(src, tmp_path / "cut.csv", "counter16 [pulses]")
    with pytest.raises(telemetry_files.TelemetryError, match=r"missing column 'counter16 \[pulses\]'"):
        telemetry_files.read(tmp_path / "cut.csv")


def test_parquet_without_a_documented_column_is_refused_naming_it(tmp_path, table):
    t = pq.read_table(telemetry_files.write(tmp_path / "full.parquet", table[:20]))
    pq.write_table(t.drop_columns(["propellant [kg]"]), tmp_path / "cut.parquet")
    with pytest.raises(telemetry_files.TelemetryError, match=r"missing column 'propellant \[kg\]'"):
        telemetry_files.read(tmp_path / "cut.parquet")


def test_renamed_unit_is_a_missing_column(tmp_path, table):
    t = pq.read_table(telemetry_files.write(tmp_path / "full.parquet", table[:5]))
    names = ["time [ms]" if n == "time [s]" else n for n in t.column_names]
    pq.write_table(t.rename_columns(names), tmp_path / "ms.parquet")
    with pytest.raises(telemetry_files.TelemetryError, match=r"missing column 'time \[s\]'"):
        telemetry_files.read(tmp_path / "ms.parquet")


def test_extra_column_is_refused_naming_it(tmp_path, table):
    t = pq.read_table(telemetry_files.write(tmp_path / "full.parquet", table[:5]))
    t = t.append_column("temperature [K]", pa.array(np.zeros(5)))
    pq.write_table(t, tmp_path / "extra.parquet")
    with pytest.raises(telemetry_files.TelemetryError, match=r"unexpected column 'temperature \[K\]'"):
        telemetry_files.read(tmp_path / "extra.parquet")


def test_columns_in_another_order_are_put_back_in_order(tmp_path, table):
    t = pq.read_table(telemetry_files.write(tmp_path / "full.parquet", table[:30]))
    pq.write_table(t.select(list(reversed(t.column_names))), tmp_path / "rev.parquet")
    back, _ = telemetry_files.read(tmp_path / "rev.parquet")
    assert np.array_equal(bits(back), bits(table[:30]))


def test_not_a_parquet_file_is_refused(tmp_path):
    (tmp_path / "x.parquet").write_bytes(b"PAR1 and then nothing of the format PAR1")
    with pytest.raises(telemetry_files.TelemetryError, match="not a readable Parquet file"):
        telemetry_files.read(tmp_path / "x.parquet")
    (tmp_path / "x.parquet").write_bytes(b"\x00\x01 binary")
    with pytest.raises(telemetry_files.TelemetryError, match="not a Parquet file$"):
        telemetry_files.read(tmp_path / "x.parquet")


def test_csv_with_text_values_is_refused(tmp_path, table):
    src = telemetry_files.write(tmp_path / "t.csv", table[:3])
    lines = src.read_text().splitlines()
    lines[3] = "abc" + lines[3][lines[3].index(","):]
    src.write_text("\n".join(lines) + "\n")
    with pytest.raises(telemetry_files.TelemetryError,
                       match=r"row 2 \(line 4\), column 'time \[s\]': 'abc' is not a number"):
        telemetry_files.read(src)


# -- a file no mission wrote is refused, naming the file, the first bad row and column -----

def _edited_csv(tmp_path, table, edit, name="t.csv"):
    t = table[:40].copy()
    edit(t)
    return telemetry_files.write(tmp_path / name, t)


def _set(col, value, row=5):
    def edit(t):
        t[row, telemetry.INDEX[col]] = value
    return edit


def _shuffled(t):
    t[:] = t[np.random.default_rng(1).permutation(len(t))]


@pytest.mark.parametrize("edit, words", [
    (_set("rate_y", np.nan), "row 6 (line 8), column 'rate_y [rad/s]': nan is not a finite number"),
    (_set("amp31", -np.inf), "row 6 (line 8), column 'amp31 [V]': -inf is not a finite number"),
    (_set("time", 0.3), "row 6 (line 8), column 'time [s]': 0.3 does not follow 0.5"),
    (_set("time", -0.1, 0), "row 1 (line 3), column 'time [s]': -0.1: mission time is >= 0"),
    (_shuffled, "column 'time [s]': "),
    (_set("mode", 9.0), ("row 6 (line 8), column 'mode [-]': 9.0 is not a mode code (1, 2, 3, 4, "
                        "5, 6.1, 6.2, 6.3, 6.4, 6.5, 6.6, 6.7, 6.8, 6.9, 7)")),
    (_set("mode", 6.15), "6.15 is not a mode code"),
    (_set("q_w", 1e308), "row 6 (line 8), column 'q_w [-]': quaternion [1e+308, "),
    (_set("q_x", 0.01), "is not of unit norm (within 1e-06)"),
    (_set("counter16", 2.5), ("row 6 (line 8), column 'counter16 [pulses]': 2.5 is not an "
                             "integer")),
    (_set("valve_yaw", 2.0), "column 'valve_yaw [-]': 2.0 is not one of -1, 0, 1"),
    (_set("star_present", 0.5), "column 'star_present [-]': 0.5 is not one of 0, 1"),
    (_set("s7_s8", 3.0), "column 's7_s8 [axis]': 3.0 is not one of 0, 1, 2"),
    (_set("switches", 2.0 ** 19), ("column 'switches [bitmask S1..S19]': 524288.0 is not one of "
                                  "0..524287")),
    (_set("overflow", 64.0), "64.0 is not one of 0..63"),
])
@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_values_no_mission_writes_are_refused(tmp_path, capsys, table, edit, words, suffix):
    path = _edited_csv(tmp_path, table, edit, f"t{suffix}")
    if suffix == ".parquet":
        words = re.sub(r" \(line \d+\)", "", words)
    with pytest.raises(telemetry_files.TelemetryError) as e:
        telemetry_files.read(path)
    assert str(e.value).startswith(f"telemetry file {str(path)!r}: ") and words in str(e.value)
    assert main(["plot", str(path), "--out", str(tmp_path / "fig")]) == 2
    assert capsys.readouterr().err == f"allsky: error: {e.value}\n"
    assert not (tmp_path / "fig").exists()  # refused before drawing


@pytest.mark.parametrize("make, words", [
    (lambda p, t: p.write_bytes(b"time [s]\n\xff\xfe\n"), "line 2: not UTF-8 text (byte 0xff)"),
    (lambda p, t: telemetry_files.write_parquet(p, t[:5]), ("a Parquet file, not CSV: name it "
                                                           ".parquet")),
    (lambda p, t: p.mkdir(), "cannot read it: a directory, not a file"),
    (lambda p, t: None, "cannot read it: no such file"),
    (lambda p, t: p.write_text('time [s]\n"unclosed\n'), ("missing column 'mode [-]' (and 38 "
                                                           "more) of telemetry format 1; see "
                                                           "docs/telemetry.md")),
])
def test_files_that_are_not_csv_telemetry_are_refused(tmp_path, capsys, table, make, words):
    path = tmp_path / "t.csv"
    make(path, table)
    assert main(["plot", str(path)]) == 2
    assert capsys.readouterr().err == f"allsky: error: telemetry file {str(path)!r}: {words}\n"


def test_csv_renamed_parquet_is_named_as_csv(tmp_path, capsys, table):
    path = telemetry_files.write_csv(tmp_path / "t.parquet", table[:5])
    assert main(["plot", str(path)]) == 2
    assert capsys.readouterr().err == (f"allsky: error: telemetry file {str(path)!r}: a CSV file, "
                                       "not Parquet: name it .csv\n")


def test_parquet_with_text_or_empty_cells_is_refused(tmp_path, table):
    t = pq.read_table(telemetry_files.write(tmp_path / "full.parquet", table[:5]))
    k = t.column_names.index("amp32 [V]")
    pq.write_table(t.set_column(k, "amp32 [V]", pa.array(["x"] * 5)), tmp_path / "text.parquet")
    with pytest.raises(telemetry_files.TelemetryError, match=r"column 'amp32 \[V\]' holds "
                                                             "string, not numbers"):
        telemetry_files.read(tmp_path / "text.parquet")
    cells = pa.array([1.0, None, 3.0, 4.0, 5.0], type=pa.float64())
    pq.write_table(t.set_column(k, "amp32 [V]", cells), tmp_path / "null.parquet")
    with pytest.raises(telemetry_files.TelemetryError, match=r"row 2, column 'amp32 \[V\]': "
                                                             "empty"):
        telemetry_files.read(tmp_path / "null.parquet")


def test_a_csv_row_of_the_wrong_width_is_refused(tmp_path, table):
    path = telemetry_files.write(tmp_path / "t.csv", table[:4])
    path.write_text(path.read_text() + "1.0,2.0\n")
    with pytest.raises(telemetry_files.TelemetryError, match=r"row 5 \(line 7\): 2 fields, the "
                                                             f"header has {recorder.N_TLM}"):
        telemetry_files.read(path)


# -- the command line ---------------------------------------------------------------------

def test_run_writes_parquet_telemetry(tmp_path, capsys, table):
    path = tmp_path / "tlm.parquet"
    assert main(["run", "--telemetry", str(path)]) == 0
    back, _ = telemetry_files.read(path)
    # Same scenario and seed: the same telemetry as the mission flown by the fixture.
    assert np.array_equal(bits(back), bits(table))


def test_run_refuses_a_bad_telemetry_suffix_before_flying(tmp_path, capsys):
    assert main(["run", "--telemetry", str(tmp_path / "tlm.xlsx")]) == 2
    out, err = capsys.readouterr()
    assert err.startswith("allsky: error: --telemetry: cannot write") and "'.xlsx'" in err
    assert len(err.strip().splitlines()) == 1
    assert "Mode timeline" not in out  # refused before the mission was flown
    assert not (tmp_path / "tlm.xlsx").exists()


# -- files of an earlier format -------------------------------------------------------------

def _format1_csv(path, table):
    """A file as allsky wrote it before the format number: format 1's columns, no number."""
    n = len(recorder.FORMATS[1])
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(telemetry.header()[:n])
        w.writerows([repr(float(v)) for v in row[:n]] for row in table)
    return path


def test_a_file_of_an_earlier_format_is_read_with_what_it_lacks_as_nan(tmp_path, table):
    path = _format1_csv(tmp_path / "old.csv", table[:30])
    back, names = telemetry_files.read(path)
    n = len(recorder.FORMATS[1])
    assert names == telemetry.header() and back.shape == (30, len(telemetry.COLUMNS))
    assert np.array_equal(bits(back[:, :n]), bits(table[:30, :n]))
    assert np.isnan(back[:, n:]).all()
    old = pq.read_table(telemetry_files.write(tmp_path / "new.parquet", table[:30]))
    old = old.select(telemetry.header()[:n]).replace_schema_metadata({})
    pq.write_table(old, tmp_path / "old.parquet")
    back, _ = telemetry_files.read(tmp_path / "old.parquet")
    assert np.array_equal(bits(back[:, :n]), bits(table[:30, :n]))
    assert np.isnan(back[:, n:]).all()


def test_a_file_of_a_later_format_is_refused_in_one_line(tmp_path, table):
    path = telemetry_files.write(tmp_path / "t.csv", table[:5])
    text = path.read_text().replace(f"format {recorder.FORMAT}", f"format {recorder.FORMAT + 1}")
    path.write_text(text)
    with pytest.raises(telemetry_files.TelemetryError,
                       match=f"telemetry format {recorder.FORMAT + 1}, written by a newer "
                             "allsky"):
        telemetry_files.read(path)
    t = pq.read_table(telemetry_files.write(tmp_path / "t.parquet", table[:5]))
    t = t.replace_schema_metadata({telemetry_files.PARQUET_FORMAT_KEY: b"9"})
    pq.write_table(t, tmp_path / "later.parquet")
    with pytest.raises(telemetry_files.TelemetryError, match="telemetry format 9"):
        telemetry_files.read(tmp_path / "later.parquet")


def test_an_earlier_format_file_with_a_later_column_is_refused(tmp_path, table):
    """Format 1 never had the true error: such a file is not one allsky wrote."""
    n = len(recorder.FORMATS[1])
    path = tmp_path / "mixed.csv"
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(telemetry.header()[:n + 1])
        w.writerows([repr(float(v)) for v in row[:n + 1]] for row in table[:3])
    with pytest.raises(telemetry_files.TelemetryError,
                       match=r"unexpected column 'true_error \[arcsec\]' of telemetry "
                             "format 1"):
        telemetry_files.read(path)


def test_files_carry_their_format(tmp_path, table):
    csv_path = telemetry_files.write(tmp_path / "t.csv", table[:3])
    assert csv_path.read_text().splitlines()[0].startswith(
        f"# allsky telemetry format {recorder.FORMAT}; rows ")
    meta = pq.read_table(telemetry_files.write(tmp_path / "t.parquet", table[:3])).schema.metadata
    assert meta[telemetry_files.PARQUET_FORMAT_KEY] == str(recorder.FORMAT).encode()
