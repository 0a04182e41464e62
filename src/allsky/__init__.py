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

import os as _os
import signal as _signal
import sys as _sys

__version__ = "0.1.0"


def _started_as_the_command() -> bool:
    """Whether this process is the ``allsky`` command (its script, or ``python -m allsky``)."""
    argv0 = _sys.argv[0] if _sys.argv else ""
    orig = getattr(_sys, "orig_argv", [])
    return _os.path.basename(argv0) == "allsky" or (
        argv0 == "-m" and any(orig[i:i + 2] == ["-m", "allsky"] for i in range(len(orig))))


def _interrupted_while_starting(signum, frame):
    """Ctrl-C, SIGTERM or SIGHUP before the command line is parsed: one line, exit 130."""
    try:
        _os.write(2, b"allsky: interrupted while starting; nothing written\n")
    except OSError:
        pass
    _os._exit(130)


#: True in the ``allsky`` command, whose signals are handled from here on (the first line
#: of allsky that runs): a Ctrl-C while its modules load ends it with one line, never a
#: traceback. :func:`allsky.apps.cli.main` takes over once it runs. A library user's
#: signals are left alone.
RUNNING_AS_COMMAND = _started_as_the_command()
if RUNNING_AS_COMMAND:
    _ENDING = tuple(getattr(_signal, _n) for _n in ("SIGINT", "SIGTERM", "SIGHUP")
                    if hasattr(_signal, _n))
    for _sig in _ENDING:
        if _signal.getsignal(_sig) in (_signal.default_int_handler, _signal.SIG_DFL):
            _signal.signal(_sig, _interrupted_while_starting)
    # A launcher that blocked them while Python started gets them now, handled.
    if hasattr(_signal, "pthread_sigmask"):
        _signal.pthread_sigmask(_signal.SIG_UNBLOCK, set(_ENDING))

#: Public name -> module that defines it (imported on first access).
_EXPORTS = {
    "fly": "allsky.apps.api",
    "Flight": "allsky.apps.api",
    "Replay": "allsky.apps.api",
    "compare": "allsky.apps.api",
    "montecarlo": "allsky.apps.api",
    "InterruptedWarning": "allsky.apps.api",
    "StrictError": "allsky.apps.api",
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
    "StrictError",
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
