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
    "dither-seed1": "24d937b29046a80bfebbe805c2aa74a0",
    "dither-seed5": "114fd52e2ce83813b2f7c1edc4db120e",
    "legacy-seed1": "cc01586624e80f1ab50836735e5a8f2b",
    "legacy-seed23-vega": "7afb5caf674e790a9f30b217a7f092cf",
    "legacy-seed7": "1a74979ebdc38566646daec3869ad458",
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


#: What the summary gained with the journal (telemetry format 2): the truth beside the
#: machine's judgement. Without them, and with the telemetry's format-1 columns only, each
#: mission hashes as it did before: the physics did not move.
ADDED_WITH_THE_JOURNAL = ("drift_dac_clipped", "end", "warnings", "events")
#: The hashes of :data:`CASES` before the journal (format-1 view, :func:`format1_hash`).
EXPECTED_FORMAT1 = {
    "dither-seed1": "21b2cb04b424a3abf81f278c2bf5e8be",
    "dither-seed5": "75a13db6b9d886ede8d7795f8494ba19",
    "legacy-seed1": "ce4060111f2178c129c8ed1c203e5910",
    "legacy-seed23-vega": "fc3f4465b1849c05ba5df86b3e502296",
    "legacy-seed7": "08c44c688fc6a765434f6fa149437ed4",
}


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
    tlm = np.ascontiguousarray(m.telemetry()[:, :len(FORMATS[1])], dtype=np.float64)
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
