"""The hold on target after Mode 6-2: the gyros alone hold it, so it drifts as the drift store errs.

Truth:
- In the hold CPU 22 keeps the errors it forms from counters 14/16/18 at zero
  and no optical sensor is switched in (S14, S15 open since 6-2), so each
  counter stands still: the converter input, gyro output less drift DAC
  7/9/11, is zero on average. With gyro sensitivity S (scale factor and
  misalignment), true drift d and stored drift D, ``S w + d - D = 0``: the
  vehicle turns at ``w = S^-1 (D - d)`` [arcsec/s]. 1 deg/h = 1 arcsec/s,
  so a drift store off by ``r`` deg/h turns the vehicle at 60 r arcsec/min,
  in the sign of r: the DAC takes out more than the gyro's drift, the loop
  turns the vehicle the other way to keep the counter still (convention of
  ``drift_arcsec_per_min``: positive about the positive body axis).
- Noise: the gyros' angle random walk (0.001 deg/sqrt(h) = 3.6 arcsec/sqrt(h))
  makes the angle after T seconds wander by 3.6 sqrt(T/3600) arcsec (1
  sigma): 2.1 arcsec over the 1200 s hold, 0.10 arcsec/min; the rate
  random walk (0.002 deg/h/sqrt(h)) adds 0.04 arcsec/min, 0.11 arcsec/min in
  all. Four sigma: 0.45 arcsec/min.
- Two holds resumed from one saved state draw the same noise (the draws are
  seeded by mission seed and leg number), so their difference is
  ``60 S^-1`` times the injected drift error alone; what is left is the
  computed errors' wander inside the PWPF deadband (under 1 arcsec at the
  hold's start and end: 0.05 arcsec/min over 20 min).
"""

import json

import numpy as np
import pytest

from allsky.apps import telemetry_files
from allsky.apps.cli import main
from allsky.apps.plots import attitude_errors, mode_spans
from allsky.config.scenario import load_scenario
from allsky.sequencer import modes
from allsky.sim.mission import DITHER_PLAN, LEGACY_PLAN, Mission

HOLD_S = 1200.0
AXES = ("roll", "pitch", "yaw")
#: Drift counter 13/15/17 offsets [counts] injected after 6-2: 0.5, -0.5, 0.75 deg/h.
INJECTED_COUNTS = np.array([200, -200, 300])
ARW_DEG_RT_H = 0.001
RRW_DEG_H_RT_H = 0.002


def noise_sigma_arcsec_per_min(hold_s):
    """1-sigma drift rate the random walks fake over ``hold_s`` [arcsec/min]."""
    arw_angle = ARW_DEG_RT_H * 3600.0 * np.sqrt(hold_s / 3600.0)  # arcsec
    rrw_rate = RRW_DEG_H_RT_H / 60.0  # arcsec/s per sqrt(s)
    rrw_angle = rrw_rate * hold_s ** 1.5 / np.sqrt(3.0)  # arcsec
    return np.hypot(arw_angle, rrw_angle) / (hold_s / 60.0)


@pytest.fixture(scope="module")
def before_hold():
    """A mission flown to the end of 6-2 with a hold to come, and its saved state."""
    cfg = load_scenario(overrides=[f"target.hold_s={HOLD_S}",
                                   f"gyro.arw_deg_rt_h={ARW_DEG_RT_H}",
                                   f"gyro.rrw_deg_h_rt_h={RRW_DEG_H_RT_H}"])
    m = Mission(cfg, telemetry=False)
    while m.plan[m.next_mode] != "hold":
        m.run_mode()
    assert m.status == "running" and m.timeline[-1].mode == "6-2"
    return m.snapshot()


def hold(snapshot, counts=(0, 0, 0)):
    """Resume, add ``counts`` to drift counters 13/15/17, fly the hold; the mission."""
    m = Mission.from_snapshot(*snapshot, telemetry=False)
    m.state.drift_counters[:] += np.asarray(counts)
    m.run_mode()
    assert m.status == "complete", m.abort_reason
    return m


def expected_arcsec_per_min(m):
    """``60 S^-1 (D - d)``: the drift the stored drift's error makes [arcsec/min]."""
    p = m.params
    error_deg_h = (m.state.drift_counters * p.electronics.drift_lsb_arcsec_s
                   - (p.gyro.drift_arcsec_s + p.vfc.integrator_drift_arcsec_s))
    return 60.0 * np.linalg.solve(p.gyro.sensitivity, error_deg_h)


def measured(m):
    return np.array([m.summary()["hold"]["drift_arcsec_per_min"][ax] for ax in AXES])


def test_the_hold_drifts_as_the_drift_store_errs(before_hold):
    m = hold(before_hold, INJECTED_COUNTS)
    h = m.summary()["hold"]
    assert h["hold_s"] == pytest.approx(HOLD_S, abs=0.1)
    want = expected_arcsec_per_min(m)
    # The injected 0.5, -0.5, 0.75 deg/h dominate: 60 x (residual) within a few percent.
    injected_deg_h = INJECTED_COUNTS * m.params.electronics.drift_lsb_arcsec_s
    np.testing.assert_allclose(injected_deg_h, [0.5, -0.5, 0.75])
    tol = 4.0 * noise_sigma_arcsec_per_min(HOLD_S)
    assert tol == pytest.approx(0.45, abs=0.01)
    np.testing.assert_allclose(measured(m), want, rtol=0, atol=tol)
    # Pointing: the roll axis walks off the target by about the drift times the hold.
    pitch_yaw_arcsec_per_min = np.hypot(want[1], want[2])
    assert h["end_pointing_error_arcsec"] == pytest.approx(
        pitch_yaw_arcsec_per_min * HOLD_S / 60.0, abs=h["start_pointing_error_arcsec"] + 10.0)


def test_the_same_noise_leaves_the_injected_drift_alone(before_hold):
    plain, off = hold(before_hold), hold(before_hold, INJECTED_COUNTS)
    np.testing.assert_allclose(measured(plain), expected_arcsec_per_min(plain), rtol=0,
                               atol=4.0 * noise_sigma_arcsec_per_min(HOLD_S))
    lsb = off.params.electronics.drift_lsb_arcsec_s
    want = 60.0 * np.linalg.solve(off.params.gyro.sensitivity, INJECTED_COUNTS * lsb)
    np.testing.assert_allclose(measured(off) - measured(plain), want, rtol=0, atol=0.05)


def test_the_hold_survives_save_and_resume(before_hold):
    m = hold(before_hold)
    history, arrays = m.snapshot()
    again = Mission.from_snapshot(json.loads(json.dumps(history)), arrays, telemetry=False)
    assert again.summary()["hold"] == m.summary()["hold"]
    assert again.plan == (*LEGACY_PLAN, "hold")


def test_no_hold_leaves_the_plan_and_summary_as_they_were():
    cfg = load_scenario()
    assert cfg.target.hold_s == 0.0
    assert Mission(cfg).plan == LEGACY_PLAN
    assert Mission(cfg, plan=DITHER_PLAN).plan == DITHER_PLAN
    held = load_scenario(overrides=["target.hold_s=60"])
    assert Mission(held, plan=DITHER_PLAN).plan == (*DITHER_PLAN, "hold")
    assert Mission(held, plan=(*LEGACY_PLAN, "hold")).plan == (*LEGACY_PLAN, "hold")
    m = Mission(cfg, telemetry=False)
    s = m.run()
    assert "hold" not in s and [r["mode"] for r in s["modes"]] == list(LEGACY_PLAN)


def test_the_hold_mode_is_in_the_table():
    mode = modes.BY_NAME["hold"]
    assert (mode.code, mode.title) == (6.3, "hold on target")
    cfg = load_scenario(overrides=["target.hold_s=600"])
    assert modes.timeout_s(cfg, "hold") >= 600.0
    # No switch moves: the bank stays as 6-2 left it.
    closed = modes.closed_after((*LEGACY_PLAN, "hold"))
    assert closed["hold"] == closed["6-2"]


def test_a_hold_longer_than_the_mission_allows_is_refused():
    from allsky.config import ConfigError

    with pytest.raises(ConfigError, match="target.hold_s"):
        load_scenario(overrides=["target.hold_s=86400"])
    with pytest.raises(ConfigError, match="target.hold_s"):
        load_scenario(overrides=["target.hold_s=-1"])


def test_allsky_run_reports_the_hold(tmp_path, capsys):
    js, tl = tmp_path / "s.json", tmp_path / "t.csv"
    assert main(["run", "--set", "target.hold_s=600", "--json", str(js),
                 "--telemetry", str(tl)]) == 0
    report = capsys.readouterr().out
    assert "Hold on target (600.0 s, gyros alone)" in report
    assert "drift [arcsec/min] roll" in report
    s = json.loads(js.read_text())
    assert [r["mode"] for r in s["modes"]][-2:] == ["6-2", "hold"]
    assert set(s["hold"]) == {"hold_s", "start_pointing_error_arcsec",
                              "end_pointing_error_arcsec", "drift_arcsec_per_min"}
    assert set(s["hold"]["drift_arcsec_per_min"]) == set(AXES)
    table, _ = telemetry_files.read(tl)  # the reader knows code 6.3 from the mode table
    spans = mode_spans(table)
    assert spans[-1][0] == "hold" and spans[-1][2] - spans[-1][1] == pytest.approx(600, abs=1)
    attitude_errors(table, s)  # the figure shades and names the hold
