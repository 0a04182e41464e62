"""What the machine judged, and beside it what happened: saturations, the end, the warnings.

Truth:
- Drift DACs 7/9/11 are 12-bit converters of the drift count with one count
  = pulse weight / count time = 0.1 arcsec / 40 s = 0.0025 arcsec/s = 0.0025
  deg/h (1 deg/h = 1 arcsec/s): full scale 2047 x 0.0025 = 5.1175 deg/h. A
  roll gyro drift of 4.0 deg/h plus an integrator drift of 2.0 deg/h (6.0
  deg/h in all) is counted (about 6.05 deg/h) but only 5.1175 deg/h is
  applied. In the hold on target the gyros alone hold the vehicle, the
  converter input ``S w + d - D`` averages zero, so the vehicle turns at
  ``w = (D - d) / S``: -0.8825 arcsec/s = -52.95 arcsec/min about roll
  (tests/flights/test_hold.py derives the rule; S departs from 1 by under
  2000 ppm, 0.1 arcsec/min here).
- A dead pitch gyro reads zero: counter 16 counts only the drift DAC 9's
  correction, CPU 22's pitch error settles while the vehicle turns; the
  truth at the end is a tumble (tens of deg/s) that the computer cannot see.
- A three-target plan ends on its third target: ``end`` names it and the
  journal holds each target's mode starts in flight order.
"""

import numpy as np
import pytest

from allsky.config import load_scenario
from allsky.config.faults import packaged_or_path
from allsky.sim.mission import Mission

DRIFT_LSB_DEG_H = 0.1 / 40.0  # pulse weight [arcsec] / count time [s], per count
DAC_FULL_SCALE_DEG_H = 2047 * DRIFT_LSB_DEG_H  # 5.1175 deg/h
HOLD_S = 300.0


@pytest.fixture(scope="module")
def clipped():
    cfg = load_scenario(overrides=["gyro.drift_deg_h=[4.0,0.0,0.0]",
                                   "electronics.integrator_drift_deg_h=[2.0,0.0,0.0]",
                                   f"target.hold_s={HOLD_S}"])
    m = Mission(cfg, telemetry=False)
    return m.run()


def test_a_clipped_drift_dac_is_reported_beside_the_count(clipped):
    s = clipped
    assert DAC_FULL_SCALE_DEG_H == pytest.approx(5.1175, abs=1e-12)
    assert s["drift_dac_clipped"] == {"roll": True, "pitch": False, "yaw": False}
    cal = s["calibration"]
    assert cal["drift_applied_deg_h"]["roll"] == pytest.approx(DAC_FULL_SCALE_DEG_H, abs=1e-12)
    assert cal["drift_deg_h"]["roll"] == pytest.approx(6.0, abs=0.1)  # what was counted
    for axis in ("pitch", "yaw"):  # within the DAC's range: applied as counted
        assert cal["drift_applied_deg_h"][axis] == cal["drift_deg_h"][axis]
    (warning,) = [w for w in s["warnings"] if "drift DAC 7" in w]
    assert "full scale +5.1175 deg/h" in warning and "roll" in warning
    assert len(s["warnings"]) == 1


def test_the_clip_is_journaled_when_s1_closes(clipped):
    events = clipped["events"]
    (closing,) = [e for e in events if e["kind"] == "switch" and 1 in e["close"]]
    (dac,) = [e for e in events if e["kind"] == "register" and e["register"] == "7"]
    (clip,) = [e for e in events if e["kind"] == "saturation" and e["what"] == "drift_dac_clip"]
    assert dac["t_s"] == closing["t_s"] and dac["pulses"] == 2047 and dac["counted_pulses"] > 2047
    # The frame loop sees the DAC at full scale from the first frame S1 feeds it.
    assert clip["t_s"] == closing["t_s"] and clip["active"] and clip["axis"] == "roll"
    assert clip["applied_pulses"] == 2047 and clip["counted_pulses"] == dac["counted_pulses"]


def test_the_hold_drifts_as_the_applied_drift_predicts(clipped):
    truth_deg_h = 4.0 + 2.0
    expected = (DAC_FULL_SCALE_DEG_H - truth_deg_h) * 60.0  # arcsec/min, about roll
    assert expected == pytest.approx(-52.95)
    drift = clipped["hold"]["drift_arcsec_per_min"]
    # The scale factor (under 2000 ppm off) and the random walks: well within 1 arcsec/min.
    assert drift["roll"] == pytest.approx(expected, abs=1.0)
    # What the counted value would have predicted is far off: the report must not use it.
    counted = clipped["calibration"]["drift_deg_h"]["roll"]
    assert abs(drift["roll"] - (counted - truth_deg_h) * 60.0) > 50.0


@pytest.fixture(scope="module")
def dead_gyro():
    m = Mission(load_scenario(packaged_or_path("gyro-failure-to-target")), telemetry=False)
    return m.run()


def test_a_tumbling_vehicle_declared_on_target_is_shown_and_warned(dead_gyro):
    s = dead_gyro
    assert s["status"] == "complete"  # the 1970s machine's judgement stands
    rates = s["end"]["body_rate_deg_s"]
    assert abs(rates["pitch"]) > 10.0  # the truth: a tumble about pitch
    assert s["end"]["true_pointing_error_arcsec"] > 3600.0
    target = s["targets"][0]
    assert target["body_rate_deg_s"] == rates  # declared on target at the end of 6-2
    assert max(abs(v) for v in target["computed_error_arcsec"].values()) < 50.0
    tumble = [w for w in s["warnings"] if "turned at" in w]
    assert len(tumble) == 1 and "about pitch" in tumble[0]
    assert "pitch gyro dead" in tumble[0]
    assert any("times what the computer judged" in w for w in s["warnings"])
    fault = [e for e in s["events"] if e["kind"] == "fault"]
    assert [(e["fault_kind"], e["active"], e["mode"]) for e in fault] == [
        ("gyro_dead", True, "6-2")]


def test_a_three_target_plan_ends_on_its_third_target():
    cfg = load_scenario(overrides=["target.sequence=['Vega','Achernar','Capella']",
                                   "target.hold_s=60"])
    m = Mission(cfg, telemetry=False)
    s = m.run()
    assert s["status"] == "complete"
    assert s["end"]["target"] == "Capella" and s["target"]["star"] == "Vega"
    assert s["end"]["true_pointing_error_arcsec"] == pytest.approx(
        s["targets"][2]["hold_end_pointing_error_arcsec"])
    starts = [(e["target"], e["mode"]) for e in s["events"] if e["kind"] == "mode_start"]
    assert [mode for _, mode in starts] == [r["mode"] for r in s["modes"]]  # in flight order
    flown_to = [t for t, mode in starts if mode == "6-1"]
    assert flown_to == ["Vega", "Achernar", "Capella"]
    times = [e["t_s"] for e in s["events"]]
    assert times == sorted(times)
    assert s["warnings"] == []


def test_a_resumed_mission_s_journal_is_the_uninterrupted_one_s(saved_states):
    from allsky.apps import states

    whole = saved_states["mission"].summary()["events"]
    m = states.load(saved_states["4"], telemetry=False)
    m.run()
    assert m.summary()["events"] == whole


def test_every_summary_says_the_end_even_when_aborted():
    m = Mission(load_scenario(overrides=["jets.propellant_kg=0.05"]), telemetry=False)
    s = m.run()
    assert s["status"] == "aborted"
    assert s["end"]["t_s"] == s["mission_time_s"] and s["end"]["propellant_remaining_kg"] == 0.0
    (abort,) = [e for e in s["events"] if e["kind"] == "abort"]
    assert abort["reason"] == s["abort_reason"] and abort["t_s"] == s["mission_time_s"]
    ends = [e for e in s["events"] if e["kind"] == "mode_end"]
    assert ends[-1]["status"] == "aborted"
    assert np.isfinite(s["end"]["true_pointing_error_arcsec"])
