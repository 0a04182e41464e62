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
    m = SimpleNamespace(pulse_weight_arcsec=0.1, state=SimpleNamespace(counters=counters))
    for turns, frac in ((1, 1.0005), (2, 1.999), (1, 0.2), (3, -3.01)):
        counters[0] = counters[2] = round(frac * FULL_TURN_ARCSEC / 0.1)
        assert ms.turns_counted(m, "roll") == ms.turns_counted(m, "yaw") == turns
