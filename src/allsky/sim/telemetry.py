"""Telemetry recorder: the columns the frame loop writes, their units and meanings, and export.

The loop fills a float64 table, one row every ``mission.telemetry_every_frames``
frames. Integers (counters, registers, switch bitmask) are exact in float64.

Files carry the unit in every column name, ``name [unit]`` (``time [s]``).
The format follows the file's suffix: ``.csv`` (text, every value written
with its shortest exact decimal form) or ``.parquet`` (Apache Parquet,
float64 columns). Both read back bit-identical (:func:`read`).

``python -m allsky.sim.telemetry --markdown`` prints ``docs/telemetry.md``, the
column list generated from :data:`COLUMNS`.
"""

import argparse
import csv
from pathlib import Path
from typing import NamedTuple

import numpy as np


class Column(NamedTuple):
    """One telemetry column."""

    name: str  #: short name, as in :data:`INDEX`
    unit: str  #: unit written in brackets after the name in files
    meaning: str  #: what the value is, with the patent numeral of its block


#: The columns, in the order :func:`allsky.sim.frame_loop._record` writes them.
COLUMNS = (
    Column("time", "s", "mission time since ejection"),
    Column("mode", "-", "mode code: 1, 2, 3, 4, 5, 6.1, 6.2 (7: dither comparison mode); "
                        "`mission.MODE_CODE`"),
    Column("q_w", "-", "attitude quaternion inertial -> body, scalar part"),
    Column("q_x", "-", "attitude quaternion, x part"),
    Column("q_y", "-", "attitude quaternion, y part"),
    Column("q_z", "-", "attitude quaternion, z part"),
    Column("rate_x", "rad/s", "true body rate about +x (roll)"),
    Column("rate_y", "rad/s", "true body rate about +y (pitch)"),
    Column("rate_z", "rad/s", "true body rate about +z (yaw)"),
    Column("sun_pitch", "arcsec", "sun sensor 104 pitch output (linear within "
                                  "`sun_sensor.linear_range_arcsec`, saturated beyond; "
                                  "0 when the Sun is absent)"),
    Column("sun_yaw", "arcsec", "sun sensor 104 yaw output"),
    Column("sun_present", "-", "1 when the Sun is inside the sun sensor's presence cone"),
    Column("tracker_yaw", "arcsec", "star tracker 105 yaw output (rotation about +x that "
                                    "brings the star to the boresight)"),
    Column("tracker_pitch", "arcsec", "star tracker 105 pitch output (rotation about +y)"),
    Column("star_present", "-", "1 when the tracker is locked on a star of its "
                                "magnitude window"),
    Column("counter14", "pulses", "roll up/down counter 14 (one pulse = "
                                  "`electronics.vfc_pulse_weight_arcsec`)"),
    Column("counter16", "pulses", "pitch up/down counter 16"),
    Column("counter18", "pulses", "yaw up/down counter 18"),
    Column("drift_counter13", "pulses", "roll drift counter 13 (Mode 3 count; feeds drift "
                                        "DAC 7)"),
    Column("drift_counter15", "pulses", "pitch drift counter 15 (drift DAC 9)"),
    Column("drift_counter17", "pulses", "yaw drift counter 17 (drift DAC 11)"),
    Column("register25", "lsb", "roll storage register 25 (one lsb = "
                                "`electronics.register_lsb_arcsec`)"),
    Column("register26", "lsb", "pitch storage register 26"),
    Column("register27", "lsb", "yaw storage register 27"),
    Column("valve_roll", "-", "roll valve command of PWPF modulator 34 to jets 39: "
                              "-1, 0 or +1"),
    Column("valve_pitch", "-", "pitch valve command, modulator 35, jets 40"),
    Column("valve_yaw", "-", "yaw valve command, modulator 36, jets 41"),
    Column("amp31", "V", "roll control amplifier 31 output"),
    Column("amp32", "V", "pitch control amplifier 32 output"),
    Column("amp33", "V", "yaw control amplifier 33 output"),
    Column("error_roll", "arcsec", "roll error computed by CPU 22 (Modes 6-1, 6-2)"),
    Column("error_pitch", "arcsec", "pitch error computed by CPU 22 (Mode 6-2)"),
    Column("error_yaw", "arcsec", "yaw error computed by CPU 22 (Mode 6-2)"),
    Column("propellant", "kg", "propellant remaining"),
    Column("switches", "bitmask S1..S19", "bit k-1 set when on/off switch Sk is closed "
                                          "(S7, S8 excluded); `switch_closed`"),
    Column("s7_s8", "axis", "axis selected by S7/S8 for CPU 22: 0 roll, 1 pitch, 2 yaw"),
    Column("overflow", "bitmask 14,16,18,13,15,17", "overflow flags latched by counters "
                                                    "14, 16, 18, 13, 15, 17 (bits 0 to 5)"),
    Column("corrected_roll", "arcsec", "CPU 22 roll angle turned, scale factor applied"),
    Column("corrected_yaw", "arcsec", "CPU 22 yaw angle turned, scale factor applied"),
    Column("intermediate_pitch", "arcsec", "CPU 22 pitch counter angle less the "
                                           "cross-coupling corrections"),
)
INDEX = {c.name: i for i, c in enumerate(COLUMNS)}
#: File suffix -> format name.
FORMATS = {".csv": "csv", ".parquet": "parquet"}


class TelemetryError(ValueError):
    """A telemetry file that cannot be written or read as such; ``str()`` is one line."""


def header() -> list:
    """Column names as written in files: ``name [unit]``."""
    return [f"{c.name} [{c.unit}]" for c in COLUMNS]


def file_format(path) -> str:
    """The format (``"csv"`` or ``"parquet"``) of a telemetry path, from its suffix.

    Raises
    ------
    TelemetryError
        For any other suffix, naming it.
    """
    suffix = Path(path).suffix.lower()
    if suffix not in FORMATS:
        shown = f"suffix {suffix!r}" if suffix else "no suffix"
        raise TelemetryError(f"telemetry file {str(path)!r}: {shown}; "
                             f"use {' or '.join(FORMATS)}")
    return FORMATS[suffix]


def write(path, table: np.ndarray) -> Path:
    """Write the telemetry table to ``path``, CSV or Parquet by its suffix."""
    fmt = file_format(path)
    table = np.asarray(table, dtype=np.float64).reshape(-1, len(COLUMNS))
    return write_csv(path, table) if fmt == "csv" else write_parquet(path, table)


def write_csv(path, table: np.ndarray) -> Path:
    """Write the telemetry table to CSV (``repr`` of each float: exact on reading back)."""
    path = Path(path)
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header())
        for row in table:
            w.writerow([repr(float(v)) for v in row])
    return path


def write_parquet(path, table: np.ndarray) -> Path:
    """Write the telemetry table to Parquet, one float64 column per telemetry column."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    path = Path(path)
    arrays = [pa.array(np.ascontiguousarray(table[:, i]), type=pa.float64())
              for i in range(len(COLUMNS))]
    pq.write_table(pa.Table.from_arrays(arrays, names=header()), path)
    return path


def _checked_order(path, names) -> list:
    """Indices that put the file's columns in :data:`COLUMNS` order; refuse others."""
    expected = header()
    missing = [n for n in expected if n not in names]
    if missing:
        more = f" (and {len(missing) - 1} more)" if len(missing) > 1 else ""
        raise TelemetryError(f"telemetry file {str(path)!r}: missing column "
                             f"{missing[0]!r}{more}; see docs/telemetry.md")
    extra = [n for n in names if n not in expected]
    if extra:
        raise TelemetryError(f"telemetry file {str(path)!r}: unexpected column "
                             f"{extra[0]!r}; see docs/telemetry.md")
    if len(set(names)) != len(names):
        raise TelemetryError(f"telemetry file {str(path)!r}: duplicated columns")
    return [names.index(n) for n in expected]


def read(path):
    """Read a telemetry file written by :func:`write` (CSV or Parquet, by suffix).

    Returns
    -------
    table : numpy.ndarray, shape (rows, len(COLUMNS))
        float64, columns in :data:`COLUMNS` order.
    names : list of str
        Column names with units, :func:`header`.

    Raises
    ------
    TelemetryError
        Unknown suffix, or columns other than the documented ones (the
        message names the first missing or unexpected column).
    OSError
        The file cannot be read.
    """
    path = Path(path)
    fmt = file_format(path)
    if fmt == "csv":
        with path.open(newline="") as f:
            rows = list(csv.reader(f))
        if not rows:
            raise TelemetryError(f"telemetry file {str(path)!r}: empty (no header)")
        order = _checked_order(path, rows[0])
        try:
            data = np.array(rows[1:], dtype=np.float64).reshape(-1, len(rows[0]))
        except ValueError as e:
            raise TelemetryError(f"telemetry file {str(path)!r}: not a table of numbers "
                                 f"({e})") from None
    else:
        import pyarrow as pa
        import pyarrow.parquet as pq

        try:
            t = pq.read_table(path)
        except pa.ArrowInvalid as e:  # not a Parquet file (a missing one is an OSError)
            raise TelemetryError(f"telemetry file {str(path)!r}: not a Parquet file "
                                 f"({e})") from None
        order = _checked_order(path, list(t.column_names))
        data = np.empty((t.num_rows, t.num_columns))
        for i in range(t.num_columns):
            data[:, i] = t.column(i).to_numpy()
    return np.ascontiguousarray(data[:, order]), header()


def switch_closed(table: np.ndarray, k: int) -> np.ndarray:
    """Boolean series: is on/off switch Sk closed in each row."""
    return (table[:, INDEX["switches"]].astype(np.int64) >> (k - 1)) & 1 == 1


def markdown() -> str:
    """The column list ``docs/telemetry.md``, generated from :data:`COLUMNS`."""
    lines = [
        "# Telemetry columns",
        "",
        ("<!-- Generated from allsky.sim.telemetry.COLUMNS by "
         "`python -m allsky.sim.telemetry --markdown > docs/telemetry.md`; do not edit. -->"),
        "",
        ("`allsky run --telemetry PATH` writes one row every "
         "`mission.telemetry_every_frames` frames (default 10 frames = 0.1 s), as CSV "
         "(`.csv`) or Apache Parquet (`.parquet`) by the file's suffix. Every column name "
         "carries its unit, `name [unit]`; all values are float64 (integers are exact). "
         "`allsky.sim.telemetry.read(path)` reads either format back and refuses a file whose "
         "columns are not these. `allsky plot` draws the figures from such a file."),
        "",
        "| # | column in the file | unit | meaning |",
        "|---|---|---|---|",
    ]
    for i, (c, h) in enumerate(zip(COLUMNS, header())):
        lines.append(f"| {i} | `{h}` | {c.unit} | {c.meaning} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    """``python -m allsky.sim.telemetry --markdown``: print the column list."""
    p = argparse.ArgumentParser(prog="python -m allsky.sim.telemetry",
                                description="Print the telemetry column list.")
    p.add_argument("--markdown", action="store_true", required=True,
                   help="print docs/telemetry.md as generated from COLUMNS")
    p.parse_args(argv)
    print(markdown(), end="")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
