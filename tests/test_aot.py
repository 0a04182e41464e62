"""The functions built ahead of time (allsky.aot): the same bits as numba's, without numba.

The package is copied (with numba's cache) to a temporary directory and the
functions are built there, as ``pip install`` builds them (setup.py); where
allsky is installed from a wheel that carries them, the installed ones are
used. Each mission runs in a fresh process, since this one has numba loaded.
"""

import collections
import json
import os
import shutil
import subprocess
import sys
import sysconfig
import textwrap

import numba
import numpy as np
import pytest

from allsky import aot

needs_jit = pytest.mark.skipif(numba.config.DISABLE_JIT, reason="about compiled code")

Pair = collections.namedtuple("Pair", "a b")
Other = collections.namedtuple("Other", "a c")


def test_structure_tells_apart_what_numba_types_differently():
    x = np.zeros(3)
    same = [aot.structure(v) for v in (np.ones(3), 1.5, 2, True, None, Pair(x, 1.0))]
    assert same == [aot.structure(v) for v in (x, 0.5, 7, False, None, Pair(np.ones(3), 2.0))]
    ro = np.zeros(3)
    ro.flags.writeable = False
    m = np.zeros((3, 4))
    different = [np.zeros(3, dtype=np.int64), np.zeros(3, dtype=np.float32), np.zeros((1, 3)),
                 ro, m[:, ::2], np.asfortranarray(m), 1, True, None, (x, 1.0), Other(x, 1.0),
                 Pair(x, 1), Pair(x.astype(np.int64), 1.0), np.float64(1.0)]
    kinds = [json.dumps(aot.structure(v)) for v in different]
    assert len(set(kinds)) == len(kinds)
    assert json.dumps(aot.structure(x)) not in kinds
    assert aot.structure(m) != aot.structure(np.asfortranarray(m))


def _env(**extra):
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTHONPATH", "NUMBA_CACHE_DIR", "ALLSKY_AOT", "NUMBA_DISABLE_JIT")}
    env.update(extra)
    return env


def _can_build() -> str:
    if not (shutil.which("cc") or shutil.which("gcc")):
        return "no C compiler"
    if not os.path.isfile(os.path.join(sysconfig.get_paths()["include"], "Python.h")):
        return "no Python headers"
    return ""


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """A directory holding the allsky package with its functions built ahead of time."""
    import allsky

    here = os.path.dirname(allsky.__file__)
    if os.path.isfile(aot.MANIFEST) and aot.available():
        return os.path.dirname(here)  # installed with them (pip install .)
    why = _can_build()
    if why:
        pytest.skip(f"cannot build ahead of time here ({why}); missions use numba")
    root = tmp_path_factory.mktemp("aot")
    shutil.copytree(here, root / "allsky", ignore=shutil.ignore_patterns("*.pyc", "_aot*"))
    done = subprocess.run([sys.executable, "-m", "allsky.apps.warm", "plain", "--no-lock",
                           "--ahead-of-time"], cwd=root, env=_env(PYTHONPATH=str(root)),
                          capture_output=True, text=True, timeout=900, check=False)
    assert done.returncode == 0, done.stderr
    assert os.path.isfile(root / "allsky" / "_aot.json"), done.stderr
    return str(root)


_FLY = textwrap.dedent("""
    import hashlib, json, sys
    sys.path.insert(0, sys.argv[1])
    import allsky
    from allsky.config import load_scenario
    from allsky.sim.mission import Mission
    from allsky.studies import montecarlo
    cfg = load_scenario(overrides=sys.argv[2:])
    m = Mission(cfg, telemetry=True)
    m.run()
    summary = json.dumps(m.summary(), sort_keys=True, default=str)
    rows = montecarlo.fly_one(cfg, 3, 17)
    print(json.dumps({"where": allsky.__file__, "numba": "numba" in sys.modules,
                      "summary": hashlib.sha256(summary.encode()).hexdigest(),
                      "telemetry": hashlib.sha256(m.telemetry().tobytes()).hexdigest(),
                      "row": json.dumps(rows, sort_keys=True, default=str)}))
""")


def _fly(root, *overrides, aot_on=True):
    out = subprocess.run([sys.executable, "-c", _FLY, root, *overrides], capture_output=True,
                         text=True, timeout=900, check=True,
                         env=_env(ALLSKY_AOT="1" if aot_on else "0"))
    return json.loads(out.stdout.splitlines()[-1])


@needs_jit
@pytest.mark.parametrize("overrides", [(), ("mission.seed=5", "target.star=Vega")])
def test_a_mission_flown_ahead_of_time_is_numbas_bit_for_bit_without_numba(built, overrides):
    ahead = _fly(built, *overrides)
    just_in_time = _fly(built, *overrides, aot_on=False)
    assert ahead["where"].startswith(built)
    assert ahead["numba"] is False and just_in_time["numba"] is True
    for key in ("summary", "telemetry", "row"):
        assert ahead[key] == just_in_time[key], key


@needs_jit
def test_a_mission_the_build_did_not_cover_goes_to_numba(built):
    """The general loop (wheels) was not built ahead of time: numba flies it, the same way."""
    wheels = _fly(built, 'actuators.kind="wheels"')
    assert wheels["numba"] is True


@needs_jit
def test_edited_sources_retire_what_was_built(built, tmp_path):
    shutil.copytree(os.path.join(built, "allsky"), tmp_path / "allsky",
                    ignore=shutil.ignore_patterns("*.pyc"))
    code = ("import sys; sys.path.insert(0, sys.argv[1]); from allsky import aot; "
            "print(aot.available())")
    check = [sys.executable, "-c", code, str(tmp_path)]
    assert subprocess.run(check, capture_output=True, text=True, env=_env(),
                          check=True).stdout.split() == ["True"]
    with open(tmp_path / "allsky" / "hardware" / "gyro.py", "a") as f:
        f.write("\n# a block edited after the build\n")
    assert subprocess.run(check, capture_output=True, text=True, env=_env(),
                          check=True).stdout.split() == ["False"]


def test_threads_other_than_the_main_one_keep_numba(built):
    """Functions built ahead of time hold the GIL: a Dask worker's threads use numba's."""
    code = textwrap.dedent("""
        import sys, threading
        sys.path.insert(0, sys.argv[1])
        from allsky import aot
        from allsky.config import load_scenario
        from allsky.sim.mission import Mission
        s = Mission(load_scenario(), telemetry=False).state
        args = (0, 0.0, s.word23, s.word24, s.cpu)
        found = {"main": aot.entry("allsky.computer.cpu.target_step", args)}
        t = threading.Thread(target=lambda: found.update(
            thread=aot.entry("allsky.computer.cpu.target_step", args)))
        t.start()
        t.join()
        print(found["main"] is not None, found["thread"] is None)
    """)
    out = subprocess.run([sys.executable, "-c", code, built], capture_output=True, text=True,
                         env=_env(), check=True).stdout.split()
    assert out == ["True", "True"]


def test_the_manifest_names_the_functions_a_mission_calls_from_python(built):
    with open(os.path.join(built, "allsky", "_aot.json"), encoding="utf-8") as f:
        manifest = json.load(f)
    assert set(manifest["exports"]) == set(aot.EXPORTS)
    assert manifest["cpu"] == aot.cpu_fingerprint()
    assert manifest["cache_tag"] == sys.implementation.cache_tag


def test_pip_install_built_them_where_it_could():
    """An install from a wheel that pip built here carries them, if this machine can build."""
    from tests.apps.test_warm_up import _installed_from_a_wheel

    files = _installed_from_a_wheel()
    if files is None:
        pytest.skip("allsky is not installed from a wheel here (editable or source tree)")
    why = _can_build()
    if why or os.environ.get("ALLSKY_BUILD_COMPILE") == "0":
        pytest.skip(f"this machine cannot build ahead of time ({why or 'told not to'})")
    assert "allsky/_aot.json" in files
    assert any(name.startswith("allsky/_aot.") and name.endswith(
        sysconfig.get_config_var("EXT_SUFFIX")) for name in files)
    assert aot.available()


@needs_jit
def test_a_manifest_without_its_module_goes_to_numba(built, tmp_path):
    """The extension module missing (a partial copy, a removed file): numba flies, the same."""
    shutil.copytree(os.path.join(built, "allsky"), tmp_path / "allsky",
                    ignore=shutil.ignore_patterns("*.pyc", "_aot.*.so", "_aot.*.pyd"))
    assert os.path.isfile(tmp_path / "allsky" / "_aot.json")
    without = _fly(str(tmp_path))
    ahead = _fly(built)
    assert without["where"].startswith(str(tmp_path)) and without["numba"] is True
    for key in ("summary", "telemetry", "row"):
        assert without[key] == ahead[key], key
