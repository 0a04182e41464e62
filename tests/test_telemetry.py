"""Telemetry columns, their documentation, and the CSV and Parquet files.

Truth: the column list in docs/telemetry.md is generated from
``telemetry.COLUMNS`` and must equal what the code generates; the recorder
writes the columns in :func:`allsky.sim.frame_loop._record`'s order, ``N_TLM`` of
them; a file read back equals the table written, bit for bit.
"""

from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from allsky.apps.cli import main
from allsky.hardware import switch_bank
from allsky.sim import frame_loop, telemetry
from allsky.sim.mission import MODE_CODE

DOCS = Path(__file__).resolve().parents[1] / "docs"


@pytest.fixture(scope="module")
def table(saved_states):
    """Telemetry of the default mission (flown once per test session, conftest.py)."""
    return saved_states["mission"].telemetry()


def bits(a):
    """Bit patterns, so that equality means exactly equal (also -0.0 and nan)."""
    return np.ascontiguousarray(a, dtype=np.float64).view(np.int64)


# -- the columns and their documentation -------------------------------------------------

def test_columns_match_the_recorder():
    assert len(telemetry.COLUMNS) == frame_loop.N_TLM
    names = [c.name for c in telemetry.COLUMNS]
    assert len(set(names)) == len(names)
    for c in telemetry.COLUMNS:
        assert c.unit and c.meaning, c


def test_header_carries_the_units():
    h = telemetry.header()
    assert h[:3] == ["time [s]", "mode [-]", "q_w [-]"]
    assert "rate_x [rad/s]" in h and "propellant [kg]" in h and "amp31 [V]" in h


def test_committed_column_list_is_what_the_code_generates():
    committed = (DOCS / "telemetry.md").read_text()
    assert committed == telemetry.markdown(), (
        "docs/telemetry.md is out of date: run "
        "`python -m allsky.sim.telemetry --markdown > docs/telemetry.md`")


def test_column_list_names_every_column_with_unit_and_meaning():
    page = telemetry.markdown()
    for i, (c, h) in enumerate(zip(telemetry.COLUMNS, telemetry.header())):
        assert f"| {i} | `{h}` | {c.unit} | {c.meaning} |" in page


def test_module_prints_the_column_list(capsys):
    assert telemetry.main(["--markdown"]) == 0
    assert capsys.readouterr().out == telemetry.markdown()


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
    path = telemetry.write(tmp_path / f"t{suffix}", table)
    back, names = telemetry.read(path)
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
    back, _ = telemetry.read(telemetry.write(tmp_path / f"a{suffix}", t))
    assert np.array_equal(bits(back), bits(t))


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_empty_table_round_trips(tmp_path, suffix):
    back, _ = telemetry.read(telemetry.write(tmp_path / f"e{suffix}",
                                             np.empty((0, len(telemetry.COLUMNS)))))
    assert back.shape == (0, len(telemetry.COLUMNS))


def test_parquet_columns_are_float64_with_units_in_names(tmp_path, table):
    t = pq.read_table(telemetry.write(tmp_path / "t.parquet", table[:50]))
    assert t.column_names == telemetry.header()
    assert all(f.type == pa.float64() for f in t.schema)


@pytest.mark.parametrize("name", ["t.txt", "t.json", "t", "t.csv.gz", "t.parq"])
def test_other_suffixes_are_refused_by_name(tmp_path, name):
    suffix = Path(name).suffix
    with pytest.raises(telemetry.TelemetryError, match="use .csv or .parquet") as e:
        telemetry.write(tmp_path / name, np.zeros((1, len(telemetry.COLUMNS))))
    assert (repr(suffix) if suffix else "no suffix") in str(e.value)
    assert not (tmp_path / name).exists()
    with pytest.raises(telemetry.TelemetryError, match="use .csv or .parquet"):
        telemetry.read(tmp_path / name)


def _drop_csv_column(src, dst, name):
    rows = [line.split(",") for line in src.read_text().splitlines()]
    k = rows[0].index(name)
    dst.write_text("\n".join(",".join(r[:k] + r[k + 1:]) for r in rows) + "\n")


def test_csv_without_a_documented_column_is_refused_naming_it(tmp_path, table):
    src = telemetry.write(tmp_path / "full.csv", table[:20])
    _drop_csv_column(src, tmp_path / "cut.csv", "counter16 [pulses]")
    with pytest.raises(telemetry.TelemetryError, match=r"missing column 'counter16 \[pulses\]'"):
        telemetry.read(tmp_path / "cut.csv")


def test_parquet_without_a_documented_column_is_refused_naming_it(tmp_path, table):
    t = pq.read_table(telemetry.write(tmp_path / "full.parquet", table[:20]))
    pq.write_table(t.drop_columns(["propellant [kg]"]), tmp_path / "cut.parquet")
    with pytest.raises(telemetry.TelemetryError, match=r"missing column 'propellant \[kg\]'"):
        telemetry.read(tmp_path / "cut.parquet")


def test_renamed_unit_is_a_missing_column(tmp_path, table):
    t = pq.read_table(telemetry.write(tmp_path / "full.parquet", table[:5]))
    names = ["time [ms]" if n == "time [s]" else n for n in t.column_names]
    pq.write_table(t.rename_columns(names), tmp_path / "ms.parquet")
    with pytest.raises(telemetry.TelemetryError, match=r"missing column 'time \[s\]'"):
        telemetry.read(tmp_path / "ms.parquet")


def test_extra_column_is_refused_naming_it(tmp_path, table):
    t = pq.read_table(telemetry.write(tmp_path / "full.parquet", table[:5]))
    t = t.append_column("temperature [K]", pa.array(np.zeros(5)))
    pq.write_table(t, tmp_path / "extra.parquet")
    with pytest.raises(telemetry.TelemetryError, match=r"unexpected column 'temperature \[K\]'"):
        telemetry.read(tmp_path / "extra.parquet")


def test_columns_in_another_order_are_put_back_in_order(tmp_path, table):
    t = pq.read_table(telemetry.write(tmp_path / "full.parquet", table[:30]))
    pq.write_table(t.select(list(reversed(t.column_names))), tmp_path / "rev.parquet")
    back, _ = telemetry.read(tmp_path / "rev.parquet")
    assert np.array_equal(bits(back), bits(table[:30]))


def test_not_a_parquet_file_is_refused(tmp_path):
    (tmp_path / "x.parquet").write_text("time [s]\n1.0\n")
    with pytest.raises(telemetry.TelemetryError, match="not a Parquet file"):
        telemetry.read(tmp_path / "x.parquet")


def test_csv_with_text_values_is_refused(tmp_path, table):
    src = telemetry.write(tmp_path / "t.csv", table[:3])
    lines = src.read_text().splitlines()
    lines[2] = "abc" + lines[2][lines[2].index(","):]
    src.write_text("\n".join(lines) + "\n")
    with pytest.raises(telemetry.TelemetryError, match="not a table of numbers"):
        telemetry.read(src)


# -- the command line ---------------------------------------------------------------------

def test_run_writes_parquet_telemetry(tmp_path, capsys, table):
    path = tmp_path / "tlm.parquet"
    assert main(["run", "--telemetry", str(path)]) == 0
    back, _ = telemetry.read(path)
    # Same scenario and seed: the same telemetry as the mission flown by the fixture.
    assert np.array_equal(bits(back), bits(table))


def test_run_refuses_a_bad_telemetry_suffix_before_flying(tmp_path, capsys):
    assert main(["run", "--telemetry", str(tmp_path / "tlm.xlsx")]) == 2
    out, err = capsys.readouterr()
    assert err.startswith("allsky: error: telemetry file") and "'.xlsx'" in err
    assert len(err.strip().splitlines()) == 1
    assert "Mode timeline" not in out  # refused before the mission was flown
    assert not (tmp_path / "tlm.xlsx").exists()
