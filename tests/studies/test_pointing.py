"""Where the final pointing error comes from (allsky.studies.pointing).

Truth from the physics of Mode 6-2, which holds the counters' angles on the
gyros alone: a drift-counter error of delta turns the vehicle at -delta
about that axis for the whole of 6-2, so the roll axis leaves the target
by delta x (duration of 6-2) when the axis is across the line of sight.
"""

import numpy as np
import pytest

from allsky.config import load_scenario
from allsky.sim.mission import LEGACY_PLAN, Mission
from allsky.sim.results import fly_calibrating
from allsky.studies import pointing


@pytest.fixture(scope="module")
def calibrated():
    """Seed 1 at the end of Mode 5, and its snapshot."""
    m = Mission(load_scenario(overrides=["mission.seed=1"]), telemetry=False, plan=LEGACY_PLAN)
    snaps = []
    fly_calibrating(m, ("4", "5"), on_end=lambda mm: snaps.append(mm.snapshot()) or False)
    return m, snaps[0]


def test_an_injected_yaw_drift_error_is_the_drift_part(calibrated):
    """Truth stored, then 40 drift-DAC counts (0.1 deg/h = 0.1"/s) added on yaw: the
    drift part is 0.1"/s x the duration of Mode 6-2 (within 5 %), the scale-factor
    and cross-coupling parts are nil, and the targeting is the truth's."""
    m, (history, arrays) = calibrated
    w, d = pointing.true_storage(m)
    arrays = {**arrays, "word23": w, "drift_counters": d.copy()}
    arrays["drift_counters"][2] += 40
    parts = pointing.decompose(history, arrays)
    assert parts["scale_factor_arcsec"] == 0.0 and parts["misalignment_arcsec"] == 0.0
    flown = Mission.from_snapshot(history, arrays, telemetry=False)
    flown.run()
    mode62 = next(r for r in flown.timeline if r.mode == "6-2")
    lsb = m.params.electronics.drift_lsb_arcsec_s
    expected = 40 * lsb * (mode62.end_s - mode62.start_s)
    assert parts["drift_arcsec"] == pytest.approx(expected, rel=0.05)
    assert parts["total_arcsec"] == pytest.approx(flown.pointing_error_arcsec(), rel=1e-6)


def test_the_parts_of_the_legacy_calibration_add_up(calibrated):
    """Seed 1 as the legacy turns stored it: the vector parts less the interaction make the
    flown error; the truth alone points within 5" (the open-loop targeting's floor)."""
    _, snap = calibrated
    parts = pointing.decompose(*snap)
    assert parts["targeting_arcsec"] < 5.0
    assert parts["interaction_arcsec"] < 0.3 * parts["total_arcsec"]
    # The legacy drift count carries the Sun's apparent motion (docs/error_budget.md): the
    # largest part of the 8-9" is the drift counters'.
    assert parts["drift_arcsec"] > max(parts["scale_factor_arcsec"],
                                       parts["misalignment_arcsec"])


def test_line_of_sight_error_is_the_pointing_error(calibrated):
    _m, snap = calibrated
    flown = Mission.from_snapshot(*snap, telemetry=False)
    flown.run()
    e = pointing.line_of_sight_error_arcsec(flown)
    assert np.linalg.norm(e) == pytest.approx(flown.pointing_error_arcsec(), rel=1e-6)
