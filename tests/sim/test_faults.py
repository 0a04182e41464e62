"""Faults: validation, each kind's effect at its block, the outcomes, the matrix, dispersion."""

import math

import numpy as np
import pytest

from allsky import clock
from allsky.apps.cli import main
from allsky.config import ConfigError, load_scenario
from allsky.config import dispersions as disp
from allsky.config.faults import KINDS, packaged_scenarios
from allsky.hardware import star_tracker as trk
from allsky.hardware.star_tracker import FALSE_TARGET, new_lock, star_tracker
from allsky.sim import faults as sf
from allsky.sim.mission import Mission, build_params, tracker_star_names
from allsky.studies.faults import fault_matrix
from allsky.units import ARCSEC2RAD, DEG2ARCSEC
from allsky.vehicle import quaternion, sky
from tests.sky_geometry import sun_azimuth_deg


def _cfg(*faults, extra=()):
    return load_scenario(overrides=[f"faults=[{', '.join(faults)}]", *extra])


def _params(*faults, extra=()):
    cfg = _cfg(*faults, extra=extra)
    fs = sf.new_fault_state()
    p = build_params(cfg)
    sf.arm(fs, cfg.faults, p.clock)
    return cfg, p, fs


def _frame(p, t_s):
    """The frame a mission time [s] lands on (the clock's rule)."""
    return clock.frame_at(p.clock, t_s)


# -- validation -----------------------------------------------------------------------

@pytest.mark.parametrize("fault, key", [
    ('{kind="gyro_ded", axis="roll"}', "faults[0].kind"),
    ('{kind="gyro_dead"}', "faults[0].axis"),
    ('{kind="gyro_dead", axis="roll", duration_s=-1}', "faults[0].duration_s"),
    ('{kind="jet_stuck_open", axis="roll", sign=2}', "faults[0].sign"),
    ('{kind="counter_upset", register="19", bit=0}', "faults[0].register"),
    ('{kind="counter_upset", register="14", bit=28}', "faults[0].bit"),
    ('{kind="wrong_star", star="Canopuss"}', "faults[0].star"),
    ('{kind="tracker_stray_light", offset_deg=9}', "faults[0].offset_deg"),
    ('{kind="gyro_dead", axis="roll", start_mode="7"}', "faults[0].start_mode"),
    ('{kind="gyro_dead", axis="roll", size_ppm=3}', "faults[0].size_ppm"),
    ('{kind="jet_stuck_open", axis="roll", sign=1, jets=3}', "faults[0].jets"),
    ('{kind="gyro_dead", axis="roll", jets=1}', "faults[0].jets"),
    ('{kind="propellant_leak", rate_kg_s=0.1, torque_n_m=[1, 2]}', "faults[0].torque_n_m"),
    ('{kind="propellant_leak", rate_kg_s=0.1}', "faults[0].torque_n_m"),
    ('{kind="propellant_leak", rate_kg_s=0.1, vent_position_m=[0, 0, 1]}',
     "faults[0].vent_direction"),
    (('{kind="propellant_leak", rate_kg_s=0.1, vent_position_m=[0, 0, 1], '
      'vent_direction=[0, 0, 0]}'), "faults[0].vent_direction"),
    (('{kind="propellant_leak", rate_kg_s=0.1, torque_n_m=[0, 0, 0], '
      'vent_position_m=[0, 0, 1], vent_direction=[1, 0, 0]}'), "faults[0].vent_position_m"),
    ('{kind="tracker_stray_light", offset_deg=1, magnitude="bright"}', "faults[0].magnitude"),
])
def test_a_bad_fault_is_refused_naming_its_key(fault, key, capsys):
    with pytest.raises(ConfigError) as e:
        _cfg(fault)
    assert e.value.key == key
    assert main(["config", "check", "--set", f"faults=[{fault}]"]) == 2
    assert key in capsys.readouterr().err


@pytest.mark.parametrize("fault, extra", [
    ('{kind="gyro_dead", axis="roll", start_mode="hold"}', ()),  # no hold flown
    ('{kind="gyro_dead", axis="roll", start_mode="reacquire"}', ()),  # one target
    ('{kind="gyro_dead", axis="roll", start_mode="recycle"}',
     ('target.sequence=["Vega", "Achernar"]',)),  # the targets are reacquired, not recycled
    ('{kind="gyro_dead", axis="roll", start_mode="direct"}',
     ('target.sequence=["Vega", "Achernar"]',)),  # ... nor flown one from the other
])
def test_a_start_mode_the_scenario_never_flies_is_refused(fault, extra, capsys):
    with pytest.raises(ConfigError) as e:
        _cfg(fault, extra=extra)
    assert e.value.key == "faults[0].start_mode"
    sets = [x for a in extra for x in ("--set", a)]
    assert main(["config", "check", "--set", f"faults=[{fault}]", *sets]) == 2
    assert "faults[0].start_mode" in capsys.readouterr().err


def test_a_start_mode_the_scenario_flies_is_accepted():
    assert _cfg('{kind="gyro_dead", axis="roll", start_mode="hold"}',
                extra=("target.hold_s=60",)).faults[0]["start_mode"] == "hold"
    seq = ('target.sequence=["Vega", "Achernar"]', "sequencer.between_targets=recycle")
    assert _cfg('{kind="gyro_dead", axis="roll", start_mode="recycle"}', extra=seq).faults
    seq = ('target.sequence=["Vega", "Achernar"]', "sequencer.between_targets=direct")
    assert _cfg('{kind="gyro_dead", axis="roll", start_mode="direct"}', extra=seq).faults


def test_a_start_mode_outside_the_plan_is_refused_when_the_mission_is_built(capsys):
    """The plan is the command's (run: the patent's; step --plan dither: the dither's)."""
    dither = _cfg('{kind="gyro_dead", axis="roll", start_mode="dither"}')
    with pytest.raises(ConfigError) as e:
        Mission(dither, telemetry=False)
    assert e.value.key == "faults[0].start_mode"
    Mission(dither, telemetry=False, plan=("1", "2", "3", "dither", "6-1", "6-2"))
    with pytest.raises(ConfigError):
        Mission(_cfg('{kind="gyro_dead", axis="roll", start_mode="4"}'), telemetry=False,
                plan=("1", "2", "3", "dither", "6-1", "6-2"))
    assert main(["run", "--set", 'faults=[{kind="gyro_dead",axis="roll",start_mode="dither"}]',
                 "--quiet"]) == 2
    assert "faults[0].start_mode" in capsys.readouterr().err


def test_a_wrong_star_the_slit_never_crosses_is_refused(capsys):
    """Sirius is 123.5 deg from the Sun on the default date; the slit sweeps 74-106 deg."""
    with pytest.raises(ConfigError) as e:
        _cfg('{kind="wrong_star", star="Sirius"}')
    assert e.value.key == "faults[0].star" and "123.5 deg from the Sun" in str(e.value)
    assert "74-106 deg" in str(e.value)
    assert _cfg('{kind="wrong_star", star="Avior"}').faults[0]["star"] == "Avior"


def test_faults_load_from_a_file_and_round_trip(tmp_path):
    p = tmp_path / "f.toml"
    p.write_text('[[faults]]\nkind = "tracker_dropout"\nstart_mode = "4"\nduration_s = 60\n'
                 '[[faults]]\nkind = "gyro_bias_step"\naxis = "yaw"\nsize_deg_h = 2\n')
    cfg = load_scenario(p)
    assert [f["kind"] for f in cfg.faults] == ["tracker_dropout", "gyro_bias_step"]
    assert cfg.faults[1]["start_s"] == 0.0
    again = tmp_path / "again.toml"
    again.write_text(cfg.to_toml())
    assert load_scenario(again) == cfg


def test_the_fault_free_mission_has_no_fault_arrays_in_use():
    cfg = load_scenario()
    assert cfg.faults == () and build_params(cfg).faults.n == 0
    assert "faults" not in cfg.as_dict()


# -- each kind at its block --------------------------------------------------------------

def _sense(p, fs, t, gyro=(10.0, 20.0, 30.0), dtheta=(1e-4, 0.0, 0.0)):
    fine = np.array([5.0, 6.0, 1.0])
    trk = np.array([7.0, 8.0, 1.0])
    g = np.array(gyro)
    star = sf.fault_sense(p.faults, p.faults.tracker, fs, _frame(p, t), 0.01, np.array(dtheta),
                          fine, trk,
                          g, new_lock(), 3, True)
    return fine, trk, g, star


def test_a_stuck_gyro_holds_the_output_of_its_onset_frame():
    _, p, fs = _params('{kind="gyro_stuck", axis="pitch", start_s=1.0}')
    assert _sense(p, fs, 0.5)[2][1] == 20.0  # before the onset: untouched
    assert _sense(p, fs, 1.0, gyro=(0, 20.0, 0))[2][1] == 20.0
    for rate in (-500.0, 0.0, 900.0):  # whatever the vehicle does, the output stays
        assert _sense(p, fs, 2.0, gyro=(0, rate, 0))[2][1] == 20.0


def test_a_stuck_gyro_counter_stops_following_the_vehicle():
    """Stuck in the Mode 4 roll: counter 14 creeps at the frozen rate while the vehicle rolls."""
    from allsky.sim.telemetry import COLUMNS

    cfg = _cfg('{kind="gyro_stuck", axis="roll", start_mode="4"}')
    m = Mission(cfg, telemetry=True)
    while m.plan[m.next_mode] != "4":
        m.run_mode()
    m.run_mode()
    tlm = m.telemetry()
    col = [c.name for c in COLUMNS]
    t = tlm[:, col.index("time")]
    start = m.timeline[-1].start_s
    window = (t > start + 1) & (t < start + 20)
    counted_arcsec = np.ptp(tlm[window, col.index("counter14")]) * 0.1
    rolled_arcsec = np.sum(np.abs(tlm[window, col.index("rate_x")])) * 0.1 / ARCSEC2RAD
    assert rolled_arcsec > 10 * DEG2ARCSEC  # the vehicle rolls ...
    assert counted_arcsec < 1e-3 * rolled_arcsec  # ... the counter hardly moves


def test_a_dead_gyro_reads_zero_and_steps_add_bias_and_scale():
    _, p, fs = _params('{kind="gyro_dead", axis="roll"}',
                       '{kind="gyro_bias_step", axis="pitch", size_deg_h=3}',
                       '{kind="gyro_scale_factor_step", axis="yaw", size_ppm=1000}')
    dtheta = (0.0, 0.0, 1e-5)
    _, _, g, _ = _sense(p, fs, 0.0, dtheta=dtheta)
    assert g[0] == 0.0
    assert g[1] == pytest.approx(20.0 + 3.0)  # 1 deg/h = 1 arcsec/s
    assert g[2] == pytest.approx(30.0 + 1e-3 * 1e-5 / 0.01 / ARCSEC2RAD)


def test_blind_sun_sensor_dropout_and_stray_light():
    _, p, fs = _params('{kind="sun_sensor_blind", duration_s=5}')
    fine, trk, _, star = _sense(p, fs, 1.0)
    assert list(fine) == [0.0, 0.0, 0.0] and trk[2] == 1.0 and star == 3
    assert _sense(p, fs, 5.0)[0][2] == 1.0  # over after its duration
    _, p, fs = _params('{kind="tracker_dropout"}')
    fine, trk, _, star = _sense(p, fs, 1.0)
    assert list(trk) == [0.0, 0.0, 0.0] and star == -1 and fine[2] == 1.0
    _, p, fs = _params('{kind="tracker_stray_light", offset_deg=1.5}')
    _, trk, _, star = _sense(p, fs, 1.0)
    assert list(trk) == [1.5 * DEG2ARCSEC, 0.0, 1.0] and star == FALSE_TARGET  # a glint


def _tracker_frame(p, fs, t, lock, star=0):
    """``fault_sense`` after a tracker that found ``star``, then the bright gate: (trk, star).

    The slit holds that star alone: its light is the stars' the tracker counts.
    """
    tp = p.faults.tracker
    out = np.array([7.0, 8.0, 1.0]) if star >= 0 else np.zeros(3)
    lock[trk.SLIT_FLUX] = 10.0 ** (-0.4 * tp.magnitudes[star]) if star >= 0 else 0.0
    star = sf.fault_sense(p.faults, tp, fs, _frame(p, t), 0.01, np.zeros(3),
                          np.array([5.0, 6.0, 1.0]), out, np.zeros(3), lock, star, True)
    if tp.bright_gate_mag > -np.inf:
        star = trk.bright_gate(tp, lock, star, out)
    return out, star


def test_the_bright_gate_drops_the_lock_while_the_slit_is_too_bright():
    """Mariner 4's window, Canopus (-0.62 mag) +-2.26 mag: the gate at -2.88 mag. Canopus
    with a -4 mag glint beside it: fluxes add, 10^(0.4*0.62) + 10^(0.4*4) = 41.6 times a
    magnitude-0 star, -4.05 mag: brighter than the gate, the lock is lost, once journaled.
    A -2 mag glint: -2.27 mag together, fainter than the gate: Canopus is kept."""
    extra = ("star_tracker.magnitude_window=[-2.88, 1.64]", "star_tracker.bright_gate=true")
    cfg, p, fs = _params('{kind="tracker_stray_light", offset_deg=1.0, magnitude=-4.0, '
                         'start_s=1, duration_s=2}', extra=extra)
    k = tracker_star_names(cfg).index("Canopus")
    mag = p.faults.tracker.magnitudes[k]
    assert mag == pytest.approx(-0.62, abs=0.005)
    assert p.faults.tracker.bright_gate_mag == -2.88
    lock = new_lock()
    lock[trk.HELD] = k
    out, star = _tracker_frame(p, fs, 0.5, lock, k)  # before the glint
    assert star == k and out[2] == 1.0 and lock[trk.GATE] == 0.0
    seen = -2.5 * math.log10(10 ** (-0.4 * mag) + 10 ** (-0.4 * -4.0))
    assert seen == pytest.approx(-4.05, abs=0.01)
    out, star = _tracker_frame(p, fs, 1.0, lock, k)
    assert star == -1 and list(out) == [0.0, 0.0, 0.0] and lock[trk.HELD] == trk.NONE
    assert lock[trk.NEW_DROP] == k and lock[trk.SEEN_MAG] == pytest.approx(seen, abs=1e-9)
    lock[trk.NEW_DROP] = trk.NONE  # the next frame's tracker clears its flags ...
    out, star = _tracker_frame(p, fs, 1.5, lock, k)  # ... and finds Canopus again: dropped
    assert star == -1 and lock[trk.NEW_DROP] == trk.NONE  # one drop, told once
    out, star = _tracker_frame(p, fs, 3.0, lock, k)  # the glint is over
    assert star == k and out[2] == 1.0 and lock[trk.GATE] == 0.0
    _, p2, fs2 = _params('{kind="tracker_stray_light", offset_deg=1.0, magnitude=-2.0}',
                         extra=extra)
    assert -2.5 * math.log10(10 ** (-0.4 * mag) + 10 ** 0.8) == pytest.approx(-2.27, abs=0.01)
    lock = new_lock()
    lock[trk.HELD] = k
    _, star = _tracker_frame(p2, fs2, 1.0, lock, k)
    assert star == k and lock[trk.GATE] == 0.0  # held: the glint only adds light
    _, p3, fs3 = _params('{kind="tracker_stray_light", offset_deg=1.0, magnitude=-4.0}',
                         extra=extra[:1])
    _, star = _tracker_frame(p3, fs3, 1.0, lock, k)
    assert star == k  # no gate: the memory holds Canopus


def test_a_glint_with_a_brightness_is_locked_only_by_an_empty_tracker_inside_the_window():
    extra = ("star_tracker.magnitude_window=[-2.88, 1.64]",)
    _, p, fs = _params('{kind="tracker_stray_light", offset_deg=1.5, magnitude=0.5}',
                       extra=extra)
    lock = new_lock()
    out, star = _tracker_frame(p, fs, 0.0, lock, -1)  # nothing held: the glint is taken
    assert star == FALSE_TARGET and list(out) == [1.5 * DEG2ARCSEC, 0.0, 1.0]
    assert lock[trk.HELD] == FALSE_TARGET
    lock = new_lock()
    lock[trk.HELD] = 3
    out, star = _tracker_frame(p, fs, 0.0, lock, 3)  # a star held: kept
    assert star == 3 and list(out) == [7.0, 8.0, 1.0]
    _, p, fs = _params('{kind="tracker_stray_light", offset_deg=1.5, magnitude=3.0}',
                       extra=extra)
    _, star = _tracker_frame(p, fs, 0.0, new_lock(), -1)
    assert star == -1  # too faint for the window
    _, p, fs = _params('{kind="tracker_stray_light", offset_deg=1.5}', extra=extra)
    lock = new_lock()
    _, star = _tracker_frame(p, fs, 0.0, lock, 3)
    assert star == FALSE_TARGET and lock[trk.HELD] == FALSE_TARGET  # no brightness: taken
    sf.fault_release(p.faults, fs, 0.0, lock)
    assert lock[trk.HELD] == FALSE_TARGET  # the glint acts: held
    _, p, fs = _params('{kind="tracker_stray_light", offset_deg=1.5, duration_s=1}',
                       extra=extra)
    sf.fault_release(p.faults, fs, _frame(p, 2.0), lock)
    assert lock[trk.HELD] == trk.NONE  # over: forgotten, the tracker searches again


def test_a_wrong_star_joins_the_window_and_is_locked_on_boresight():
    # On this date Rigil Kentaurus is inside the slit's cone about the Sun (voyager1-wrong-star).
    cfg, p, fs = _params('{kind="wrong_star", star="Rigil Kentaurus", start_s=10}',
                         extra=("mission.date_utc=2026-09-01T00:00:00Z",))
    names = [s.name for s in sky.stars_in_magnitude_window(*cfg.star_tracker.magnitude_window,
                                                             cfg.mission.date_utc)]
    assert "Rigil Kentaurus" not in names
    before = sf.fault_tracker(p.faults, p.tracker, fs, _frame(p, 0.0))
    assert before.stars_inertial.shape[0] == len(names)
    extended = sf.fault_tracker(p.faults, p.tracker, fs, _frame(p, 10.0))
    k = extended.stars_inertial.shape[0] - 1
    assert k == len(names)
    # An attitude with the wrong star on the tracker's boresight (+z).
    w = sky.star_direction_inertial("Rigil Kentaurus", cfg.mission.date_utc)
    x = np.cross([0.0, 0.0, 1.0], w)
    x /= np.linalg.norm(x)
    q = quaternion.from_dcm(np.array([x, np.cross(w, x), w]))  # rows: body axes, inertial
    out = np.zeros(3)
    assert star_tracker(extended, q, new_lock(), out, np.ones(1, dtype=np.uint64)) == k
    assert star_tracker(p.tracker, q, new_lock(), out, np.ones(1, dtype=np.uint64)) != k


@pytest.mark.parametrize("reg, bit, start, expect", [
    ("14", 12, 5, 5 ^ (1 << 12)), ("14", 27, 3, 3 - (1 << 27)), ("16", 0, -1, -2),
    ("13", 15, 0, -(1 << 15)), ("27", 3, 100, 100 ^ 8)])
def test_an_upset_flips_exactly_that_bit_once(reg, bit, start, expect):
    _, p, fs = _params(f'{{kind="counter_upset", register="{reg}", bit={bit}, start_s=2}}')
    words = [np.zeros(3, dtype=np.int64) for _ in range(3)]  # drift, up/down, registers
    index = sf.WORD_INDEX[reg]
    words[index // 3][index % 3] = start
    sf.fault_upset(p.faults, fs, _frame(p, 1.0), *words)
    assert words[index // 3][index % 3] == start
    sf.fault_upset(p.faults, fs, _frame(p, 2.0), *words)
    sf.fault_upset(p.faults, fs, _frame(p, 3.0), *words)  # once only
    assert words[index // 3][index % 3] == expect
    flat = np.concatenate(words)
    assert np.count_nonzero(flat) == (1 if expect else 0)


def _actuate(p, fs, valve, kg=1.0, feed=1.0):
    """``fault_actuate`` after what jets 39-41 did for ``valve``: (ok, torque, gas used)."""
    torque = np.array([v * p.jets.torque_n_m[i] * feed for i, v in enumerate(valve)])
    tank = np.array([kg - feed * sum(abs(v) * f * 0.01
                                     for v, f in zip(valve, p.jets.flow_kg_s))])
    ok = sf.fault_actuate(p.faults, fs, 0, p.jets, 0.01, np.array(valve, dtype=np.int64),
                          tank, torque, True, feed)
    return ok, torque, kg - tank[0]


def test_a_stuck_open_couple_gives_its_torque_and_uses_its_gas():
    _, p, fs = _params('{kind="jet_stuck_open", axis="yaw", sign=-1}')  # jets = 2
    t_yaw, flow = p.jets.torque_n_m[2], p.jets.flow_kg_s[2] * 0.01
    ok, torque, used = _actuate(p, fs, [0, 0, 0])
    assert ok and torque[2] == -t_yaw and used == pytest.approx(flow)
    _, torque, used = _actuate(p, fs, [0, 0, 1])  # the opposite couple: the torques cancel
    assert torque[2] == 0.0 and used == pytest.approx(2 * flow)
    _, torque, used = _actuate(p, fs, [0, 0, -1])  # already firing that way
    assert torque[2] == -t_yaw and used == pytest.approx(flow)
    _, p2, fs2 = _params('{kind="jet_stuck_open", axis="yaw", sign=-1, jets=2}')
    assert _actuate(p2, fs2, [0, 0, 0])[1][2] == -t_yaw  # the default, said


def test_one_stuck_jet_gives_half_the_couple_and_the_opposite_couple_still_brakes():
    """One jet of thrust F at arm r: F r, half the couple's 2 F r, and F / (Isp g0), half
    its flow. Commanded the other way, the couple's -2 F r and the stuck jet's +F r leave
    -F r: it still brakes, at half the torque, using one and a half couples' gas."""
    _, p, fs = _params('{kind="jet_stuck_open", axis="roll", sign=1, jets=1}')
    f_r = 0.25 * 0.5  # default roll jet: 0.25 N at 0.5 m
    flow = 0.25 / (65.0 * 9.80665) * 0.01  # one jet, one frame
    _, torque, used = _actuate(p, fs, [0, 0, 0])
    assert torque[0] == pytest.approx(f_r, rel=1e-12) and used == pytest.approx(flow, rel=1e-9)
    _, torque, used = _actuate(p, fs, [-1, 0, 0])
    assert torque[0] == pytest.approx(-f_r, rel=1e-12)
    assert used == pytest.approx(3 * flow, rel=1e-9)
    _, torque, used = _actuate(p, fs, [1, 0, 0])  # the stuck jet is one of the couple firing
    assert torque[0] == pytest.approx(2 * f_r, rel=1e-12)
    assert used == pytest.approx(2 * flow, rel=1e-9)
    _, torque, used = _actuate(p, fs, [0, 0, 0], feed=0.5)  # a blow-down tank at half pressure
    assert torque[0] == pytest.approx(0.5 * f_r, rel=1e-12)
    assert used == pytest.approx(0.5 * flow, rel=1e-9)


def test_a_failed_jet_gives_nothing_when_commanded():
    _, p, fs = _params('{kind="jet_failed_off", axis="roll", sign=1}')
    _, torque, used = _actuate(p, fs, [1, 0, 0])
    assert torque[0] == 0.0 and used == pytest.approx(0.0, abs=1e-15)
    _, torque, _ = _actuate(p, fs, [-1, 0, 0])
    assert torque[0] == -p.jets.torque_n_m[0]


def test_a_leak_drains_the_tank_until_it_is_dry():
    _, p, fs = _params('{kind="propellant_leak", rate_kg_s=0.5, torque_n_m=[0, 0, 0]}')
    ok, torque, used = _actuate(p, fs, [0, 0, 0])
    assert ok and used == pytest.approx(0.005) and list(torque) == [0.0, 0.0, 0.0]
    ok, _, _ = _actuate(p, fs, [0, 0, 0], kg=0.004)
    assert not ok


def test_a_leak_with_a_torque_turns_the_vehicle_as_euler_says():
    """A leak of 1 g/s with a torque [0, 0.002, 0] N m on a body at rest, with principal
    axes along the body axes (no product of inertia): about pitch alone, Euler's equation
    is I_yy dw/dt = tau, so w(50 s) = 0.002 * 50 / 650 rad/s; the tank loses 0.05 kg. The
    leak's stage feeds the plant of the frame loop, frame by frame, nothing else acting."""
    from allsky.sim.frame_loop import advance_vehicle

    cfg, p, fs = _params('{kind="propellant_leak", rate_kg_s=0.001, torque_n_m=[0, 0.002, 0]}',
                         extra=("vehicle.inertia_kg_m2=[[100,0,0],[0,650,0],[0,0,680]]",))
    assert cfg.faults[0]["torque_n_m"] == (0.0, 0.002, 0.0)
    x = np.array([1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    tank = np.array([1.0])
    frame = np.zeros(1, dtype=np.int64)
    for _ in range(5000):
        torque = np.zeros(3)
        assert sf.fault_actuate(p.faults, fs, frame[0], p.jets, 0.01,
                                np.zeros(3, dtype=np.int64), tank, torque, True, 1.0)
        advance_vehicle(p.plant, None, 0, 0.01, torque, None, None, None, None, None, x,
                        np.zeros(3), frame)
    assert x[5] == pytest.approx(0.002 * 50.0 / 650.0, rel=1e-9)
    assert x[4] == x[6] == 0.0
    # The pitch angle turned: w t / 2 over the 50 s (a quaternion's half angle, small).
    assert 2.0 * x[2] == pytest.approx(0.5 * 0.002 / 650.0 * 50.0 ** 2, rel=1e-6)
    assert tank[0] == pytest.approx(1.0 - 0.001 * 50.0, abs=1e-12)


def test_a_leak_without_its_torque_thrusts_from_its_vent_at_the_exhaust_speed():
    """5 g/s from a vent at 1.25 m along +z, the gas leaving along (1, 1, 0)/sqrt 2: the
    vehicle feels F = -rate Isp g0 d at r, the torque r x F: with Isp 65 s, |F| = 3.187 N
    (5e-3 * 65 * 9.80665) and r x F = 1.25 |F| / sqrt 2 (+1, -1, 0) = (2.82, -2.82, 0) N m."""
    cfg, p, fs = _params('{kind="propellant_leak", rate_kg_s=0.005, vent_position_m=[0, 0, '
                         '1.25], vent_direction=[1, 1, 0]}')
    force = 0.005 * cfg.jets.isp_s * 9.80665
    assert force == pytest.approx(3.187, abs=1e-3)
    ok, torque, used = _actuate(p, fs, [0, 0, 0])
    k = 1.25 * force / math.sqrt(2.0)
    np.testing.assert_allclose(torque, [k, -k, 0.0], rtol=1e-12, atol=1e-15)
    assert ok and used == pytest.approx(0.005 * 0.01, rel=1e-12)
    with pytest.raises(ConfigError) as e:  # a leak must say how its gas turns the vehicle
        _cfg('{kind="propellant_leak", rate_kg_s=0.005}')
    assert "vent_position_m" in str(e.value) and e.value.key == "faults[0].torque_n_m"


def _blowdown_leak(rate, kg, torque="[0, 0.01, 0]"):
    return _params(f'{{kind="propellant_leak", rate_kg_s={rate}, torque_n_m={torque}}}',
                   extra=('jets.supply="blowdown"', f"jets.propellant_kg={kg}",
                          "jets.tank_pressure_initial_bar=20.0",
                          "jets.tank_pressure_final_bar=5.0"))


def test_a_blowdown_leak_falls_with_the_tank_pressure_as_the_closed_form_says():
    """On a blow-down feed the leak's flow is its rate times p/p0 = f + (1 - f) m/M at each
    frame's start (f = 5/20): per frame m' + c = (m + c)(1 - (1 - f) r dt / M) with c =
    f M/(1 - f), so m_k = (M + c) a^k - c exactly, a geometric decay; the torque follows
    p/p0 too. 10 g/s from a 1 kg tank over 60 s: the closed form, not 0.4 kg."""
    from allsky.hardware.jets import thrust_fraction

    rate, kg, frames, dt = 0.01, 1.0, 6000, 0.01
    _, p, fs = _blowdown_leak(rate, kg)
    tank = np.array([kg])
    for k in range(frames):
        feed = thrust_fraction(p.jets, tank[0])
        torque = np.zeros(3)
        assert sf.fault_actuate(p.faults, fs, k, p.jets, dt, np.zeros(3, dtype=np.int64),
                                tank, torque, True, feed)
        assert torque[1] == pytest.approx(0.01 * feed, rel=1e-15)
    f = 0.25
    c = f * kg / (1.0 - f)
    a = 1.0 - (1.0 - f) * rate * dt / kg
    assert tank[0] == pytest.approx((kg + c) * a**frames - c, rel=1e-12)
    # Continuous limit: m(t) = (M + c) exp(-(1 - f) r t / M) - c, within the Euler error.
    assert tank[0] == pytest.approx((kg + c) * math.exp(-(1 - f) * rate * 60.0 / kg) - c,
                                    rel=1e-4)
    assert tank[0] > kg - rate * 60.0 + 0.05  # the regulated drain would leave 0.4 kg


# -- outcomes -----------------------------------------------------------------------

def _fly(*faults, extra=()):
    m = Mission(_cfg(*faults, extra=extra), telemetry=False)
    return m, m.run()


def test_complete_with_degraded_figures():
    _, s = _fly('{kind="gyro_bias_step", axis="yaw", size_deg_h=20, start_mode="6-1"}')
    assert s["status"] == "complete" and s["target"]["pointing_error_arcsec"] > 1000
    assert s["faults"][0]["onset_s"] == s["modes"][5]["start_s"]  # the start of Mode 6-1


@pytest.mark.parametrize("fault, words", [
    ('{kind="tracker_dropout", start_s=640, duration_s=60}',
     ("Mode 5:", "star lost", "(tracker dropout at 640.0 s)")),
    ('{kind="sun_sensor_blind", start_mode="3"}', ("Mode 3:", "Sun lost", "sun sensor blind")),
    ('{kind="propellant_leak", rate_kg_s=0.01, torque_n_m=[0, 0, 0]}',
     ("propellant exhausted", "propellant leak")),
    ('{kind="gyro_dead", axis="yaw", start_mode="6-2"}',
     ("Mode 6-2:", "mode timeout", "yaw gyro dead")),
    ('{kind="jet_stuck_open", axis="roll", sign=1, start_mode="4"}',
     ("Mode 4:", "+roll jet couple stuck open")),
])
def test_aborts_name_mode_symptom_and_fault(fault, words):
    m, s = _fly(fault)
    assert s["status"] == "aborted"
    for w in words:
        assert w in s["abort_reason"], s["abort_reason"]
    assert sf.symptom(s["abort_reason"]) in s["abort_reason"]
    assert "(" not in sf.symptom(s["abort_reason"])
    # Bounded: no mode outlives its timeout.
    for r in m.timeline:
        assert r.end_s - r.start_s <= m.mode_timeout_s(r.mode) + 1.0


def test_a_wrong_star_met_first_points_where_its_geometry_says():
    """On the default date Avior crosses the slit 5.83 deg of roll before Canopus: Mode 2
    locks it, the tracker holds it, and Mode 4's roll, leaving it, meets Canopus, loses it
    and meets Avior again after 360 deg: the calibration is right, the reference is not.

    The programmed angles are Canopus's, so the vehicle points the target's direction
    turned about the Sun by the two stars' azimuth difference dphi:
    2 asin(sin(dphi/2) sin(theta)), theta the Sun-target angle.
    """
    m, s = _fly('{kind="wrong_star", star="Avior"}')
    assert s["status"] == "complete" and s["locked_star"] == "Avior"
    assert s["reference_star"] == "Canopus"
    locks = [e["star"] for e in s["events"] if e["kind"] == "star_lock"]
    assert locks[:4] == ["Avior", "Canopus", None, "Avior"]  # Mode 2, then Mode 4's roll
    assert m.counted_arcsec["roll"][0] == pytest.approx(360.0 * 3600.0, rel=3e-3)
    cfg, d = m.cfg, m.cfg.mission.date_utc
    sun = m.params.sun0_inertial + m.params.sun_rate_inertial * m.timeline[5].start_s
    sun /= np.linalg.norm(sun)
    dphi = math.radians(sun_azimuth_deg(sun, sky.star_direction_inertial("Avior", d),
                                         sky.star_direction_inertial("Canopus", d)))
    assert abs(math.degrees(dphi)) == pytest.approx(5.83, abs=0.01)
    theta = math.acos(sun @ sky.star_direction_inertial(cfg.target.star, d))
    predicted = 2 * math.asin(abs(math.sin(dphi / 2)) * math.sin(theta)) / ARCSEC2RAD
    assert predicted > 15000
    assert s["target"]["pointing_error_arcsec"] == pytest.approx(predicted, abs=50)


def test_a_wrong_star_met_after_canopus_ends_the_calibration_roll():
    """On 2026-06-04 Canopus is met first and locked; Avior lies 9.46 deg of roll on. The
    tracker holds Canopus as Mode 4's roll starts, loses it past the slit's edge and
    takes Avior, in the slit by then: the roll ends after 9.46 deg, which calibration
    sequencer 19 takes for 360 deg, and Mode 6-1's roll loop, 38 times too stiff, never
    settles. (The nearest-star rule this tracker had before let Canopus win back the
    slit and rescued the calibration; a slit tracker does not.)"""
    m, s = _fly('{kind="wrong_star", star="Avior"}',
                extra=["mission.date_utc=2026-06-04T00:00:00Z"])
    assert s["status"] == "aborted" and s["abort_reason"].startswith("Mode 6-1:")
    locks = [e["star"] for e in s["events"] if e["kind"] == "star_lock"]
    assert locks[:2] == ["Canopus", "Avior"]
    d = m.cfg.mission.date_utc
    sun = sky.sun_direction_inertial(d)
    dphi = sun_azimuth_deg(sun, sky.star_direction_inertial("Avior", d),
                            sky.star_direction_inertial("Canopus", d))
    assert abs(dphi) == pytest.approx(9.46, abs=0.01)
    # Counter 14 holds the roll from Canopus to Avior, as the roll gyro (+1500 ppm) reads it.
    assert m.counted_arcsec["roll"][0] == pytest.approx(abs(dphi) * 3600.0 * 1.0015, abs=60.0)


def test_the_cone_angle_check_refuses_the_wrong_star_and_the_mission_flies_as_without_it():
    """Avior's cone angle (+6.8 deg) is 16.8 deg from Canopus's (-9.95): with a 2 deg check
    Mode 2 and Mode 4 refuse it (journaled) and lock Canopus; the flight is the fault-free
    one's, frame for frame after the refusals (the refusal draws no noise)."""
    check = "star_tracker.cone_angle_check_deg=2"
    _, s = _fly('{kind="wrong_star", star="Avior"}', extra=[check])
    clean = Mission(load_scenario(overrides=[check]), telemetry=False).run()
    assert s["status"] == "complete" and s["locked_star"] == "Canopus"
    assert s["target"]["pointing_error_arcsec"] == clean["target"]["pointing_error_arcsec"]
    refused = [e for e in s["events"] if e["kind"] == "lock_rejected"]
    assert [(e["mode"], e["star"]) for e in refused] == [("2", "Avior"), ("4", "Avior")]
    assert refused[0]["cone_angle_deg"] == pytest.approx(6.83, abs=0.01)
    assert refused[0]["reference_cone_angle_deg"] == pytest.approx(-9.95, abs=0.01)
    assert refused[0]["check_deg"] == 2.0


# -- the matrix, the dispersion, the packaged scenarios -----------------------------

def test_the_matrix_has_no_errors():
    r = fault_matrix(load_scenario(), kinds=list(KINDS), modes=["5"], workers=1)
    assert r["reference"]["status"] == "complete"
    assert len(r["cases"]) == len(KINDS)
    assert r["counts"]["status"].get("error", 0) == 0
    assert {c["status"] for c in r["cases"]} <= {"complete", "aborted"}


def test_faults_are_dispersed_with_a_probability_and_an_onset():
    base = ['faults=[{kind="tracker_dropout", start_mode="4", duration_s=60}]']
    never = load_scenario(overrides=[*base, ('dispersions.faults.1={dist="fault", '
                                             'probability=0}')])
    assert disp.disperse(never, 5)[0].faults == ()
    cfg = load_scenario(overrides=[*base, ('dispersions.faults.1={dist="fault", '
                                          'probability=0.5, low=100, high=200}')])
    kept = []
    for seed in range(40):
        run, drawn = disp.disperse(cfg, seed)
        assert drawn["faults.1"]["present"] == float(bool(run.faults))
        if run.faults:
            assert 100 <= run.faults[0]["start_s"] <= 200 and "start_mode" not in run.faults[0]
            kept.append(seed)
    assert 8 < len(kept) < 32
    assert disp.input_columns(cfg) == ["faults.1.present", "faults.1.start_s"]
    with pytest.raises(ConfigError) as e:
        load_scenario(overrides=[*base, 'dispersions.faults.2={dist="fault", probability=1}'])
    assert e.value.key == "dispersions.faults.2"


def test_packaged_scenarios_are_listed_and_run_by_name(capsys):
    names = {e["name"] for e in packaged_scenarios()}
    assert {"voyager1-wrong-star", "mariner4-star-hopping", "mariner4-dust-glints",
            "stuck-jet-roll-calibration", "gyro-failure-to-target"} <= names
    for name in names:
        load_scenario(name)
    assert main(["scenarios"]) == 0
    assert "mariner4-star-hopping" in capsys.readouterr().out


def test_the_matrix_table_keeps_its_columns_apart():
    from allsky.apps.faults import format_matrix

    row = {"status": "aborted", "outcome": "x", "abort_reason": "x"}
    modes = ["hold", "dither", "6-2"]
    result = {"modes": modes, "kinds": ["gyro_dead"], "faults": {"gyro_dead": "roll gyro dead"},
              "reference": {"status": "complete", "pointing_error_arcsec": 8.7},
              "cases": [{**row, "kind": "gyro_dead", "mode": m} for m in modes],
              "counts": {"status": {"aborted": 3}}}
    text = format_matrix(result)
    assert "Mode hold  Mode dither  Mode 6-2" in text
    assert "3 missions" in text and "Fault-free reference: complete" in text
    one = {**result, "modes": ["hold"], "cases": result["cases"][:1],
           "scenario_faults": ["tracker dropout"]}
    text = format_matrix(one)
    assert "1 mission," in text
    assert "Reference (the scenario's own faults: tracker dropout): complete" in text


@pytest.mark.parametrize("argv, kinds, modes, scenario", [
    (["--kinds", "gyro_dead,tracker_dropout", "--modes", "4,5"],
     ["gyro_dead", "tracker_dropout"], ["4", "5"], None),
    (["--kinds", "gyro_dead", "tracker_dropout", "--modes", "4", "5"],
     ["gyro_dead", "tracker_dropout"], ["4", "5"], None),
    (["--kinds", "gyro_dead", "my.toml"], ["gyro_dead"], None, "my.toml"),
    (["--modes", "6-2", "mariner4-star-hopping"], None, ["6-2"], "mariner4-star-hopping"),
    (["my.toml", "--kinds", "gyro_dead,gyro_stuck"], ["gyro_dead", "gyro_stuck"], None,
     "my.toml"),
])
def test_kinds_and_modes_take_comma_lists_and_words(argv, kinds, modes, scenario):
    from allsky.apps.cli import _parser

    args = _parser().parse_args(["faults", *argv])
    assert (args.kinds, args.modes, args.scenario) == (kinds, modes, scenario)


@pytest.mark.parametrize("mode", ["hold", "dither"])
def test_the_matrix_refuses_a_mode_the_mission_never_flies(mode, capsys):
    assert main(["faults", "--kinds", "gyro_dead", "--modes", mode, "--quiet"]) == 2
    assert "--modes" in capsys.readouterr().err


def test_the_faults_command_prints_the_matrix(tmp_path, capsys):
    out = tmp_path / "m.json"
    assert main(["faults", "--kinds", "gyro_dead", "--modes", "6-2", "--workers", "1",
                 "--json", str(out), "--quiet"]) == 0
    text = capsys.readouterr().out
    assert "gyro_dead" in text and "Mode 6-2" in text and out.exists()


def test_the_campaign_table_gives_the_outcome_probabilities(tmp_path, capsys):
    from allsky.apps.campaign import format_summary
    from allsky.studies.montecarlo import summarize

    lost = "Mode 4: star lost while waiting for: settled on Sun and star"
    rows = [{"status": "complete", "abort_reason": None},
            {"status": "aborted", "abort_reason": f"{lost} (tracker dropout at 512.0 s)"},
            {"status": "aborted", "abort_reason": f"{lost} (tracker dropout at 530.5 s)"},
            {"status": "complete", "abort_reason": None}]
    s = summarize(rows)
    text = format_summary(s, outcomes=True)
    assert "Outcomes (runs, probability, outcome)" in text
    assert "      2   50.0%  complete" in text and f"      2   50.0%  {lost}\n" in text + "\n"
    assert "512.0" not in text  # one outcome, whatever the onsets
    assert "512.0" in format_summary(s)  # without: the reasons, one by one
    p = tmp_path / "f.toml"
    p.write_text('[[faults]]\nkind = "tracker_dropout"\nstart_s = 600.0\nduration_s = 60.0\n')
    assert main(["montecarlo", str(p), "--runs", "1", "--workers", "1", "--quiet"]) == 0
    assert "100.0%  Mode 4: star lost" in capsys.readouterr().out


def test_saved_states_keep_the_faults_and_older_files_load(tmp_path):
    """A state saved mid-flight resumes its faults bit for bit; a file from before the
    faults (no fault_state, no wheels) loads as a mission without faults."""
    import json
    import zipfile

    from allsky.apps import states

    fault = ('faults=[{kind="gyro_bias_step", axis="yaw", size_deg_h=2, start_s=10}, '
             '{kind="gyro_dead", axis="roll", start_mode="6-2"}]')
    m = Mission(load_scenario(overrides=[fault]), telemetry=False)
    m.run_mode()
    m.run_mode()
    path = tmp_path / "after2.npz"
    states.save(m, path)
    resumed = states.load(path, telemetry=False)
    assert np.all(np.isfinite(resumed.state.fault_state))
    assert list(resumed.state.fault_state[sf.ONSET, :2]) == [1000.0, sf.UNKNOWN]
    assert resumed.run() == m.run()
    plain = Mission(load_scenario(), telemetry=False)
    plain.run_mode()
    states.save(plain, path)
    older = tmp_path / "older.npz"
    with zipfile.ZipFile(path) as src, zipfile.ZipFile(older, "w") as dst:
        for item in src.infolist():
            if "fault_state" not in item.filename and "wheel" not in item.filename:
                dst.writestr(item, src.read(item))
    again = states.load(older, telemetry=False)
    assert np.array_equal(again.state.fault_state, sf.new_fault_state())
    bad = tmp_path / "bad.npz"
    history, arrays = plain.snapshot()
    arrays["fault_state"][sf.ONSET, 0] = -5.0
    np.savez(bad, history=np.array(json.dumps(history)),
             **{states.ARRAY_PREFIX + k: v for k, v in arrays.items()})
    with pytest.raises(states.StateError, match="fault_state"):
        states.load(bad)
