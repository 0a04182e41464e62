"""Configuration rules: :class:`ConfigError`, numeric conditions, generic checkers.

A checker takes ``(key, value as read from TOML)`` and returns the frozen
value (a float, a tuple of floats, a UTC datetime ...) or raises
:class:`ConfigError` naming the key, the value and the rule. Each checker
carries ``allowed``, the words the configuration reference shows for it.
A :class:`Cond` is one rule on one number: its text and its test.

Type rules are the same everywhere: an integer is accepted where a float is
expected; a boolean or a string is never a number; a number must be finite.
"""

import math
from collections.abc import Callable
from datetime import UTC, date, datetime, time
from typing import NamedTuple

from allsky.units import DEG2ARCSEC
from allsky.vocabulary import PATENT_MODES

#: The master-sequencer modes, the keys of ``sequencer.timeout_s``.
MODE_KEYS = PATENT_MODES
#: Dates the ephemeris is trusted for (PyEphem; the same as ``allsky.vehicle.sky.EPHEMERIS_YEARS``).
EPHEMERIS_START_UTC = datetime(1900, 1, 1, tzinfo=UTC)
EPHEMERIS_END_UTC = datetime(2100, 12, 31, 23, 59, 59, 999999, tzinfo=UTC)
#: Largest gyro input-axis misalignment [arcsec]: 1 degree.
MISALIGNMENT_MAX_ARCSEC = 1.0 * DEG2ARCSEC
#: Largest mission seed: seeds are 32-bit words (a campaign's seeds, base + run, too).
SEED_MAX = 2**32 - 1
#: Most runs of one campaign (``allsky montecarlo`` and ``compare --runs``): the campaign
#: keeps every finished run's row for its statistics, about 2 kB each in memory, so ten
#: million runs take about 20 GB (the jobs themselves are made as they are flown).
RUNS_MAX = 10_000_000


class _Absent:
    """Marks a ConfigError with no value to show (pickles as this very object)."""

    def __reduce__(self):
        return "_ABSENT"


_ABSENT = _Absent()


class ConfigError(Exception):
    """A scenario that cannot be used: ``str()`` is one line, ``key = value: rule``.

    Made from ``key``, ``value`` and ``rule``, the attributes below; leave
    ``value`` out when there is none to show (the attribute is then None and
    the line reads ``key: rule``).

    Attributes
    ----------
    key : str or None
        Dotted key path (``gyro.arw_deg_rt_h``), or None for a whole-file problem.
    value : object
        The offending value (a number as the float it became; None when none is shown).
    rule : str
        The rule that was broken, in words.

    Examples
    --------
    >>> import allsky
    >>> try:
    ...     allsky.scenario_from_dict({"mission": {"seed": -1}})
    ... except allsky.ConfigError as e:
    ...     print(e.key, e.value)
    ...     print(e)
    mission.seed -1
    mission.seed = -1: must be in [0, 4294967295] (2**32 - 1: 32-bit seeds)

    An unknown key (here a misspelt unit) names the nearest valid ones:

    >>> try:
    ...     allsky.load_scenario(overrides=["gyro.drift_deg_hr=[1, 2, 3]"])
    ... except allsky.ConfigError as e:
    ...     print(e)
    gyro.drift_deg_hr: unknown key; nearest valid keys: gyro.drift_deg_h, ...
    """

    def __init__(self, key, value=_ABSENT, rule=""):
        self.key, self.rule, self._given = key, rule, value
        self.value = None if value is _ABSENT else value
        if key is None:
            text = rule
        elif value is _ABSENT:
            text = f"{_show_key(key)}: {rule}"
        else:
            text = f"{_show_key(key)} = {_show_value(value)}: {rule}"
        # One line whatever the file held (a key or a path may contain newlines).
        super().__init__(text.replace("\r", "\\r").replace("\n", "\\n"))

    def __reduce__(self):  # so that it crosses process boundaries intact
        return type(self), (self.key, self._given, self.rule)

    def with_rule(self, rule: str) -> "ConfigError":
        """The same error with ``rule`` in place of the rule.

        Key and value are kept, the value shown or not as here.
        """
        return type(self)(self.key, self._given, rule)


def _show_key(key: str) -> str:
    return key if key.isprintable() else repr(key)


def _show_value(value, limit=120) -> str:
    if type(value) is int and value.bit_length() > 3 * limit:  # no 10**5000 in full
        return f"an integer of about {int(value.bit_length() * math.log10(2)) + 1} digits"
    try:
        text = value.isoformat() if isinstance(value, datetime | date | time) else repr(value)
    except ValueError:  # an integer inside has more digits than Python prints
        text = f"{type_name(value)} holding an integer too long to show"
    return text if len(text) <= limit else text[:limit - 3] + "..."


# ---------------------------------------------------------------------------
# Conditions on one number
# ---------------------------------------------------------------------------

class Cond(NamedTuple):
    """A rule on one number: the words shown when it fails, and the test."""

    text: str  #: the rule in words, as the error shows it ("must be > 0")
    ok: Callable[[float], bool]  #: the test: true when the number obeys the rule


def shown_number(x) -> str:
    """Number ``x`` as rule texts show it: integers whole, floats in %g form."""
    return str(x) if isinstance(x, int) else f"{x:g}"


def _why(why: str) -> str:
    return f" ({why})" if why else ""


POSITIVE = Cond("must be > 0", lambda x: x > 0)
NON_NEGATIVE = Cond("must be >= 0", lambda x: x >= 0)


def at_least(lo, why=""):
    """:class:`Cond` requiring ``x >= lo`` (``why``, if given, in parentheses).

    ``lo`` is in the unit of the key the rule is for.
    """
    return Cond(f"must be >= {shown_number(lo)}{_why(why)}", lambda x: x >= lo)


def in_closed(lo, hi, why=""):
    """:class:`Cond` requiring ``lo <= x <= hi`` (``why``, if given, in parentheses).

    ``lo`` and ``hi`` are in the unit of the key the rule is for.
    """
    return Cond(f"must be in [{shown_number(lo)}, {shown_number(hi)}]{_why(why)}", lambda x: lo <= x <= hi)


def in_open(lo, hi):
    """:class:`Cond` requiring ``lo < x < hi`` (``lo``, ``hi`` in the key's unit)."""
    return Cond(f"must be in ({shown_number(lo)}, {shown_number(hi)})", lambda x: lo < x < hi)


def in_open_closed(lo, hi, why=""):
    """:class:`Cond` requiring ``lo < x <= hi`` (``why``, if given, in parentheses).

    ``lo`` and ``hi`` are in the unit of the key the rule is for.
    """
    return Cond(f"must be in ({shown_number(lo)}, {shown_number(hi)}]{_why(why)}", lambda x: lo < x <= hi)


def in_closed_open(lo, hi):
    """:class:`Cond` requiring ``lo <= x < hi`` (``lo``, ``hi`` in the key's unit)."""
    return Cond(f"must be in [{shown_number(lo)}, {shown_number(hi)})", lambda x: lo <= x < hi)


def magnitude_at_most(limit):
    """:class:`Cond` requiring ``abs(x) <= limit`` (``limit`` in the key's unit)."""
    return Cond(f"magnitude must be <= {shown_number(limit)}", lambda x: abs(x) <= limit)


def check_conds(conds, key, x, shown, where=""):
    """Raise :class:`ConfigError` for the first ``Cond`` that ``x`` breaks.

    ``conds`` are the :class:`Cond` to test, in order; the error names
    ``key``, shows the value as ``shown`` (the whole array when ``x`` is one
    element of it) and prefixes the rule with ``where``.
    """
    for c in conds:
        if not c.ok(x):
            raise ConfigError(key, shown, f"{where}{c.text}")


# ---------------------------------------------------------------------------
# Types as read from TOML
# ---------------------------------------------------------------------------

_TOML_TYPE_NAMES = ((bool, "a boolean"), (int, "an integer"), (float, "a float"),
                    (str, "a string"), (list, "an array"), (dict, "a table"),
                    (datetime, "a date-time"), (date, "a date"), (time, "a time"))


def type_name(v) -> str:
    """The TOML type of ``v`` in words (``"an array"``), for error messages."""
    for t, name in _TOML_TYPE_NAMES:
        if isinstance(v, t):
            return name
    return type(v).__name__


def as_float(v):
    """``(float, None)`` or ``(None, reason)``: ``v`` as a finite number.

    An int is accepted, a bool is not.
    """
    if isinstance(v, bool) or not isinstance(v, int | float):
        return None, f"must be a number, not {type_name(v)}"
    try:
        x = float(v)
    except OverflowError:  # an integer too large for a float
        return None, "must be finite"
    if not math.isfinite(x):
        return None, "must be finite (not nan or inf)"
    return x, None


def real_array(key, v, shape):
    """Nested tuples of finite floats with the exact ``shape`` (1 or 2 dimensions).

    ``v`` is the value of ``key`` as read from TOML (nested lists); a wrong
    shape or element raises :class:`ConfigError` naming ``key``.
    """
    what = (f"an array of {shape[0]} numbers" if len(shape) == 1 else
            f"a {shape[0]}x{shape[1]} array ({shape[0]} arrays of {shape[1]} numbers)")
    if not isinstance(v, list) or len(v) != shape[0]:
        got = f"{len(v)} elements" if isinstance(v, list) else type_name(v)
        raise ConfigError(key, v, f"must be {what}, not {got}")
    if len(shape) == 2:
        if not all(isinstance(r, list) and len(r) == shape[1] for r in v):
            raise ConfigError(key, v, f"must be {what}")
        return tuple(tuple(_element(key, v, x, f"[{i}][{j}]") for j, x in enumerate(row))
                     for i, row in enumerate(v))
    return tuple(_element(key, v, x, f"{i}") for i, x in enumerate(v))


def _element(key, whole, x, index):
    f, why = as_float(x)
    if why:
        raise ConfigError(key, whole, f"element {index} {why}")
    return f


# ---------------------------------------------------------------------------
# Checkers built from conditions
# ---------------------------------------------------------------------------

def _allowed(what, conds, each=False):
    """Words for the configuration reference: ``a number; must be > 0``."""
    rules = "; ".join(("each " if each else "") + c.text.removeprefix("must be ")
                      for c in conds)
    return f"{what}, {rules}" if rules else what


def number(*conds: Cond):
    """Checker of a finite float (an integer is accepted) obeying all ``*conds``."""
    def check(key, v):
        x, why = as_float(v)
        if why:
            raise ConfigError(key, v, why)
        check_conds(conds, key, x, x)  # shown as the float it became: -1 -> -1.0
        return x
    check.allowed = _allowed("a number", conds)
    return check


def integer(*conds: Cond):
    """Checker of an integer (not a float, not a boolean) obeying all ``*conds``."""
    def check(key, v):
        if isinstance(v, bool) or not isinstance(v, int):
            raise ConfigError(key, v, f"must be an integer, not {type_name(v)}")
        check_conds(conds, key, v, v)
        return v
    check.allowed = _allowed("an integer", conds)
    return check


def vector(n: int, *conds: Cond):
    """Checker of an array of ``n`` finite floats, each obeying all ``*conds``."""
    def check(key, v):
        xs = real_array(key, v, (n,))
        for i, x in enumerate(xs):
            check_conds(conds, key, x, v, where=f"element {i} ")
        return xs
    check.allowed = _allowed(f"{n} numbers", conds, each=True)
    return check


def one_of(*choices: str):
    """Checker of a string that is one of ``*choices``."""
    def check(key, v):
        if not isinstance(v, str) or v not in choices:
            quoted = [f'"{c}"' for c in choices]
            raise ConfigError(key, v, f"must be {', '.join(quoted[:-1])} or {quoted[-1]}")
        return v
    check.allowed = "one of " + ", ".join(f'"{c}"' for c in choices)
    return check
