# The public names of allsky for type checkers. At run time allsky/__init__.py loads
# each on first use (_EXPORTS); tests/test_init.py checks that both say the same.
from allsky.apps.api import Flight as Flight
from allsky.apps.api import InterruptedWarning as InterruptedWarning
from allsky.apps.api import Replay as Replay
from allsky.apps.api import StrictError as StrictError
from allsky.apps.api import compare as compare
from allsky.apps.api import fly as fly
from allsky.apps.api import montecarlo as montecarlo
from allsky.config import ConfigError as ConfigError
from allsky.config import Scenario as Scenario
from allsky.config import load_scenario as load_scenario
from allsky.config import scenario_from_dict as scenario_from_dict
from allsky.sim.mission import DITHER_PLAN as DITHER_PLAN
from allsky.sim.mission import LEGACY_PLAN as LEGACY_PLAN
from allsky.sim.mission import Hooks as Hooks
from allsky.sim.mission import Mission as Mission
from allsky.sim.mission import ModeRecord as ModeRecord
from allsky.sim.mission import run_mission as run_mission

__version__: str
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
