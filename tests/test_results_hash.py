"""Results stay bit-identical: hashes of summaries and telemetry of several missions.

A change that is not meant to move results (a refactor, a speed-up, a new
option that defaults off) must leave every hash below unchanged. A change
that is meant to move results updates the hashes in the same commit and says
why in its message. Run this file with ``-s`` and ``ALLSKY_PRINT_HASHES=1``
to print the current hashes.
"""

import hashlib
import json
import os

import numpy as np
import pytest

from allsky import clock
from allsky.config.scenario import load_scenario
from allsky.sim.mission import DITHER_PLAN, LEGACY_PLAN, Mission
from allsky.sim.recorder import FORMATS
from allsky.studies.compare import compare

CASES = {
    "legacy-seed1": (LEGACY_PLAN, 1, ()),
    "legacy-seed7": (LEGACY_PLAN, 7, ()),
    "legacy-seed23-vega": (LEGACY_PLAN, 23, ("target.star='Vega'",
                                             "gyro.drift_deg_h=[1.5,-2.0,0.7]")),
    "dither-seed1": (DITHER_PLAN, 1, ()),
    "dither-seed5": (DITHER_PLAN, 5, ()),
}

#: sha256 of (summary JSON, telemetry bytes) per case, and of ``compare --runs 5``.
EXPECTED = {
    "dither-seed1": "72becdfec09dff91babe8fc079bef790",
    "dither-seed5": "7cd95e6070d4918c92be0551d844dfe1",
    "legacy-seed1": "fd9c81590cb20ba1f038f9b61313b04f",
    "legacy-seed23-vega": "0b4c1b66decbce2768a225f04b35c0a5",
    "legacy-seed7": "b9f04be5348a424d79936a8ddc923873",
    "compare-runs5": "22b091e30a59020e35185be47d10610e",
}


def _digest(*parts: bytes) -> str:
    h = hashlib.sha256()
    for p in parts:
        h.update(p)
        h.update(b"\0")
    return h.hexdigest()[:32]


def _summary_bytes(summary) -> bytes:
    return json.dumps(summary, sort_keys=True).encode()


def mission_hash(plan, seed, overrides) -> str:
    cfg = load_scenario(overrides=[f"mission.seed={seed}", *overrides])
    m = Mission(cfg, plan=plan)
    summary = m.run()
    tlm = np.ascontiguousarray(m.telemetry(), dtype=np.float64)
    return _digest(_summary_bytes(summary), tlm.tobytes())


#: What the summary gained with the journal (telemetry format 2): the truth beside the
#: machine's judgement. Without them, with the telemetry's format-1 columns only and its
#: decimated rows only (not the row of the last frame, which ends the record exactly), each
#: mission hashes as it did before: the physics did not move.
ADDED_WITH_THE_JOURNAL = ("drift_dac_clipped", "end", "warnings", "events")
#: The hashes of :data:`CASES` before the journal (format-1 view, :func:`format1_hash`).
EXPECTED_FORMAT1 = {
    "dither-seed1": "134c0bd8de5c35975e70d823ea17b187",
    "dither-seed5": "c26a558bd685def6dbd9eb777316a981",
    "legacy-seed1": "752e1aac947e010b2b7ce093851816f4",
    "legacy-seed23-vega": "f0f1dc96b60e333031eb343ede02ce8c",
    "legacy-seed7": "f0ef1cb2b519dfbb05817e7b3720e659",
}


#: The hashes of :data:`CASES` with the telemetry's format-2 columns only, before the gyros'
#: outputs were recorded (format 3 appends them): the physics did not move.
EXPECTED_FORMAT2 = {
    "dither-seed1": "e1f509ebee972ad4a92293c6f352992e",
    "dither-seed5": "66473152051997f5ead4b6e4966dfc21",
    "legacy-seed1": "df754a06ba28bd5f1d47522a33680ab4",
    "legacy-seed23-vega": "d9c3ca7088dc3995751513dc3f2e9477",
    "legacy-seed7": "ac84819c82458ffb1f60ac34784f033e",
}


def format2_hash(plan, seed, overrides) -> str:
    """The hash of a mission's summary and its telemetry's format-2 columns."""
    cfg = load_scenario(overrides=[f"mission.seed={seed}", *overrides])
    m = Mission(cfg, plan=plan)
    summary = m.run()
    tlm = np.ascontiguousarray(m.telemetry()[:, :len(FORMATS[2])], dtype=np.float64)
    return _digest(_summary_bytes(summary), tlm.tobytes())


@pytest.mark.parametrize("name", sorted(EXPECTED_FORMAT2))
def test_the_physics_is_what_it_was_before_the_gyro_columns(name):
    assert format2_hash(*CASES[name]) == EXPECTED_FORMAT2[name], f"{name}: physics changed"


def format1_hash(plan, seed, overrides) -> str:
    """The hash of a mission's summary and telemetry as they were before the journal."""
    cfg = load_scenario(overrides=[f"mission.seed={seed}", *overrides])
    m = Mission(cfg, plan=plan)
    summary = {k: v for k, v in m.run().items() if k not in ADDED_WITH_THE_JOURNAL}
    if summary["calibration"]:
        summary["calibration"] = {k: v for k, v in summary["calibration"].items()
                                  if k != "drift_applied_deg_h"}
    summary["targets"] = [{k: v for k, v in t.items()
                           if k not in ("body_rate_deg_s", "computed_error_arcsec")}
                          for t in summary["targets"]]
    table = m.telemetry()
    # the decimated rows only: the row of the flight's last frame, off the grid, came later
    frames = np.array([clock.frame_at(m.params.clock, t) for t in table[:, 0]])
    table = table[frames % m.params.telemetry_every == 0]
    tlm = np.ascontiguousarray(table[:, :len(FORMATS[1])], dtype=np.float64)
    return _digest(_summary_bytes(summary), tlm.tobytes())


@pytest.mark.parametrize("name", sorted(EXPECTED_FORMAT1))
def test_the_physics_is_what_it_was_before_the_journal(name):
    assert format1_hash(*CASES[name]) == EXPECTED_FORMAT1[name], f"{name}: physics changed"


def compare_hash() -> str:
    result = compare(load_scenario(overrides=["mission.seed=3"]), runs=5, workers=2)
    return _digest(_summary_bytes(result))


def _check(name, value):
    if os.environ.get("ALLSKY_PRINT_HASHES"):
        print(f'    "{name}": "{value}",')
    assert EXPECTED.get(name) == value, f"{name}: results changed"


@pytest.mark.parametrize("name", sorted(CASES))
def test_mission_results_are_unchanged(name):
    _check(name, mission_hash(*CASES[name]))


def test_compare_results_are_unchanged():
    _check("compare-runs5", compare_hash())


#: The CPU-dependent paths a machine may take, switched to their plainest: glibc's libm
#: without its FMA and AVX2 variants, numba compiling for a generic x86-64 (or CPU), NumPy
#: without its SIMD dispatch targets, OpenBLAS on its oldest x86 kernels. A flight that
#: used any of them would change its bits here (docs/design.md, "The same bits everywhere").
def plain_machine_env() -> dict:
    import platform

    from numpy._core import _multiarray_umath as umath

    env = {**os.environ, "NUMBA_CPU_NAME": "generic",
           "GLIBC_TUNABLES": "glibc.cpu.hwcaps=-AVX2,-FMA,-AVX2_Usable,-FMA_Usable",
           "NPY_DISABLE_CPU_FEATURES": " ".join(
               f for f in umath.__cpu_dispatch__ if umath.__cpu_features__.get(f))}
    if platform.machine() in ("x86_64", "AMD64"):
        env["OPENBLAS_CORETYPE"] = "Prescott"
    return env


def test_the_results_are_the_same_bits_on_a_plainer_machine(tmp_path):
    """The hashes flown again on the plainest paths, compiled into a cache of their own.

    The generic CPU's loop goes to ``tmp_path``, not beside the installed package, whose
    cache holds the build's loop only (tests/apps/test_warm_up.py).
    """
    import subprocess
    import sys
    from pathlib import Path

    code = ("import json, sys; sys.path.insert(0, 'tests'); import test_results_hash as t; "
            "out = {n: t.mission_hash(*t.CASES[n]) for n in t.CASES}; "
            "out['compare-runs5'] = t.compare_hash(); print(json.dumps(out))")
    env = {**plain_machine_env(), "NUMBA_CACHE_DIR": str(tmp_path / "numba")}
    run = subprocess.run([sys.executable, "-c", code], env=env,
                         cwd=Path(__file__).resolve().parents[1], capture_output=True,
                         text=True, timeout=900, check=False)
    assert run.returncode == 0, run.stderr[-2000:]
    assert json.loads(run.stdout.strip().splitlines()[-1]) == EXPECTED
