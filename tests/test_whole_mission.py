"""The patent's whole mission, end to end: integrator drift, Mode 3's exit, the star locked.

Truth:
- US 4,012,018, Mode 3: the drift counters count "the net drift" of each
  gyro and its chain to the converter; the stored drift DAC value removes
  the gyro's and the integrator's drift alike, so an integrator drift of
  1.5 deg/h (= 1.5 arcsec/s at the converter) on roll with perfect gyros is
  stored within the 0.1 deg/h drift accuracy, and pointing stays within 60";
  uncalibrated, 1.5 arcsec/s over the ~250 s of Mode 6 is hundreds of arcsec.
- Mode 3 ends when, S1-S3 closed, the optical errors "have remained less
  than 50 arc-seconds for at least 10 seconds": settled throughout the
  40 s count, Mode 3 lasts the count plus the one frame in which the
  sequencer sees S1-S3 closed.
- The programmed angles are computed for the planned star; on 2026-10-01 the
  Sun is 83 deg from Sirius and 88 deg from Canopus, both inside the
  tracker's 90 +- 16 deg slit, and the Mode 2 roll meets Sirius first: with a
  window passing both (V = -1.44 and -0.62), the tracker locks Sirius. The
  vehicle then points as far off as the roll-yaw frame built on the wrong
  star puts it (tens of degrees: Sirius and Canopus are 36 deg apart).
"""

import zipfile

import numpy as np
import pytest

from allsky.apps import states
from allsky.apps.report import format_report, tracker_star
from allsky.config.scenario import load_scenario
from allsky.sim.mission import DITHER_PLAN, Mission
from allsky.sim.results import calibration_errors
from allsky.units import DEG2ARCSEC

INTEGRATOR = ["electronics.integrator_drift_deg_h=[1.5, 0, 0]", "gyro.drift_deg_h=[0, 0, 0]"]
TWO_STARS = ["mission.date_utc=2026-10-01T12:00:00Z", "star_tracker.magnitude_window=[-1.5, -0.3]"]


def fly(overrides, plan=None):
    m = Mission(load_scenario(overrides=overrides), telemetry=False,
                **({"plan": plan} if plan else {}))
    m.run()
    return m


@pytest.fixture(scope="module")
def default_mission():
    return fly([])


def test_mode3_removes_an_integrator_drift():
    s = fly(INTEGRATOR).summary()
    assert s["status"] == "complete", s["abort_reason"]
    truth = s["truth"]
    assert truth["integrator_drift_deg_h"] == {"roll": 1.5, "pitch": 0.0, "yaw": 0.0}
    assert truth["gyro_drift_deg_h"] == {"roll": 0.0, "pitch": 0.0, "yaw": 0.0}
    assert truth["drift_deg_h"] == {"roll": 1.5, "pitch": 0.0, "yaw": 0.0}  # the sum
    err = calibration_errors(s["calibration"], truth)["drift_deg_h"]
    assert all(abs(e) < 0.1 for e in err.values()), err
    assert s["target"]["pointing_error_arcsec"] < 60.0


def test_an_uncalibrated_integrator_drift_points_far_off():
    s = fly([*INTEGRATOR, "calibration.apply=false"]).summary()
    assert s["status"] == "complete", s["abort_reason"]
    assert s["target"]["pointing_error_arcsec"] > 600.0


def test_truth_adds_gyro_and_integrator_drift(default_mission):
    truth = default_mission.summary()["truth"]
    for ax, gyro_deg_h in zip(("roll", "pitch", "yaw"), (1.2, -0.8, 1.5)):  # default.toml
        assert truth["gyro_drift_deg_h"][ax] == gyro_deg_h
        assert truth["integrator_drift_deg_h"][ax] == 0.0
        assert truth["drift_deg_h"][ax] == gyro_deg_h


def test_mode3_ends_once_the_errors_have_remained_settled(default_mission):
    cfg = default_mission.cfg
    mode3 = next(r for r in default_mission.timeline if r.mode == "3")
    assert mode3.end_s - mode3.start_s == pytest.approx(
        cfg.sequencer.drift_count_s + cfg.mission.frame_s, abs=1e-6)


def test_default_mission_locks_the_planned_star(default_mission):
    s = default_mission.summary()
    assert s["reference_star"] == s["locked_star"] == "Canopus"
    assert "the tracker locked" not in format_report(s, tracker_star(default_mission.cfg))


def test_a_window_passing_two_stars_can_lock_the_wrong_one():
    m = fly(TWO_STARS, plan=DITHER_PLAN)
    s = m.summary()
    assert s["status"] == "complete", s["abort_reason"]
    assert (s["reference_star"], s["locked_star"]) == ("Canopus", "Sirius")
    assert s["target"]["pointing_error_arcsec"] > 10.0 * DEG2ARCSEC
    text = format_report(s, tracker_star(m.cfg))
    assert "the tracker locked Sirius, not the planned Canopus" in text


def test_the_locked_star_survives_save_and_resume(tmp_path):
    m = Mission(load_scenario(overrides=TWO_STARS), telemetry=False, plan=DITHER_PLAN)
    m.run_mode()
    m.run_mode()  # Mode 2: the roll search locks Sirius
    path = tmp_path / "after2.npz"
    states.save(m, path)
    assert states.load(path).locked_star() == "Sirius"
    # A file written before the tracker told its star: loads, with none recorded.
    older = tmp_path / "older.npz"
    with zipfile.ZipFile(path) as src, zipfile.ZipFile(older, "w") as dst:
        for item in src.infolist():
            if item.filename != f"{states.ARRAY_PREFIX}locked_star.npy":
                dst.writestr(item, src.read(item))
    assert states.load(older).locked_star() is None


def test_a_state_saved_before_the_locked_star_was_kept_still_loads(tmp_path):
    m = Mission(load_scenario(), telemetry=False)
    m.run_mode()
    history, arrays = m.snapshot()
    del arrays["locked_star"]
    resumed = Mission.from_snapshot(history, arrays, telemetry=False)
    assert resumed.locked_star() is None
    assert np.array_equal(resumed.state.x, m.state.x)
