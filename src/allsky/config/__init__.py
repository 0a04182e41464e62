"""Configuration: scenario rules, loading and merging, dispersions.

A scenario is a TOML file merged over the packaged default, validated once
at load (unknown key -> error) and then passed down as a frozen object.
"""

from allsky.config.scenario import (
    DEFAULT_SCENARIO_PATH,
    ConfigError,
    Scenario,
    load_scenario,
    scenario_from_dict,
)

__all__ = ["DEFAULT_SCENARIO_PATH", "ConfigError", "Scenario", "load_scenario",
           "scenario_from_dict"]
