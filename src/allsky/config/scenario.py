"""Scenarios: TOML files, ``KEY=VALUE`` overrides, validation, a frozen result.

The packaged default (``scenarios/default.toml``,
:data:`~allsky.config.schema.DEFAULT_SCENARIO_PATH`) is the schema: every key
it has, with the unit in the key's name, and nothing else. A user scenario file is merged over the
default, table by table and key by key, so a file states only what it
changes. A section or key the default does not have is an error naming the
nearest valid keys.

Overrides (``allsky ... --set KEY=VALUE``) are applied after the file, in
order, by the same merge. KEY is a dotted path (``gyro.drift_deg_h``,
``sequencer.timeout_s.6-1``); VALUE is in TOML value syntax
(``[800,-300,1500]``, ``2027-03-01T00:00:00Z``, ``"Vega"``, ``{ "1" = 600 }``);
a VALUE that is not TOML is taken as a plain string (``target.star=Vega``).

The target is given in exactly one of three forms: ``target.star`` (a name in
PyEphem's catalog, any case), ``target.ra_deg`` + ``target.dec_deg`` (J2000,
degrees) or ``target.sequence`` (a list of either, flown one after the other).
A table that sets two forms is an error; setting a form (in a file or by an
override) removes the others inherited from the default, the file or an
earlier override. In the result the unused forms are ``None``.

``mission.date_utc`` may be a TOML date-time (with an offset, or local, which
is read as UTC), a TOML date (midnight UTC) or an ISO-8601 string; it becomes
a timezone-aware UTC :class:`~datetime.datetime`. ``ejection.attitude`` is
``"random"`` or a quaternion ``[w, x, y, z]`` (scalar first) rotating
inertial-frame components into body-frame components; it is normalised on
load. ``vehicle.inertia_kg_m2`` is stored exactly symmetric (the upper
triangle, after checking symmetry to a relative 1e-9).

``[dispersions]`` (empty in the default) names keys drawn at random per
mission seed for Monte Carlo campaigns (syntax and seeding:
:mod:`allsky.config.dispersions`, ``docs/montecarlo.md``); its entries are merged by
key (:mod:`allsky.config.dispersion_table`), and ``load_scenario(..., disperse=FILE)``
merges a file's ``[dispersions]`` table over the scenario's.

Every value is checked once, here: its type (an integer is accepted where a
float is expected; a boolean or a string is never a number), finiteness, its
own rule (:data:`~allsky.config.schema.RULES`, one entry per key) and the rules
tying keys together (:data:`~allsky.config.cross_rules.CROSS_RULES`). Anything wrong
raises :class:`~allsky.config.rules.ConfigError` naming the key, the value and
the rule; no other exception escapes for any file content.
"""

from collections.abc import Mapping
from datetime import datetime

from allsky.config import dispersion_table
from allsky.config import faults as fault_table
from allsky.config.cross_rules import CROSS_RULES
from allsky.config.frozen import Section, freeze, thaw
from allsky.config.meanings import describe
from allsky.config.rules import ConfigError, type_name
from allsky.config.schema import (
    RULES,
    TARGET_RADEC_FORM,
    TARGET_SEQUENCE_FORM,
    TARGET_STAR_FORM,
    default_tables,
    key_tree,
    unknown_key,
)
from allsky.config.toml_io import BARE_KEY, copy_tables, iso_utc, parse_value, read_toml, toml_dumps

# ---------------------------------------------------------------------------
# Merging
# ---------------------------------------------------------------------------

def _merge(base: dict, incoming: dict, schema: dict, path=()) -> None:
    """Merge ``incoming`` over ``base`` in place: tables key by key, other values replaced."""
    if path == ("target",):
        _replace_target_form(base, incoming)
    for k, v in incoming.items():
        here = (*path, k)
        if not path and k == "dispersions":  # entries by key
            base[k] = dispersion_table.merge(base.get(k) or {}, v)
            continue
        if not path and k == "faults":  # an array of tables: replaced whole
            base[k] = v
            continue
        if k not in schema:
            raise unknown_key(here, schema)
        if isinstance(schema[k], dict):
            if not isinstance(v, dict):
                raise ConfigError(".".join(here), v, f"must be a table, not {type_name(v)}")
            if not isinstance(base.get(k), dict):
                base[k] = {}
            _merge(base[k], v, schema[k], here)
        else:
            base[k] = v


def _replace_target_form(base: dict, incoming: dict) -> None:
    forms = (TARGET_STAR_FORM, TARGET_RADEC_FORM, TARGET_SEQUENCE_FORM)
    given = [form for form in forms if any(k in incoming for k in form)]
    if len(given) > 1:
        keys = ", ".join(f"target.{k}" for form in given for k in form if k in incoming)
        raise ConfigError("target", incoming, "set either target.star or target.ra_deg + "
                          f"target.dec_deg or target.sequence, not both (sets {keys})")
    for form in forms if given else ():
        if form is not given[0]:
            for k in form:
                base.pop(k, None)


def parse_override(item: str) -> dict:
    """Parse an override ``"a.b=VALUE"`` into ``{"a": {"b": value}}``.

    ``item`` is the override's text, as given on the command line. VALUE is
    read in TOML syntax, else kept as a plain string.
    """
    if not isinstance(item, str) or "=" not in item:
        raise ConfigError(None, item, f"override {item!r} must be KEY=VALUE, "
                          "e.g. gyro.arw_deg_rt_h=0.002")
    key, text = item.split("=", 1)
    parts = [p.strip() for p in key.split(".")]
    if not all(BARE_KEY.fullmatch(p) for p in parts):
        raise ConfigError(None, item, f"override {item!r}: KEY must be a dotted path "
                          "such as gyro.drift_deg_h")
    value = parse_value(text)
    for p in reversed(parts):
        value = {p: value}
    return value


class Scenario:
    """A validated, frozen scenario: ``cfg.section.key``, and ``cfg.faults``.

    Build it with :func:`load_scenario`, which passes ``sections``: each
    section's validated values by key (each becomes a :class:`Section`), and
    the ``faults`` list, frozen as it is.

    Vectors are tuples of floats, matrices tuples of tuples, ``mission.date_utc``
    a UTC datetime, ``sequencer.timeout_s`` a read-only mapping mode -> seconds.

    Examples
    --------
    >>> import allsky
    >>> cfg = allsky.load_scenario()
    >>> cfg
    <Scenario 2026-11-22T12:00:00Z seed 1: Sirius>
    >>> cfg.target.star, cfg.gyro.drift_deg_h        # [deg/h] roll, pitch, yaw
    ('Sirius', (1.2, -0.8, 1.5))
    >>> allsky.scenario_from_dict(cfg.as_dict()) == cfg
    True
    >>> cfg.mission.seed = 2
    Traceback (most recent call last):
    ...
    AttributeError: a Scenario is frozen
    """

    __slots__ = ("_sections",)
    __hash__ = None

    def __init__(self, sections: Mapping[str, Mapping]):
        object.__setattr__(self, "_sections",
                           {name: Section(name, values) if isinstance(values, Mapping)
                            else freeze(values) for name, values in sections.items()})

    def __getattr__(self, name):
        if name.startswith("_"):
            raise AttributeError(name)
        try:
            return self._sections[name]
        except KeyError:
            raise AttributeError(f"scenario has no section [{name}]") from None

    def __setattr__(self, key, value):
        raise AttributeError("a Scenario is frozen")

    def __delattr__(self, key):
        raise AttributeError("a Scenario is frozen")

    def __dir__(self):
        return [*self._sections, "as_dict", "to_toml"]

    def __eq__(self, other):
        if not isinstance(other, Scenario):
            return NotImplemented
        return self._sections == other._sections

    def __reduce__(self):
        return Scenario, ({n: thaw(getattr(s, "_values", s))
                           for n, s in self._sections.items()},)

    def __repr__(self):
        t = self.target
        if t.sequence is not None:
            what = f"{len(t.sequence)} targets"
        else:
            what = t.star or f"RA {t.ra_deg:g} deg, Dec {t.dec_deg:g} deg"
        return f"<Scenario {iso_utc(self.mission.date_utc)} seed {self.mission.seed}: {what}>"

    def _export(self, date_as_text: bool) -> dict:
        out = {}
        for name, sec in self._sections.items():
            if not isinstance(sec, Section):  # the faults: written only when there are some
                if sec:
                    out[name] = thaw(sec)
                continue
            table = out[name] = {}
            for k, v in sec._values.items():
                if v is None:  # the target form not in use
                    continue
                if isinstance(v, datetime) and date_as_text:
                    v = iso_utc(v)
                table[k] = thaw(v)
        return out

    def as_dict(self) -> dict:
        """Plain nested dict of lists, floats and strings.

        The date is written as ``YYYY-MM-DDTHH:MM:SSZ``.

        :func:`scenario_from_dict` turns it back into an equal Scenario.
        """
        return self._export(date_as_text=True)

    def to_toml(self, annotate: bool = False) -> str:
        """The fully resolved scenario as TOML text that loads back to an equal Scenario.

        With ``annotate``, each key has a comment line above it: its meaning,
        unit and accepted values (:func:`allsky.config.meanings.describe`).
        """
        header = "# allsky scenario, fully resolved (every key, validated)\n\n"
        doc = self._export(date_as_text=False)
        notes = None
        if annotate:
            notes = {f"{t}.{k}": describe(f"{t}.{k}") for t, table in doc.items()
                     if isinstance(table, Mapping) for k in table if f"{t}.{k}" in RULES}
        return header + toml_dumps(doc, notes)


# ---------------------------------------------------------------------------
# Entry points
# ---------------------------------------------------------------------------

def _validate(data: dict) -> dict:
    """Check every key of the merged dict; return ``{section: {key: value}}``."""
    flat = {}
    for key, rule in RULES.items():
        sec, name = key.split(".")
        if name in data.get(sec, {}):
            flat[key] = rule(key, data[sec][name])
        elif sec == "target":
            flat[key] = None
        else:
            raise ConfigError(key, rule="missing")
    for rule in CROSS_RULES:
        rule(flat)
    sections = {}
    for key, v in flat.items():
        sec, name = key.split(".")
        sections.setdefault(sec, {})[name] = v
    faults = fault_table.validate(data.get("faults", []), flat)
    table = data.get("dispersions") or {}
    sections["dispersions"] = {
        **dispersion_table.validate({k: e for k, e in table.items()
                                     if not fault_table.is_fault_key(k)}, flat),
        **{k: fault_table.validate_dispersion(k, e, faults) for k, e in table.items()
           if fault_table.is_fault_key(k)}}
    sections["faults"] = faults
    # A key just added to the default but not yet to RULES is kept as read (frozen), so
    # the simulator can use it; test_config checks that RULES covers the whole schema.
    for sec, table in data.items():
        for name, v in (table.items() if isinstance(table, Mapping) else ()):
            sections.setdefault(sec, {}).setdefault(name, v)
    return sections


def scenario_from_dict(data: Mapping, overrides=()) -> Scenario:
    """Validate a nested dict (as from a TOML file or :meth:`Scenario.as_dict`).

    Parameters
    ----------
    data : dict
        Sections of keys; merged over the packaged default.
    overrides : iterable of str
        ``KEY=VALUE`` strings applied after ``data``, in order.

    Returns
    -------
    Scenario
        The validated, frozen scenario.

    Raises
    ------
    ConfigError
        For an unknown key or any value that breaks its rule.

    Examples
    --------
    >>> import allsky
    >>> cfg = allsky.scenario_from_dict({"target": {"star": "Vega"}, "mission": {"seed": 7}})
    >>> cfg
    <Scenario 2026-11-22T12:00:00Z seed 7: Vega>
    >>> allsky.scenario_from_dict(cfg.as_dict(), ["mission.seed=8"]).mission.seed
    8
    """
    if isinstance(overrides, str):
        overrides = (overrides,)
    if not isinstance(data, Mapping):
        raise ConfigError(None, data, "a scenario is a table of sections")
    merged = default_tables()
    schema = key_tree()
    _merge(merged, copy_tables(data), schema)
    for item in overrides:
        _merge(merged, parse_override(item), schema)
    return Scenario(_validate(merged))


def load_scenario(path=None, overrides=(), disperse=None) -> Scenario:
    """Load a scenario file, merge it over the default, apply overrides, validate.

    Parameters
    ----------
    path : str or path-like, optional
        Scenario TOML file, or the name of a packaged one
        (:func:`allsky.config.faults.packaged_scenarios`); None for the default alone.
    overrides : iterable of str
        ``KEY=VALUE`` strings (dotted KEY, VALUE in TOML syntax), applied in order.
    disperse : str or path-like, optional
        TOML file holding a ``[dispersions]`` table (and nothing else), merged
        over the scenario's dispersions before the overrides.

    Returns
    -------
    Scenario
        The validated, frozen scenario.

    Raises
    ------
    ConfigError
        For an unreadable or missing file, a TOML syntax error (with its line),
        an unknown key or any value that breaks its rule.

    Examples
    --------
    >>> import allsky
    >>> allsky.load_scenario(overrides=['target.star="Vega"', "mission.seed=7"])
    <Scenario 2026-11-22T12:00:00Z seed 7: Vega>
    >>> cfg = allsky.load_scenario("voyager1-wrong-star")   # a packaged scenario
    >>> cfg.faults[0]["kind"], cfg.faults[0]["star"]
    ('wrong_star', 'Rigil Kentaurus')
    """
    path = fault_table.packaged_or_path(path)
    data = {} if path is None else read_toml(path)
    if disperse is not None:
        extra = read_toml(disperse, what="--disperse file")
        others = [k for k in extra if k != "dispersions"]
        if others:
            raise ConfigError(None, str(disperse), f"{disperse}: a dispersion file holds only a "
                              f"[dispersions] table, not {', '.join(map(repr, others))}")
        table = dispersion_table.merge({}, data.get("dispersions", {}))
        data = {**data, "dispersions": dispersion_table.merge(table, extra.get("dispersions", {}))}
    return scenario_from_dict(data, overrides)
