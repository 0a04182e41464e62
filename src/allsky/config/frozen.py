"""A scenario's frozen values: read-only sections of its validated keys.

:class:`allsky.config.scenario.Scenario` holds one :class:`Section` per table
of the scenario; :func:`freeze` and :func:`thaw` turn its values into
read-only data and back (``Scenario.as_dict``).
"""

from collections.abc import Mapping
from types import MappingProxyType


def freeze(v):
    """``v`` frozen: mappings read-only, lists and tuples as tuples, all the way down."""
    if isinstance(v, Mapping):
        return MappingProxyType({k: freeze(x) for k, x in v.items()})
    if isinstance(v, list | tuple):
        return tuple(freeze(x) for x in v)
    return v


def thaw(v):
    """``v`` as plain data again: dicts and lists (:func:`freeze` undone)."""
    if isinstance(v, Mapping):
        return {k: thaw(x) for k, x in v.items()}
    if isinstance(v, tuple):
        return [thaw(x) for x in v]
    return v


class Section:
    """One frozen scenario section: its keys as read-only attributes.

    ``name`` is the section's name (``gyro``), as errors show it; ``values``
    its validated values by key, frozen here (lists to tuples, mappings
    read-only).
    """

    __slots__ = ("_name", "_values")
    __hash__ = None

    def __init__(self, name: str, values: Mapping):
        object.__setattr__(self, "_name", name)
        object.__setattr__(self, "_values", {k: freeze(v) for k, v in values.items()})

    def __getattr__(self, key):
        if key.startswith("_"):
            raise AttributeError(key)
        try:
            return self._values[key]
        except KeyError:
            raise AttributeError(f"scenario section [{self._name}] has no key {key!r}") from None

    def __setattr__(self, key, value):
        raise AttributeError("a Scenario is frozen")

    def __delattr__(self, key):
        raise AttributeError("a Scenario is frozen")

    def __dir__(self):
        return sorted(self._values)

    def __eq__(self, other):
        if not isinstance(other, Section):
            return NotImplemented
        return self._name == other._name and self._values == other._values

    def __reduce__(self):
        return Section, (self._name, thaw(self._values))

    def __repr__(self):
        return f"Section({self._name!r}, {thaw(self._values)!r})"
