"""The sequencer's recoveries (``sequencer.recovery``): a failed leg retried once."""

import numpy as np
import pytest

from allsky.apps.cli import main
from allsky.computer.calibration_sequencer import FULL_TURN_ARCSEC
from allsky.config import load_scenario
from allsky.sequencer import master_sequencer as ms
from allsky.sequencer import modes
from allsky.sim import faults as sf
from allsky.sim.mission import Mission

ON = "sequencer.recovery=true"
#: The tracker blind for a minute from 600 s: Mode 4's roll has just met the star again
#: (at about 585 s) and the loop is settling on it.
DROPOUT_WHILE_SETTLING = 'faults=[{kind="tracker_dropout", start_s=600, duration_s=60}]'
#: The tracker blind for a minute from 560 s: the star crosses the slit unseen at the end
#: of Mode 4's 360 deg roll.
DROPOUT_AT_THE_CROSSING = 'faults=[{kind="tracker_dropout", start_s=560, duration_s=60}]'
#: Fault-free figures of the default scenario, for the recovered missions to match [arcsec].
POINTING_ARCSEC = 20.0


def _fly(*overrides, telemetry=False):
    m = Mission(load_scenario(overrides=list(overrides)), telemetry=telemetry)
    return m, m.run()


def test_recovery_is_off_by_default_and_checked(capsys):
    assert load_scenario().sequencer.recovery is False
    assert main(["config", "check", "--set", "sequencer.recovery=2"]) == 2
    assert "sequencer.recovery" in capsys.readouterr().err


def test_every_recovery_of_the_table_is_a_valid_rule():
    used = {key for mode in modes.MODE_TABLE for step in mode.steps
            for key in getattr(step, "retry", ())}
    assert used == set(modes.RETRIES)
    bad = modes.Mode("x", 99.0, "x", (
        modes.Wait("w", "none", "settle", ("sun yaw",), retry=("nowhere",)),), "x")
    with pytest.raises(ValueError, match="unknown recovery"):
        modes.check((bad,))


def test_a_fault_free_mission_is_bit_identical_with_recovery_on():
    off, s_off = _fly(telemetry=True)
    on, s_on = _fly(ON, telemetry=True)
    assert s_on == s_off
    assert np.array_equal(on.telemetry(), off.telemetry())


def test_a_fault_no_recovery_answers_flies_the_same_with_recovery_on():
    fault = 'faults=[{kind="gyro_bias_step", axis="yaw", size_deg_h=5, start_mode="6-1"}]'
    assert _fly(fault)[1] == _fly(fault, ON)[1]


def test_a_star_lost_after_the_calibration_roll_is_found_one_revolution_on():
    _, s = _fly(DROPOUT_WHILE_SETTLING)
    assert s["status"] == "aborted"
    assert s["abort_reason"] == ("Mode 4: star lost while waiting for: settled on Sun and star "
                                 "(tracker dropout at 600.0 s)")
    m, s = _fly(DROPOUT_WHILE_SETTLING, ON)
    assert s["status"] == "complete", s["abort_reason"]
    assert s["target"]["pointing_error_arcsec"] < POINTING_ARCSEC
    assert "recovered: roll on for one more revolution" in s["modes"][3]["exit"]
    # Counter 14 held two turns (as the gyro's 1500 ppm scale error reads them), and
    # calibration sequencer 19 took them as two.
    assert m.counted_arcsec["roll"][0] == pytest.approx(2 * FULL_TURN_ARCSEC, rel=2e-3)


def test_a_star_missed_at_the_end_of_the_roll_is_calibrated_as_two_turns():
    """Unseen as it crosses, the star is met a turn later; the patent's sequencer takes
    that for one turn and halves the roll scale factor, the recovering one counts two."""
    _, s = _fly(DROPOUT_AT_THE_CROSSING)
    assert s["status"] == "complete" and s["target"]["pointing_error_arcsec"] > 1e5
    _, s = _fly(DROPOUT_AT_THE_CROSSING, ON)
    assert s["status"] == "complete"
    assert s["target"]["pointing_error_arcsec"] < POINTING_ARCSEC


def test_a_sun_lost_in_mode_2_is_acquired_again():
    """The sun sensor blind for 30 s as Mode 2 starts: the Sun, just acquired by Mode 1 and
    switched in (S14/S15), is lost; the recovery flies Mode 1's leg again, then Mode 2."""
    blind = 'faults=[{kind="sun_sensor_blind", start_mode="2", duration_s=30}]'
    _, s = _fly(blind)
    assert s["status"] == "aborted" and s["abort_reason"].startswith("Mode 2: Sun lost")
    _, s = _fly(blind, ON)
    assert s["status"] == "complete", s["abort_reason"]
    assert s["target"]["pointing_error_arcsec"] < POINTING_ARCSEC
    assert "recovered: acquire the Sun again" in s["modes"][1]["exit"]


def test_mode_1_goes_on_acquiring_the_sun_past_its_timeout():
    short = "sequencer.timeout_s.1=100"
    _, s = _fly(short)
    assert s["abort_reason"] == ("Mode 1: sun acquired and settled not achieved within the "
                                 "mode timeout of 100 s")
    _, s = _fly(short, ON)
    assert s["status"] == "complete", s["abort_reason"]


@pytest.mark.parametrize("fault", [
    '{kind="tracker_dropout", start_mode="3", duration_s=60}',  # the star lost in a hold
    '{kind="tracker_stray_light", offset_deg=1.5, start_mode="2", duration_s=30}',
    '{kind="sun_sensor_blind", start_mode="4", duration_s=60}',
    '{kind="tracker_dropout", start_mode="5", duration_s=60}',
])
def test_transient_optical_faults_abort_without_recovery_and_complete_with_it(fault):
    _, s = _fly(f"faults=[{fault}]")
    assert s["status"] == "aborted"
    _, s = _fly(f"faults=[{fault}]", ON)
    assert s["status"] == "complete", s["abort_reason"]
    assert s["target"]["pointing_error_arcsec"] < POINTING_ARCSEC


def test_a_failed_recovery_aborts_naming_mode_symptom_fault_and_recovery():
    m, s = _fly('faults=[{kind="tracker_dropout", start_s=600}]', ON)  # permanent
    reason = s["abort_reason"]
    assert s["status"] == "aborted"
    assert reason.startswith("Mode 4: star re-acquired after one more roll not achieved "
                             "within the mode timeout of 840 s")
    assert "; recovery tried: roll on for one more revolution" in reason
    assert reason.endswith("(tracker dropout at 600.0 s)")
    assert "tracker dropout" not in sf.symptom(reason)
    # Bounded: the mode ran to its deadline moved on by one revolution, not beyond.
    mode4 = m.timeline[-1]
    assert mode4.end_s - mode4.start_s <= 600.0 + 240.0 + 0.1


def test_each_recovery_is_flown_once_per_flight_of_a_mode():
    calls, notes = [], []

    class Stub:
        def __init__(self):
            self.cfg = load_scenario(overrides=[ON])

        def leg(self, what, *args, **kwargs):
            calls.append(what)
            raise ms.ModeAbort(f"Mode 1: {what} not achieved", "timeout")

        def extend_mode(self, seconds):
            calls.append(seconds)

        def switch(self, close=(), open_=(), step="", waits_for=""):
            pass

        def note(self, kind, **fields):
            notes.append(kind)

    with pytest.raises(ms.ModeAbort) as e:
        ms.run_mode(Stub(), "1")
    assert calls == ["sun acquired and settled", 900.0, "sun acquired and settled"]
    assert str(e.value).endswith("; recovery tried: go on acquiring the Sun for one more "
                                 "Mode 1 timeout")
    assert e.value.failure == "timeout"
    assert notes == ["action"]  # the recovery, journaled by the sequencer


def test_whole_turns_counted_from_the_counter():
    from types import SimpleNamespace

    counters = np.zeros(3, dtype=np.int64)
    m = SimpleNamespace(pulse_weight_arcsec=0.1, view=SimpleNamespace(counters=counters))
    for turns, frac in ((1, 1.0005), (2, 1.999), (1, 0.2), (3, -3.01)):
        counters[0] = counters[2] = round(frac * FULL_TURN_ARCSEC / 0.1)
        assert ms.turns_counted(m, "roll") == ms.turns_counted(m, "yaw") == turns


# -- the turn check (sequencer.turn_check_ppm) -------------------------------------------

CHECK = "sequencer.turn_check_ppm=10000"
#: The Voyager-like scenario: Mode 4's roll re-acquires Rigil Kentaurus 58.5 deg on.
VOYAGER = "voyager1-wrong-star"


def _counted(deg, recovery=False, ppm=10000.0):
    """A stand-in mission whose counters 14 and 18 hold ``deg`` of turn."""
    from types import SimpleNamespace

    counters = np.zeros(3, dtype=np.int64)
    counters[0] = counters[2] = round(deg * 3600.0 / 0.1)
    cfg = SimpleNamespace(sequencer=SimpleNamespace(turn_check_ppm=ppm, recovery=recovery),
                          star_tracker=SimpleNamespace(fov_narrow_half_deg=8.0),
                          sun_sensor=SimpleNamespace(presence_half_angle_deg=30.0))
    return SimpleNamespace(pulse_weight_arcsec=0.1, view=SimpleNamespace(counters=counters),
                           cfg=cfg, current_mode="4")


@pytest.mark.parametrize("deg, scale_factor", [(58.5, 6.1538), (301.5, 1.1940)])
def test_the_turn_check_refuses_a_turn_that_is_not_a_turn(deg, scale_factor):
    """A re-acquisition after 58.5 deg (or 301.5 deg) is refused: (deg - 360) / 360 parts,
    -837500 (-162500) ppm. The patent's sequencer, taking it for 360 deg, would store a roll
    scale factor of 360 / deg: 6.15 (1.19)."""
    assert 360.0 / deg == pytest.approx(scale_factor, abs=1e-4)
    m = _counted(deg)
    with pytest.raises(ms.ModeAbort) as e:
        ms.check_turn(m, {}, "roll")
    assert e.value.failure == "turn refused"
    ppm = (deg - 360.0) / 360.0 * 1e6
    assert f"counter 14 holds {deg:.2f} deg" in str(e.value) and f"{ppm:+.0f} ppm" in str(e.value)
    assert str(e.value).startswith("Mode 4: the turn check refused the star re-acquired")


def test_the_turn_check_passes_whole_turns_and_counts_them_with_recovery():
    ms.check_turn(_counted(360.0 * 1.0015), {}, "roll")  # a 1500 ppm gyro: 1500 ppm off
    with pytest.raises(ms.ModeAbort):  # the patent's sequencer calibrates one turn only
        ms.check_turn(_counted(720.8), {}, "yaw")
    ms.check_turn(_counted(720.8, recovery=True), {}, "yaw")  # two turns, +1111 ppm
    assert ms.turn_verdict(_counted(720.8, recovery=True), "yaw")[0] == 2
    with pytest.raises(ms.ModeAbort):
        ms.check_turn(_counted(360.0 * 1.0015, ppm=1000.0), {}, "roll")  # tighter than the gyro


def test_the_turn_check_off_flies_the_patent_and_on_flies_a_good_turn_the_same():
    _, s_off = _fly()
    _, s_on = _fly(CHECK)
    assert s_on["target"] == s_off["target"] and s_on["modes"] == s_off["modes"]
    checks = [e for e in s_on["events"] if e["kind"] == "action" and e["action"] == "check_turn"]
    assert [e["mode"] for e in checks] == ["4", "5"]
    assert not [e for e in s_off["events"] if e.get("action") == "check_turn"]


def test_a_wrong_star_re_acquired_is_refused_and_with_recovery_rolled_past():
    """Voyager-like: the calibration roll stops on Rigil Kentaurus after 58.59 deg. Without
    the check calibration sequencer 19 stores a roll scale factor of 360/58.59 = 6.14 and
    Mode 6-1 aborts; with it Mode 4 aborts naming the count; with recovery too the roll
    goes on to Canopus, met again after 360 deg, and the mission points as a fault-free one."""
    m = Mission(load_scenario(VOYAGER), telemetry=False)
    s = m.run()
    assert s["status"] == "aborted" and s["abort_reason"].startswith("Mode 6-1:")
    counted = m.counted_arcsec["roll"][0] / 3600.0
    assert counted == pytest.approx(58.5 * 1.0015, abs=0.1)
    assert s["calibration"]["scale_factor"]["roll"] == pytest.approx(360.0 / counted, rel=1e-4)
    s = Mission(load_scenario(VOYAGER, overrides=[CHECK]), telemetry=False).run()
    assert s["status"] == "aborted"
    assert s["abort_reason"].startswith("Mode 4: the turn check refused the star re-acquired: "
                                        "counter 14 holds 58.59 deg")
    s = Mission(load_scenario(VOYAGER, overrides=[CHECK, ON]), telemetry=False).run()
    assert s["status"] == "complete", s["abort_reason"]
    assert "recovered: roll on past the refused star" in s["modes"][3]["exit"]
    assert s["locked_star"] == "Canopus"
    assert s["target"]["pointing_error_arcsec"] < POINTING_ARCSEC


#: The +roll couple stuck open as Mode 4 begins (both jets, 0.25 N m).
STUCK = 'faults=[{kind="jet_stuck_open", axis="roll", sign=1, start_mode="4"}]'


def test_recovery_does_not_roll_again_a_vehicle_that_cannot_brake():
    """The +roll couple stuck open: the star is lost settling. Recovery alone rolls once
    more, burns more gas (0.395 kg), and still aborts; with the turn check, counter 14 shows
    the vehicle rolled 16 deg past the turn, beyond the slit's 8 deg: no retry, and the
    flight is the patent sequencer's, frame for frame, with the reason added."""
    _, patent = _fly(STUCK)
    _, retried = _fly(STUCK, ON)
    _, checked = _fly(STUCK, ON, CHECK)
    assert patent["status"] == retried["status"] == checked["status"] == "aborted"
    assert "recovery tried: roll on for one more revolution" in retried["abort_reason"]
    assert retried["propellant_kg"] > patent["propellant_kg"] + 0.3
    assert checked["propellant_kg"] == patent["propellant_kg"]
    assert checked["mission_time_s"] == patent["mission_time_s"]
    assert "; no recovery: counter 14 holds 376.12 deg, +16.12 deg from one turn, beyond the 8 " \
           "deg in which the star stays in view" in checked["abort_reason"]


def test_recovery_with_the_turn_check_still_finds_a_star_that_vanished():
    """The star hidden while the loop settles on it: counter 14 is within the slit of a
    whole turn, so the star vanished: rolled on for, found, and the calibration is right."""
    _, s = _fly(DROPOUT_WHILE_SETTLING, ON, CHECK)
    assert s["status"] == "complete", s["abort_reason"]
    assert s["target"]["pointing_error_arcsec"] < POINTING_ARCSEC
    _, s = _fly(DROPOUT_AT_THE_CROSSING, CHECK)  # the patent's one turn: 720 deg refused
    assert s["status"] == "aborted" and "counter 14 holds 721." in s["abort_reason"]
    _, s = _fly(DROPOUT_AT_THE_CROSSING, ON, CHECK)  # with recovery: two turns
    assert s["status"] == "complete"
    assert s["target"]["pointing_error_arcsec"] < POINTING_ARCSEC

