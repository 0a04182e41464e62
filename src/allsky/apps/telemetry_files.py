"""Telemetry files: CSV and Parquet, written and read back bit for bit.

Also the column page, ``docs/telemetry.md``.

A telemetry table (:meth:`allsky.sim.mission.Mission.telemetry`) has one
float64 column per entry of :data:`allsky.sim.recorder.COLUMNS`. Files
carry the unit in every column name, ``name [unit]`` (``time [s]``,
:func:`allsky.sim.telemetry.header`), and the schema's format number
(:data:`allsky.sim.recorder.FORMAT`): a first line ``# allsky telemetry
format N; rows R`` in CSV (R: the rows, so that a file cut short
at a line boundary is refused as truncated), the key ``allsky.telemetry_format`` of the Parquet
file's metadata. The format follows the file's suffix: ``.csv`` (text,
every value written with its shortest exact decimal form) or ``.parquet``
(Apache Parquet, float64 columns). Both read back bit-identical
(:func:`read`). A file of an earlier format (no number: format 1) is read
when the later formats only appended columns, its missing columns NaN ("not
recorded"); a file of a later format than this allsky knows is refused.
Reading refuses, in one line naming the file and the first bad row and
column, a file whose columns are not its format's and values no mission
writes (:func:`check_table`): a non-finite cell, time not increasing, an
unknown mode code, a quaternion off unit norm, a value outside an integer
column's set.

``python -m allsky.apps.telemetry_files --markdown`` prints
``docs/telemetry.md``, the column list generated from ``COLUMNS``.
"""

import argparse
import csv
import io
from pathlib import Path

import numpy as np

from allsky.config.toml_io import os_reason, read_bounded
from allsky.sim import recorder
from allsky.sim.telemetry import COLUMNS, INDEX, header

#: File suffix -> format name.
FORMATS = {".csv": "csv", ".parquet": "parquet"}


class TelemetryError(ValueError):
    """A telemetry file that cannot be written or read as such; ``str()`` is one line."""


def file_format(path) -> str:
    """The format (``"csv"`` or ``"parquet"``) of telemetry ``path``, from its suffix.

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


def write(path, table: np.ndarray, option=None) -> Path:
    """Write the telemetry ``table`` to ``path``, CSV or Parquet by its suffix.

    The file is written whole or not at all (:func:`allsky.apps.output.write_atomic`);
    ``option`` names the command-line option in an
    :class:`~allsky.apps.output.OutputError`.
    """
    from allsky.apps.output import is_null_device

    fmt = "csv" if is_null_device(path) else file_format(path)  # the null device: any
    table = np.asarray(table, dtype=np.float64).reshape(-1, len(COLUMNS))
    return write_csv(path, table, option) if fmt == "csv" else write_parquet(path, table,
                                                                              option)


#: The first line of a CSV file: the schema's format.
CSV_FORMAT_LINE = "# allsky telemetry format {}"
#: What follows the format on that line: the number of rows, so that a file cut short at
#: a line boundary is known as such (files written before it have no count).
CSV_ROWS = "; rows {}"
#: The Parquet metadata key holding the schema's format.
PARQUET_FORMAT_KEY = b"allsky.telemetry_format"


def write_csv(path, table: np.ndarray, option=None) -> Path:
    """Write the telemetry table to CSV (each float as ``repr``: exact on reading).

    ``path``, ``table`` and ``option`` as for :func:`write`.
    """
    from allsky.apps.output import write_atomic

    def writer(tmp):
        with tmp.open("w", newline="") as f:
            f.write(CSV_FORMAT_LINE.format(recorder.FORMAT) + CSV_ROWS.format(len(table))
                    + "\n")
            w = csv.writer(f)
            w.writerow(header())
            for row in table:
                w.writerow([repr(float(v)) for v in row])

    return write_atomic(path, writer=writer, option=option)


def write_parquet(path, table: np.ndarray, option=None) -> Path:
    """Write the telemetry table to Parquet, one float64 column per telemetry column.

    ``path``, ``table`` and ``option`` as for :func:`write`.
    """
    import pyarrow as pa
    import pyarrow.parquet as pq

    from allsky.apps.output import write_atomic

    arrays = [pa.array(np.ascontiguousarray(table[:, i]), type=pa.float64())
              for i in range(len(COLUMNS))]
    schema = pa.schema([(n, pa.float64()) for n in header()],
                       metadata={PARQUET_FORMAT_KEY: str(recorder.FORMAT).encode()})
    return write_atomic(path, writer=lambda tmp: pq.write_table(
        pa.Table.from_arrays(arrays, schema=schema), tmp), option=option)


def _refuse(path, what) -> TelemetryError:
    return TelemetryError(f"telemetry file {str(path)!r}: {what}")


def _format_columns(path, number) -> int:
    """How many of :data:`COLUMNS` a file of format ``number`` holds; refuse unknown ones."""
    if number > recorder.FORMAT:
        raise _refuse(path, f"telemetry format {number}, written by a newer allsky; this one "
                            f"reads formats 1 to {recorder.FORMAT}")
    if number not in recorder.FORMATS:
        raise _refuse(path, f"telemetry format {number} is not one allsky wrote "
                            f"(formats {', '.join(map(str, recorder.FORMATS))})")
    return len(recorder.FORMATS[number])


def _checked_order(path, names, number=recorder.FORMAT) -> list:
    """Indices that put the file's columns in :data:`COLUMNS` order; refuse others.

    The file is of format ``number``: it holds that format's columns, the
    first of :data:`COLUMNS` (later formats only append).
    """
    expected = header()[:_format_columns(path, number)]
    missing = [n for n in expected if n not in names]
    if missing:
        more = f" (and {len(missing) - 1} more)" if len(missing) > 1 else ""
        raise _refuse(path, f"missing column {missing[0]!r}{more} of telemetry format "
                            f"{number}; see docs/telemetry.md")
    extra = [n for n in names if n not in expected]
    if extra:
        later = "" if number == recorder.FORMAT else f" of telemetry format {number}"
        raise _refuse(path, f"unexpected column {extra[0]!r}{later}; see docs/telemetry.md")
    if len(set(names)) != len(names):
        raise _refuse(path, "duplicated columns")
    return [names.index(n) for n in expected]


def _widened(table: np.ndarray) -> np.ndarray:
    """A table of an earlier format with the columns it lacks, NaN: not recorded."""
    if table.shape[1] == len(COLUMNS):
        return table
    out = np.full((table.shape[0], len(COLUMNS)), np.nan)
    out[:, :table.shape[1]] = table
    return out


#: [bytes] Largest telemetry file read: the longest mission records at most 1e6 rows
#: (config.schema.TELEMETRY_MAX_ROWS), under 1 kB each as CSV.
FILE_MAX_BYTES = 2**30
#: Parquet files begin (and end) with these four bytes.
PARQUET_MAGIC = b"PAR1"
#: Largest departure of a row's quaternion from unit norm: the plant keeps it within
#: 1e-15; a file off by more was not written by a mission.
QUATERNION_NORM_TOLERANCE = 1e-6
#: Columns of integers and the values each may hold (None: any integer), from the schema.
INTEGER_COLUMNS = {c.name: c.allowed for c in COLUMNS
                   if c.kind in (recorder.INTEGER, recorder.FLAG, recorder.SET,
                                 recorder.BITMASK)}


def read(path, check=True):
    """Read a telemetry file written by :func:`write` (CSV or Parquet, by suffix).

    Parameters
    ----------
    path : str or path-like
        The file.
    check : bool
        Refuse values no mission writes (:func:`check_table`); False reads any
        numbers in the documented columns.

    Returns
    -------
    table : numpy.ndarray, shape (rows, len(COLUMNS))
        float64, columns in :data:`COLUMNS` order; the columns a file of an
        earlier format lacks are NaN.
    names : list of str
        Column names with units, :func:`header`.

    Raises
    ------
    TelemetryError
        One line naming the file and, where it applies, the first bad row
        (CSV: also its line) and column: an unknown suffix, a file that cannot
        be read, text that is not UTF-8, a Parquet file named ``.csv`` or a
        CSV file named ``.parquet``, columns other than the documented ones
        (the first missing or unexpected one), a cell that is not a number,
        and with ``check`` the values :func:`check_table` refuses.
    """
    path = Path(path)
    fmt = file_format(path)
    try:
        data = read_bounded(path, FILE_MAX_BYTES, "telemetry file")
    except (OSError, ValueError) as e:  # missing, a directory, no permission, NUL in the name
        raise _refuse(path, f"cannot read it: {os_reason(e) if isinstance(e, OSError) else e}"
                      ) from None
    table, lines = (_read_csv(path, data) if fmt == "csv" else (_read_parquet(path, data), None))
    if check:
        check_table(table, path, lines)
    return _widened(table), header()


def _read_csv(path, data: bytes):
    """The table of a CSV file's bytes, and the line of each row."""
    if data.startswith(PARQUET_MAGIC):
        raise _refuse(path, "a Parquet file, not CSV: name it .parquet")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as e:
        line = data.count(b"\n", 0, e.start) + 1
        raise _refuse(path, f"line {line}: not UTF-8 text (byte 0x{data[e.start]:02x})") from None
    number, skipped, count = 1, 0, None
    first = text.split("\n", 1)[0].rstrip("\r")
    if first.startswith("#"):
        first, sep, rows_text = first.partition(CSV_ROWS.format("").rstrip())
        if sep:
            if not rows_text.strip().isdigit():
                raise _refuse(path, f"line 1: rows {_shown(rows_text.strip())} is not a count")
            count = int(rows_text.strip())
        number = _csv_format(path, first)
        skipped = 1
        text = text.split("\n", 1)[1] if "\n" in text else ""
    reader = csv.reader(io.StringIO(text, newline=""))
    rows, lines = [], []
    try:
        for record in reader:
            rows.append(record)
            lines.append(reader.line_num)
    except csv.Error as e:  # a field over the size limit, an unclosed quote
        raise _refuse(path, f"line {reader.line_num + skipped}: not CSV ({e})") from None
    lines = [n + skipped for n in lines]
    if not rows:
        raise _refuse(path, "empty (no header)")
    order = _checked_order(path, rows[0], number)
    width, body = len(rows[0]), rows[1:]
    for r, (record, line) in enumerate(zip(body, lines[1:], strict=True), start=1):
        if len(record) != width:
            raise _refuse(path, f"row {r} (line {line}): {len(record)} fields, the header "
                                f"has {width}")
    if count is not None and len(body) != count:
        raise _refuse(path, f"truncated: {len(body)} of the {count} rows its first line "
                      "promises (cut short)" if len(body) < count else
                      f"{len(body)} rows, more than the {count} its first line says")
    try:
        table = np.array(body, dtype=np.float64).reshape(-1, width)
    except ValueError:  # find the cell, and read what numpy would not
        table = np.empty((len(body), width))
        for r, (record, line) in enumerate(zip(body, lines[1:], strict=True), start=1):
            for c, text in enumerate(record):
                try:
                    table[r - 1, c] = float(text)
                except ValueError:
                    raise _refuse(path, f"row {r} (line {line}), column {rows[0][c]!r}: "
                                        f"{_shown(text)} is not a number") from None
    return np.ascontiguousarray(table[:, order]), lines[1:]


def _csv_format(path, line) -> int:
    """The format number of a CSV file's first line ``# allsky telemetry format N``."""
    head, _, number = line.rpartition(" ")
    if head != CSV_FORMAT_LINE.format("").rstrip() or not number.isdigit():
        raise _refuse(path, f"line 1: {_shown(line)} is not "
                            f"{CSV_FORMAT_LINE.format('N')!r}")
    return int(number)


def _shown(text, limit=40) -> str:
    return repr(text if len(text) <= limit else text[:limit] + "...")


def _read_parquet(path, data: bytes) -> np.ndarray:
    """The table of a Parquet file's bytes."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    if not (data.startswith(PARQUET_MAGIC) and data.endswith(PARQUET_MAGIC)):
        head = data[:200]
        looks_csv = head.lstrip(b'"').startswith(b"time [s]") or head.startswith(
            CSV_FORMAT_LINE.format("").encode())
        raise _refuse(path, "a CSV file, not Parquet: name it .csv" if looks_csv
                      else "not a Parquet file")
    try:
        t = pq.read_table(pa.BufferReader(data))
    except (pa.ArrowException, OSError, ValueError) as e:  # a damaged file
        raise _refuse(path, f"not a readable Parquet file ({_one_line(e)})") from None
    meta = t.schema.metadata or {}
    number = meta.get(PARQUET_FORMAT_KEY, b"1")
    if not number.isdigit():
        raise _refuse(path, f"metadata {PARQUET_FORMAT_KEY.decode()} = {number[:20]!r} is not "
                            "a format number")
    order = _checked_order(path, list(t.column_names), int(number))
    table = np.empty((t.num_rows, t.num_columns))
    for i, name in enumerate(t.column_names):
        col = t.column(i)
        if not (pa.types.is_floating(col.type) or pa.types.is_integer(col.type)):
            raise _refuse(path, f"column {name!r} holds {col.type}, not numbers")
        if col.null_count:
            row = next(r for r, x in enumerate(col.is_null().to_pylist(), start=1) if x)
            raise _refuse(path, f"row {row}, column {name!r}: empty")
        table[:, i] = col.to_numpy()
    return np.ascontiguousarray(table[:, order])


def _one_line(e) -> str:
    return " ".join(str(e).split())[:200]


def check_table(table, path="", lines=None) -> None:
    """Refuse a telemetry table no mission writes, naming the first bad row and column.

    Every cell finite; time >= 0 and strictly increasing; the mode a code of
    the mode table (:data:`allsky.sequencer.modes.MODE_CODE`); the quaternion
    of unit norm (within :data:`QUATERNION_NORM_TOLERANCE`); integers, within
    their sets, in :data:`INTEGER_COLUMNS`.

    Parameters
    ----------
    table : numpy.ndarray
        Rows of :data:`COLUMNS`.
    path : str or path-like
        The file, for the message.
    lines : sequence of int, optional
        The file's line of each row (CSV), for the message.

    Raises
    ------
    TelemetryError
        The first value that breaks a rule, by row (1-based) and column.
    """
    names = header()[:table.shape[1]]

    def bad(row_index, col, what):
        line = f" (line {lines[row_index]})" if lines is not None else ""
        return _refuse(path, f"row {row_index + 1}{line}, column {names[col]!r}: {what}")

    finite = np.isfinite(table)
    if not finite.all():
        r, c = np.argwhere(~finite)[0]
        raise bad(r, c, f"{float(table[r, c])!r} is not a finite number")
    t = table[:, INDEX["time"]]
    if len(t) and t[0] < 0:
        raise bad(0, INDEX["time"], f"{float(t[0])!r}: mission time is >= 0")
    back = np.flatnonzero(np.diff(t) <= 0)
    if back.size:
        r = int(back[0]) + 1
        raise bad(r, INDEX["time"], f"{float(t[r])!r} does not follow {float(t[r - 1])!r}: "
                                    "times must increase from row to row")
    codes = sorted(set(COLUMNS[INDEX["mode"]].allowed))
    mode = table[:, INDEX["mode"]]
    unknown = np.flatnonzero(~np.isin(mode, codes))
    if unknown.size:
        r = int(unknown[0])
        raise bad(r, INDEX["mode"], f"{float(mode[r])!r} is not a mode code "
                                    f"({', '.join(f'{c:g}' for c in codes)})")
    q = table[:, INDEX["q_w"]:INDEX["q_z"] + 1]
    with np.errstate(over="ignore"):  # a norm past the float range is inf: refused
        off = np.flatnonzero(~(np.abs(np.linalg.norm(q, axis=1) - 1.0)
                               <= QUATERNION_NORM_TOLERANCE))
    if off.size:
        r = int(off[0])
        raise bad(r, INDEX["q_w"], f"quaternion {q[r].tolist()} is not of unit norm "
                                   f"(within {QUATERNION_NORM_TOLERANCE:g})")
    for name, allowed in INTEGER_COLUMNS.items():
        c = INDEX[name]
        if c >= table.shape[1]:  # a column a file of an earlier format lacks
            continue
        x = table[:, c]
        wrong = x != np.round(x)
        if isinstance(allowed, range):
            wrong |= (x < allowed.start) | (x > allowed.stop - 1)
        elif allowed is not None:
            wrong |= ~np.isin(x, np.asarray(allowed, dtype=float))
        if wrong.any():
            r = int(np.flatnonzero(wrong)[0])
            kind = "an integer" if allowed is None else f"one of {_allowed_words(allowed)}"
            raise bad(r, c, f"{float(x[r])!r} is not {kind}")


def _allowed_words(allowed) -> str:
    if isinstance(allowed, range):
        return f"{allowed.start}..{allowed.stop - 1}"
    return ", ".join(map(str, allowed))


def _allowed_text(c) -> str:
    if c.allowed is None:
        return "any" if c.kind != recorder.INTEGER else "any integer"
    return _allowed_words(c.allowed)


def _replay_text(c) -> str:
    if isinstance(c.replay, float):
        return f"x {c.replay:g}, rounded"
    return {recorder.EXACT: "exact", recorder.RUNS: "runs", recorder.DIGITS: "digits"}.get(
        c.replay, "-")


def markdown() -> str:
    """The column page ``docs/telemetry.md``, from :data:`allsky.sim.recorder.COLUMNS`."""
    first = {}
    for number in sorted(recorder.FORMATS):
        for name in recorder.FORMATS[number]:
            first.setdefault(name, number)
    lines = [
        "# Telemetry columns",
        "",
        ("<!-- Generated from allsky.sim.recorder.COLUMNS by "
         "`python -m allsky.apps.telemetry_files --markdown > docs/telemetry.md`; "
         "do not edit. -->"),
        "",
        ("`allsky run --telemetry PATH` writes one row every "
         "`mission.telemetry_every_frames` frames (default 10 frames = 0.1 s), and one more "
         "at the flight's last frame when that falls between two (so the record ends where "
         "the mission ended: its last row is the summary's `end`), as CSV "
         "(`.csv`) or Apache Parquet (`.parquet`) by the file's suffix. Every column name "
         "carries its unit, `name [unit]`; all values are float64 (integers are exact). "
         "`allsky.apps.telemetry_files.read(path)` reads either format back and refuses a "
         "file whose columns are not these. `allsky plot` draws the figures from such a file."),
        "",
        (f"Files carry the schema's format number, now {recorder.FORMAT}: a first line "
         f"`{CSV_FORMAT_LINE.format(recorder.FORMAT)}{CSV_ROWS.format('N')}` in CSV (N the "
         "rows that follow the header, so that a file cut short at a line boundary is "
         "refused as truncated; a file without the count is read as it is), the metadata key "
         f"`{PARQUET_FORMAT_KEY.decode()}` in Parquet (a file without one is format 1). "
         "A format only appends columns to the one before, so a file of an earlier format "
         "is read, the columns it lacks given as NaN (not recorded); a file of a later "
         "format than the reader knows is refused in one line."),
        "",
        ("Each column is one record of `allsky.sim.recorder.COLUMNS`: the writer, the "
         "reader's checks (*values*), this page and the replay page's encoding (*replay*) "
         "are all derived from it. What happened between rows, when it happened, is in the "
         "journal of the summary (`events`, [journal.md](journal.md))."),
        "",
        "| # | column in the file | unit | kind | values | replay | since | meaning |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for i, (c, h) in enumerate(zip(COLUMNS, header())):
        lines.append(f"| {i} | `{h}` | {c.unit} | {c.kind} | {_allowed_text(c)} | "
                     f"{_replay_text(c)} | {first[c.name]} | {c.meaning} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    """``python -m allsky.apps.telemetry_files --markdown``: print the column list.

    ``argv`` are the arguments (None: the command line's); returns the exit status.
    """
    p = argparse.ArgumentParser(prog="python -m allsky.apps.telemetry_files",
                                description="Print the telemetry column list.")
    p.add_argument("--markdown", action="store_true", required=True,
                   help="print docs/telemetry.md as generated from COLUMNS")
    p.parse_args(argv)
    print(markdown(), end="")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
