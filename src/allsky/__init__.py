"""allsky: an emulator of the 1970s all-sky pointing attitude control system.

The system is the one of US patent 4,012,018 (a sun sensor, a Canopus star
tracker, three strapped-down rate gyros, cold-gas jets, hard-wired electronics
and a small special-purpose computer). A dither scale-factor method is flown
beside it for comparison.

The packages follow the block diagram, from the bottom up: ``units`` and
``jit`` (foundations), ``vehicle`` (rigid body, sky), ``config`` (scenarios),
``hardware`` (the numbered blocks and the switch wiring), ``computer``
(computer 111), ``sequencer`` (master sequencer 20: mode table, rules,
watch, plans), ``sim`` (frame loop, mission), ``studies`` (comparison,
Monte Carlo, loop analysis) and ``apps`` (command line, displays, files).

The names most scripts and notebooks need are importable from here: the
Python API (:func:`fly`, :class:`Flight`, :func:`compare`,
:func:`montecarlo`; :mod:`allsky.apps.api`) and the mission and scenario
underneath it. They are loaded on first use, so ``import allsky`` stays
cheap (no NumPy, no pandas); ``__init__.pyi`` declares them for type
checkers.

>>> import allsky
>>> f = allsky.fly()                     # the default mission
>>> f.telemetry["true_error"].iloc[-1]   # [arcsec] at the end
"""

__version__ = "0.1.0"

#: Public name -> module that defines it (imported on first access).
_EXPORTS = {
    "fly": "allsky.apps.api",
    "Flight": "allsky.apps.api",
    "Replay": "allsky.apps.api",
    "compare": "allsky.apps.api",
    "montecarlo": "allsky.apps.api",
    "InterruptedWarning": "allsky.apps.api",
    "load_scenario": "allsky.config",
    "scenario_from_dict": "allsky.config",
    "Scenario": "allsky.config",
    "ConfigError": "allsky.config",
    "Mission": "allsky.sim.mission",
    "Hooks": "allsky.sim.mission",
    "ModeRecord": "allsky.sim.mission",
    "run_mission": "allsky.sim.mission",
    "LEGACY_PLAN": "allsky.sim.mission",
    "DITHER_PLAN": "allsky.sim.mission",
}

__all__ = [
    "DITHER_PLAN",
    "LEGACY_PLAN",
    "ConfigError",
    "Flight",
    "Hooks",
    "InterruptedWarning",
    "Mission",
    "ModeRecord",
    "Replay",
    "Scenario",
    "__version__",
    "compare",
    "fly",
    "load_scenario",
    "montecarlo",
    "run_mission",
    "scenario_from_dict",
]


def __getattr__(name: str):
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'allsky' has no attribute {name!r}")
    import importlib

    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list:
    """The module's names with the public ones loaded on first use (completion, autodoc)."""
    return sorted(set(globals()) | set(__all__))
