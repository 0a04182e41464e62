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

from allsky.config.scenario import load_scenario
from allsky.sim.mission import DITHER_PLAN, LEGACY_PLAN, Mission
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
    "dither-seed1": "21b2cb04b424a3abf81f278c2bf5e8be",
    "dither-seed5": "75a13db6b9d886ede8d7795f8494ba19",
    "legacy-seed1": "ce4060111f2178c129c8ed1c203e5910",
    "legacy-seed23-vega": "fc3f4465b1849c05ba5df86b3e502296",
    "legacy-seed7": "08c44c688fc6a765434f6fa149437ed4",
    "compare-runs5": "74a41bd424e5995606644d0cdbd042ee",
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
