"""Each command imports only what it needs: ``allsky --help`` starts without the heavy packages.

Run in a fresh interpreter, since this test process has imported everything already.
"""

import json
import subprocess
import sys

import pytest

HEAVY = ("numba", "matplotlib", "scipy", "control", "pyarrow", "dask")


def _imported_by(argv):
    """The packages of HEAVY (and numpy) loaded after ``allsky ARGV`` in a new process."""
    code = ("import contextlib, io, json, sys\n"
            "from allsky.apps import cli\n"
            "with contextlib.redirect_stdout(io.StringIO()):\n"
            f"    code = cli.main({argv!r})\n"
            f"print(json.dumps([code, sorted(m for m in {HEAVY + ('numpy',)!r} "
            "if m in sys.modules)]))\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True)
    return json.loads(done.stdout.splitlines()[-1])


def test_help_imports_neither_numba_nor_matplotlib_nor_numpy():
    code, loaded = _imported_by(["--help"])
    assert code == 0
    assert loaded == []


@pytest.mark.parametrize("argv", [["config", "show"],
                                  ["config", "check", "--set", "mission.seed=2"],
                                  ["run", "--help"], ["montecarlo", "--help"]])
def test_config_commands_and_command_help_leave_out_the_heavy_packages(argv):
    code, loaded = _imported_by(argv)
    assert code == 0
    assert not set(loaded) & set(HEAVY), loaded


@pytest.mark.parametrize("argv", [["config", "show"],
                                  ["config", "check", "--set", "actuators.kind=\"wheels\"",
                                   "--set", "gyro.scale_factor_error_ppm=[800,-300,1500]"]])
def test_validating_a_scenario_needs_no_numpy(argv):
    """config show/check validate the whole default scenario (inertia, wheel axes, dispersions)
    in pure Python: NumPy's import is most of what they would otherwise cost."""
    code, loaded = _imported_by(argv)
    assert code == 0
    assert loaded == [], loaded
