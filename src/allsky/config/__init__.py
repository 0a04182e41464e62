"""Configuration: scenario rules, loading and merging, dispersions.

A scenario is a TOML file merged over the packaged default, validated once
at load (unknown key -> error) and then passed down as a frozen object.

Modules, each one job, lowest first: ``rules`` (:class:`ConfigError`, the
checkers of one value), ``toml_io`` (reading TOML, the writer), ``schema``
(the keys, :data:`RULES`, :data:`CROSS_RULES`), ``dispersion_table`` (the
``[dispersions]`` table), ``faults`` (the ``[[faults]]`` tables), ``frozen``
(a scenario's read-only sections), ``scenario`` (merging, overrides, the
frozen :class:`Scenario`) and ``dispersions``
(drawing a scenario per mission seed).
"""

from allsky.config.cross_rules import CROSS_RULES
from allsky.config.rules import ConfigError
from allsky.config.scenario import Scenario, load_scenario, scenario_from_dict
from allsky.config.schema import DEFAULT_SCENARIO_PATH, RULES, allowed

__all__ = ["CROSS_RULES", "DEFAULT_SCENARIO_PATH", "RULES", "ConfigError", "Scenario",
           "allowed", "load_scenario", "scenario_from_dict"]
