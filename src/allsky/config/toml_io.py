"""TOML in and out: reading with one-line errors, values in TOML syntax, writing.

Reading wraps :mod:`tomllib`: a missing or unreadable file and a syntax
error (with its line and column) become :class:`~allsky.config.rules.ConfigError`
with no key. An integer literal longer than Python converts is read as a
:class:`LongInteger`, past any bound, so that the key's rule refuses it.
The writer covers what a scenario holds (tables of scalars, arrays and inline
tables); ``tomllib.loads`` reads its text back to equal data.
"""

import math
import os
import re
import stat
import sys
import tomllib
from collections.abc import Mapping
from datetime import date, datetime, time
from pathlib import Path

from allsky.config.rules import ConfigError

#: A TOML bare key (also one part of a dotted ``--set`` KEY).
BARE_KEY = re.compile(r"[A-Za-z0-9_-]+")
#: Marks a long integer literal read as a TOML string (it starts with a NUL, which no
#: scenario value does); in TOML text the NUL is written as an escape.
_LONG_MARK = "\x00long integer "
_LONG_MARK_TOML = _LONG_MARK.replace("\x00", "\\u0000")


# ---------------------------------------------------------------------------
# Reading
# ---------------------------------------------------------------------------

class LongInteger(int):
    """An integer literal with more digits than Python converts, shown by its size.

    Python turns at most ``sys.get_int_max_str_digits()`` decimal digits (4300
    by default) into an ``int``, so that a huge literal cannot stall a reader.
    Such a literal reads as this: an ``int`` of the literal's sign and
    magnitude ``10**limit``, beyond any bound a rule sets and any float, whose
    ``repr`` is the literal's start and its number of digits.
    """

    def __new__(cls, text: str):
        digits = sum(ch.isdigit() for ch in text)
        sign = -1 if text.lstrip().startswith("-") else 1
        self = super().__new__(cls, sign * 10 ** sys.get_int_max_str_digits())
        self.text, self.digits = text, digits
        return self

    def __repr__(self):
        return f"{self.text[:90]}... ({self.digits} digits)"

    __str__ = __repr__

    def __reduce__(self):
        return LongInteger, (self.text,)


def os_reason(e: OSError) -> str:
    """Why a file cannot be opened, in words (no errno number, no repeated path).

    ``e`` is the error that opening or reading it raised.
    """
    if isinstance(e, FileNotFoundError):
        return "no such file"
    if isinstance(e, IsADirectoryError):
        return "a directory, not a file"
    if isinstance(e, PermissionError):
        return "permission denied"
    return (e.strerror or type(e).__name__).lower()


#: [bytes] Largest scenario or ``--disperse`` file read (the packaged default is 9 kB).
TOML_MAX_BYTES = 2**20
#: [bytes] Bytes read at a time from a FIFO or a device.
_BLOCK = 2**20


def _size_text(n: int) -> str:
    for unit, size in (("GiB", 2**30), ("MiB", 2**20), ("kiB", 2**10)):
        if n >= size:
            return f"{n / size:g} {unit}"
    return f"{n} bytes"


#: [s] How long opening a FIFO may wait for its other end before a line says so.
FIFO_PARTNER_S = 1.0


def open_fifo_waiting(path, mode: str, what: str):
    """Open ``path``; a FIFO with no other end is reported, then waited for.

    Opening a FIFO blocks until a process opens its other end (a reader for
    an output, a writer for an input). After :data:`FIFO_PARTNER_S` one line
    on stderr says what is awaited; the wait goes on (Ctrl-C ends it). Any
    other path is opened at once. ``mode`` is ``open``'s; ``what`` names
    the file in the line.
    """
    try:
        is_fifo = stat.S_ISFIFO(os.stat(path).st_mode)
    except (OSError, ValueError):
        is_fifo = False
    if not is_fifo:
        return open(path, mode)
    import threading

    box = {}

    def opener():
        try:
            box["file"] = open(path, mode)  # noqa: SIM115 - the caller closes it
        except BaseException as e:  # noqa: BLE001 - handed to the waiting thread
            box["error"] = e

    t = threading.Thread(target=opener, name="allsky-fifo-open", daemon=True)
    t.start()
    t.join(FIFO_PARTNER_S)
    if t.is_alive():
        partner = "reader" if "w" in mode or "a" in mode else "writer"
        print(f"allsky: {what} {path} is a FIFO with no {partner} yet; waiting for one "
              "(Ctrl-C to stop)", file=sys.stderr, flush=True)
        while t.is_alive():
            t.join(0.1)
    if "error" in box:
        raise box["error"]
    return box["file"]


def read_bounded(path, limit: int, what: str) -> bytes:
    """The bytes of the file at ``path``; ConfigError past ``limit`` bytes.

    A regular file's size is looked at before anything is read; anything else
    (a FIFO, a device such as ``/dev/zero``, a pipe) is read in blocks until
    it ends or passes the limit, so that no input can fill the memory. The
    refusal is one line naming ``what`` (``"telemetry file"``), the path and
    the limit. OSError (no such file, a directory, no permission) and
    ValueError (a NUL in the path) are the caller's to word. A FIFO with no
    writer is reported after a second and waited for (:func:`open_fifo_waiting`).
    """
    with open_fifo_waiting(path, "rb", what) as f:
        st = os.fstat(f.fileno())
        if stat.S_ISREG(st.st_mode) and st.st_size > limit:
            data = None
        else:
            chunks, n = [], 0
            while n <= limit:
                block = f.read(min(_BLOCK, limit + 1 - n))
                if not block:
                    break
                chunks.append(block)
                n += len(block)
            data = b"".join(chunks) if n <= limit else None
    if data is None:
        raise ConfigError(None, rule=f"{what} {path}: larger than {_size_text(limit)}, the "
                                     f"most a {what} may hold; not read")
    return data


def read_toml(path, what="scenario file") -> dict:
    """The parsed TOML file at ``path``; ConfigError if missing, unreadable or bad.

    ``what`` names the file in the messages (``"scenario file"``, ``"--disperse file"``);
    a file over :data:`TOML_MAX_BYTES` is refused unread (:func:`read_bounded`).
    """
    p = Path(path)
    try:
        data = read_bounded(p, TOML_MAX_BYTES, what)
    except FileNotFoundError:
        raise ConfigError(None, str(p), f"{what} not found: {p}") from None
    except (OSError, ValueError) as e:  # a directory, no permission, NUL in the path
        reason = os_reason(e) if isinstance(e, OSError) else str(e)
        raise ConfigError(None, str(p), f"cannot read {what} {p}: {reason}") from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as e:
        line = data.count(b"\n", 0, e.start) + 1
        raise ConfigError(None, str(p), f"cannot read {what} {p}: not UTF-8 text (byte "
                          f"0x{data[e.start]:02x} on line {line})") from None
    return parse_toml(text, str(p))


#: Deepest nesting of tables and arrays read (a scenario nests 4 deep); deeper is refused
#: before anything walks it, whether it came from brackets or from a table header
#: ``[a.b.c...]``, which tomllib reads without recursion.
TOML_MAX_DEPTH = 64


def _depth_over(doc, limit) -> bool:
    """Whether ``doc`` nests tables and arrays deeper than ``limit`` (without recursion)."""
    stack = [(doc, 1)]
    while stack:
        v, d = stack.pop()
        if d > limit:
            return True
        children = v.values() if isinstance(v, dict) else v
        stack.extend((c, d + 1) for c in children if isinstance(c, dict | list))
    return False


def parse_toml(text: str, source: str) -> dict:
    """The parsed TOML ``text``; a syntax error names ``source`` and the line.

    Tables and arrays nested deeper than :data:`TOML_MAX_DEPTH` are refused.
    """
    try:
        doc = _loads(text)
        if _depth_over(doc, TOML_MAX_DEPTH):
            raise RecursionError
        return doc
    except tomllib.TOMLDecodeError as e:  # its message gives the line and column
        raise ConfigError(None, source, f"{source}: TOML syntax error: {e}") from None
    except RecursionError:
        raise ConfigError(None, source, f"{source}: TOML syntax error: nested too deeply "
                          f"(over {TOML_MAX_DEPTH} tables or arrays)") from None
    except ValueError as e:  # a long integer where _loads could not mark it
        raise ConfigError(None, source, f"{source}: TOML value not readable: {e}") from None


def parse_value(text: str):
    """One value in TOML syntax (``[1, 2]``, ``"Vega"``), read from ``text``.

    Text that is not TOML is returned stripped.
    """
    try:
        parsed = _loads(f"v = {text}")
    except (ValueError, RecursionError):  # TOMLDecodeError is a ValueError
        return text.strip()
    return parsed["v"] if list(parsed) == ["v"] else text.strip()


def _long_integers(limit: int) -> re.Pattern:
    """A decimal integer literal of more than ``limit`` digits in a value's place."""
    return re.compile(r"(?<=[=\[,{])([ \t]*)([+-]?[0-9](?:_?[0-9]){" + str(limit) + r",})"
                      r"(?=[ \t]*(?:[,\]}#\r\n]|$))")


def _loads(text: str) -> dict:
    """:func:`tomllib.loads`, reading integers too long for ``int`` as :class:`LongInteger`.

    Python converts at most ``sys.get_int_max_str_digits()`` decimal digits
    (so that a huge literal cannot stall the reader); tomllib then raises a
    bare ValueError. Such literals are read again as marked strings and
    returned as :class:`LongInteger`.
    """
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError:
        raise
    except ValueError:
        limit = sys.get_int_max_str_digits()
        marked, n = _long_integers(limit).subn(lambda m: f'{m[1]}"{_LONG_MARK_TOML}{m[2]}"',
                                                     text)
        if not n:
            raise
        return _unmark(tomllib.loads(marked))


def _unmark(v):
    if isinstance(v, dict):
        return {k: _unmark(x) for k, x in v.items()}
    if isinstance(v, list):
        return [_unmark(x) for x in v]
    if isinstance(v, str) and v.startswith(_LONG_MARK):
        return LongInteger(v[len(_LONG_MARK):])
    return v


def copy_tables(v):
    """Copy of TOML data ``v``: tables and arrays copied, scalars (immutable) shared."""
    if isinstance(v, Mapping):
        return {k: copy_tables(x) for k, x in v.items()}
    if isinstance(v, list):
        return [copy_tables(x) for x in v]
    return v


# ---------------------------------------------------------------------------
# Writing
# ---------------------------------------------------------------------------

def iso_utc(d: datetime) -> str:
    """``YYYY-MM-DDTHH:MM:SS[.ffffff]Z`` for UTC date-time ``d`` (TOML's offset form)."""
    frac = f".{d.microsecond:06d}" if d.microsecond else ""
    return f"{d.year:04d}-{d:%m-%dT%H:%M:%S}{frac}Z"  # %Y drops the zeros of year 999


_ESCAPES = {'"': '\\"', "\\": "\\\\", "\b": "\\b", "\t": "\\t", "\n": "\\n", "\f": "\\f",
            "\r": "\\r"}


def _toml_key(k: str) -> str:
    return k if BARE_KEY.fullmatch(k) else _toml_string(k)


def toml_key(k: str) -> str:
    """Key ``k`` as TOML text: bare when it can be, else quoted.

    ``hold_s`` stays bare, ``"a.b"`` is quoted.
    """
    return _toml_key(k)


def _toml_string(s: str) -> str:
    out = []
    for ch in s:
        if ch in _ESCAPES:
            out.append(_ESCAPES[ch])
        elif ord(ch) < 0x20 or ord(ch) == 0x7F:
            out.append(f"\\u{ord(ch):04X}")
        else:
            out.append(ch)
    return '"' + "".join(out) + '"'


def toml_value(v) -> str:
    """One value ``v`` as TOML text.

    A UTC date-time is written as ``...Z``, a mapping as an inline table.
    """
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)  # shortest text that reads back to the same float
    if isinstance(v, str):
        return _toml_string(v)
    if isinstance(v, datetime):
        if v.tzinfo is not None and v.utcoffset().total_seconds() == 0:
            return iso_utc(v)
        return v.isoformat()
    if isinstance(v, date | time):
        return v.isoformat()
    if isinstance(v, list | tuple):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, Mapping):
        if not v:
            return "{}"
        return "{ " + ", ".join(f"{_toml_key(k)} = {toml_value(x)}" for k, x in v.items()) + " }"
    raise TypeError(f"no TOML form for {type(v).__name__}")


def toml_dumps(doc: Mapping, comments: Mapping | None = None) -> str:
    """TOML text for ``doc``, a dict of tables and top-level scalars.

    ``tomllib.loads`` reads it back.

    ``comments`` maps ``"table.key"`` to a line written as a ``#`` comment
    above that key.
    """
    comments = comments or {}
    lines = [f"{_toml_key(k)} = {toml_value(v)}" for k, v in doc.items()
             if not isinstance(v, Mapping)]
    for name, table in doc.items():
        if isinstance(table, Mapping):
            if lines:
                lines.append("")
            lines.append(f"[{_toml_key(name)}]")
            for k, v in table.items():
                note = comments.get(f"{name}.{k}")
                if note:
                    lines.append(f"# {note}")
                lines.append(f"{_toml_key(k)} = {toml_value(v)}")
    return "\n".join(lines) + "\n"
