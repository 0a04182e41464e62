"""The numbers the documents quote about the physics, computed again and found in the text.

Each test computes a figure from its cause -- the ephemeris and the catalog,
Newton's and Euler's laws, the scaling of the electronics, or a flight of the
emulator set up to isolate it -- and checks the document quotes that figure,
so that a document cannot drift from what the code and the sky give.
Sources of truth: PyEphem's ephemeris and catalog (allsky.vehicle.sky);
w^2 / (2 a) for a stop at constant deceleration; T dt / I for a torque
pulse; N / sqrt(T) for angle random walk averaged over T.
"""

import math
from pathlib import Path

import numpy as np
import pytest

from allsky.computer.targeting import reference_frame
from allsky.config import load_scenario
from allsky.sim.mission import Mission, reference_star_inertial
from allsky.units import RAD2ARCSEC
from allsky.vehicle import sky
from tests.sky_geometry import sun_azimuth_deg

DOCS = Path(__file__).resolve().parents[2] / "docs"


def text(name) -> str:
    """A document, spaces normalised and the typographic minus as a hyphen."""
    return " ".join((DOCS / name).read_text().replace("\u2212", "-").split())


def quotes(name, *figures):
    page = text(name)
    for f in figures:
        assert " ".join(f.replace("\u2212", "-").split()) in page, f"{name} does not quote {f!r}"


def sun_angle_deg(star, date):
    return math.degrees(math.acos(sky.sun_direction_inertial(date)
                                  @ sky.star_direction_inertial(star, date)))


def test_assumptions_sirius_and_canopus_from_the_sun_on_2026_10_01():
    from datetime import datetime

    date = datetime.fromisoformat("2026-10-01T00:00:00Z")
    sirius, canopus = sun_angle_deg("Sirius", date), sun_angle_deg("Canopus", date)
    assert sirius == pytest.approx(84.91, abs=0.005)
    quotes("assumptions.md", f"Sirius {sirius:.2f}° from the Sun, Canopus {canopus:.2f}°")


def test_assumptions_cone_angles_on_the_default_date():
    date = load_scenario().mission.date_utc
    canopus = 90.0 - sun_angle_deg("Canopus", date)
    avior = 90.0 - sun_angle_deg("Avior", date)
    quotes("assumptions.md", f"Canopus {canopus:.2f}°, Avior +{avior:.2f}°",
           f"Avior ({abs(avior - canopus):.1f}° away)")


def test_assumptions_the_roll_couple_stops_inside_the_slit_and_its_smallest_pulses():
    cfg = load_scenario()
    j, inertia = cfg.jets, np.diag(cfg.vehicle.inertia_kg_m2)
    couple = [2 * f * r for f, r in zip(j.thrust_n, j.moment_arm_m)]
    w = math.radians(cfg.electronics.rate_command_deg_s)
    stop = math.degrees(w * w / (2 * couple[0] / inertia[0]))
    past = stop - cfg.sequencer.handover_arcsec / 3600.0
    steps = [couple[a] * j.min_on_time_s / inertia[a] * RAD2ARCSEC for a in range(3)]
    quotes("assumptions.md", f"stopping distance ω²/2α = {stop:.1f}°, so {past:.1f}° past",
           f"{steps[0]:.1f} arcsec/s (roll), {steps[1]:.1f} arcsec/s (pitch) and "
           f"{steps[2]:.1f} arcsec/s (yaw)")


def _mode3_count(*overrides, frozen_sun=False):
    """The drift counted in Mode 3 [deg/h], no drift and no noise but ``overrides``."""
    quiet = ["gyro.drift_deg_h=[0,0,0]", "gyro.arw_deg_rt_h=0", "gyro.rrw_deg_h_rt_h=0",
             "sun_sensor.noise_arcsec=0", "star_tracker.noise_arcsec=0", *overrides]
    m = Mission(load_scenario(overrides=quiet), telemetry=False)
    if frozen_sun:
        m.params = m.params._replace(sun_rate_inertial=np.zeros(3))
    for _ in range(3):
        m.run_mode()
    return m, m.calibration()["drift_deg_h"]


def test_error_budget_the_sun_and_the_settling_roll_loop_in_the_drift_count():
    m, counted = _mode3_count()
    count = next(r for r in m.timeline if r.mode == "3")
    p, star = m.params, reference_star_inertial(m.cfg)

    def frame(t):
        return reference_frame(p.sun0_inertial + p.sun_rate_inertial * t, star)
    turn = frame(count.end_s) @ frame(count.start_s).T  # body at the end from the start
    rate = np.array([turn[1, 2] - turn[2, 1], turn[2, 0] - turn[0, 2], turn[0, 1] - turn[1, 0]])
    rate_deg_h = rate / 2.0 * RAD2ARCSEC / (count.end_s - count.start_s)  # 1 deg/h = 1"/s
    sun_arcsec_s = np.linalg.norm(p.sun_rate_inertial) * RAD2ARCSEC
    assert counted["roll"] - rate_deg_h[0] == pytest.approx(0.018, abs=0.001)
    frozen = [_mode3_count(f"sequencer.drift_count_s={t}", frozen_sun=True)[1]["roll"]
              for t in (40, 60, 120)]
    # A fixed roll of the settling loop spread over the count: counts x T about constant.
    spread = [f * t for f, t in zip(frozen, (40, 60, 120))]
    assert max(spread) - min(spread) < 0.35  # [deg/h s = arcsec]: within 3 pulses of 0.1"
    quotes("error_budget.md", f"the Sun moves {sun_arcsec_s:.3f}″/s",
           f"turns at {rate_deg_h[2]:.3f} deg/h about yaw, +{rate_deg_h[0]:.4f} deg/h about "
           f"roll and +{rate_deg_h[1]:.4f} deg/h about pitch",
           f"the count reads +{counted['roll']:.4f} deg/h on roll, {counted['yaw']:.3f} on yaw",
           f"+{counted['roll'] - rate_deg_h[0]:.3f} deg/h, is the roll loop still closing",
           f"+{frozen[0]:.4f} deg/h over 40 s, +{frozen[1]:.3f} over 60 s, "
           f"+{frozen[2]:.3f} over 120 s", f"a roll of {min(spread):.1f}-{max(spread):.1f}″")


def test_error_budget_arw_and_quantisation():
    cfg = load_scenario()
    arw_arcsec_rt_s = cfg.gyro.arw_deg_rt_h * 3600.0 / 60.0  # deg/sqrt(h) -> "/sqrt(s)
    t = cfg.sequencer.drift_count_s
    quotes("error_budget.md", f"N/√T = ({arw_arcsec_rt_s:.2f}″/√s)/√{t:.0f} s = "
           f"{arw_arcsec_rt_s / math.sqrt(t):.4f} deg/h",
           f"drift DAC step {cfg.electronics.vfc_pulse_weight_arcsec / t:.4f} deg/h",
           f"{cfg.electronics.vfc_pulse_weight_arcsec:g}″ per pulse → "
           f"{cfg.electronics.vfc_pulse_weight_arcsec / 1296000 * 1e6:.2f} ppm")


def test_faults_a_dead_roll_gyro_runs_its_counter_on_the_applied_drift():
    m = Mission(load_scenario(overrides=[('faults=[{kind="gyro_dead", axis="roll", '
                                         'start_mode="6-2"}]')]), telemetry=False)
    while m.plan[m.next_mode] != "6-2":
        m.run_mode()
    applied = m.calibration()["drift_applied_deg_h"]["roll"]
    before, t0 = int(m.state.counters[0]), m.now_s()
    m.run_mode()
    # The loop turns the vehicle, but the dead gyro sees none of it: only the DAC counts.
    rate = (int(m.state.counters[0]) - before) / (m.now_s() - t0)
    pulses_s = -applied / m.pulse_weight_arcsec  # 1 deg/h = 1"/s at the summing amplifier
    assert rate == pytest.approx(pulses_s, rel=0.02)
    quotes("faults.md", f"stored roll drift (+{applied:.2f} deg/h)",
           f"runs backwards at {abs(pulses_s):.1f} pulses/s")


def test_faults_a_wrong_star_taken_in_mode_5_corrupts_yaw_into_roll():
    """Counter 14 holds the roll onto Avior, -dphi (1 + roll scale error), beside the yaw
    turn's true cross-coupling; divided by the 360 deg turn it is the stored factor."""
    cfg = load_scenario(overrides=[('faults=[{kind="wrong_star", star="Avior", start_mode="5"},'
                                   ' {kind="tracker_dropout", start_mode="5", duration_s=0.5}]')])
    m = Mission(cfg, telemetry=False)
    s = m.run()
    date = cfg.mission.date_utc
    sun = sky.sun_direction_inertial(date)
    dphi = sun_azimuth_deg(sun, sky.star_direction_inertial("Avior", date),
                           sky.star_direction_inertial("Canopus", date))
    predicted = dphi * (1 + cfg.gyro.scale_factor_error_ppm[0] * 1e-6) / 360.0 * RAD2ARCSEC
    stored = s["calibration"]["cross_coupling"]["yaw_into_roll"] * RAD2ARCSEC
    truth = s["truth"]["cross_coupling"]["yaw_into_roll"] * RAD2ARCSEC
    assert stored - truth == pytest.approx(predicted, abs=2.0)
    quotes("faults.md", f"{dphi:.2f} deg × 1.0015 / 360 deg = {predicted / RAD2ARCSEC:.5f} rad "
           f"= {predicted:.1f}″", f"{stored:.1f}″ stored against the gyro's {truth:.1f}″, "
           f"{stored - truth:.1f}″", f"points {s['target']['pointing_error_arcsec']:.0f}″ off")


def test_faults_a_wrong_star_added_in_mode_3_ends_the_roll_short_of_a_turn():
    m = Mission(load_scenario(overrides=[('faults=[{kind="wrong_star", star="Avior", '
                                         'start_mode="3"}]')]), telemetry=False)
    s = m.run()
    counted = m.counted_arcsec["roll"][0] / 3600.0
    date = m.cfg.mission.date_utc
    sun = sky.sun_direction_inertial(date)
    dphi = abs(sun_azimuth_deg(sun, sky.star_direction_inertial("Avior", date),
                               sky.star_direction_inertial("Canopus", date)))
    assert counted == pytest.approx((360.0 - dphi) * 1.0015, abs=0.05)
    quotes("faults.md", f"counter 14 holds {counted:.1f} deg",
           f"({s['target']['pointing_error_arcsec']:.0f}\")")


def test_assumptions_a_blowdown_feed_on_the_default_mission():
    regulated = Mission(load_scenario(), telemetry=False).run()
    blowdown = Mission(load_scenario(overrides=["jets.supply=blowdown"]), telemetry=False).run()
    quotes("assumptions.md", f"the default mission flies "
           f"{blowdown['target']['pointing_error_arcsec']:.1f}″, "
           f"{blowdown['propellant_kg']:.2f} kg, against "
           f"{regulated['target']['pointing_error_arcsec']:.1f}″ and "
           f"{regulated['propellant_kg']:.2f} kg regulated")
