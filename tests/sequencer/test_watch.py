"""Master sequencer 20's watch (allsky.sequencer.watch), frame by frame in a tiny harness.

Truth from the patent's mode table (SPEC section 4, numbers of section 6):
"settled" is every watched error below 50" continuously for 10 s, so one
frame at or above 50" starts the 10 s again; a hand-over happens inside
7200", and in Mode 4 (and the Mode 5 yaw) not before the 10 s tracker
blanking; a sensor whose outputs are switched into a control amplifier
(Sun: S14/S15, star: S12/S13) may not be absent for longer than the
scenario's ``sensor_loss_s`` (5 s).
"""

import numpy as np

from allsky import clock
from allsky.hardware.switch_bank import new_bank
from allsky.hardware.wiring import ROUTING
from allsky.sequencer import legs
from allsky.sequencer.watch import (
    ABSENT_ARCSEC,
    EXIT_NONE,
    sensors_in_use,
    watch,
    watched_signals,
)
from allsky.sim.state import SequencerParams

DT_S = 0.125  # a binary fraction
CLOCK = clock.clock(DT_S)
SQ = SequencerParams(settle_threshold_arcsec=50.0, handover_arcsec=7200.0,
                     sensor_loss_frames=clock.frames_within(CLOCK, 5.0))
SUN = np.array([10.0, -10.0, 1.0])  # sun sensor 104: pitch, yaw [arcsec], present
STAR = np.array([20.0, 5.0, 1.0])  # star tracker 105: yaw, pitch [arcsec], present
NO_ERRORS = np.zeros(6)  # CPU 22 working store: no computed errors


def leg(watch_kind=legs.WATCH_SETTLE, mask=legs.SETTLE_OPTICAL, signal=legs.SIG_TRACKER_YAW,
        blank_s=0.0, hold_s=10.0):
    """A leg, its times in seconds turned into frames as the mission driver turns them."""
    return legs.Leg(1, 2.0, legs.PROGRAM_NONE, watch_kind, mask, signal,
                    clock.frames_within(CLOCK, blank_s), clock.frames_for(CLOCK, hold_s),
                    clock.NEVER)


class Harness:
    """The watch over successive frames, its counts carried as the frame loop carries them."""

    def __init__(self, the_leg, closed=(14, 15)):
        self.leg = the_leg
        self.bank = new_bank()
        self.bank[list(closed)] = 1
        self.n = self.settled = self.sun_gone = self.star_gone = 0
        self.sig = np.zeros(legs.N_SIGNALS)

    @property
    def t_s(self):
        return clock.time_s(CLOCK, self.n)

    @property
    def settle_s(self):
        return clock.time_s(CLOCK, self.settled)

    @property
    def sun_gone_s(self):
        return clock.time_s(CLOCK, self.sun_gone)

    def frame(self, fine=SUN, trk=STAR, tank_ok=True, cpu=NO_ERRORS):
        self.n += 1
        sun_in_use, star_in_use = sensors_in_use(self.bank, ROUTING)
        code, self.settled, self.sun_gone, self.star_gone = watch(
            SQ, self.leg, sun_in_use, star_in_use, tank_ok, fine, trk, cpu, self.sig, self.n,
            self.settled, self.sun_gone, self.star_gone)
        return code

    def frames(self, n, **kw):
        """Run up to ``n`` frames; the exit code and the frames run."""
        for i in range(n):
            code = self.frame(**kw)
            if code != EXIT_NONE:
                return code, i + 1
        return EXIT_NONE, n


# -- settle --------------------------------------------------------------------------------

def test_settles_after_10_s_below_50_arcsec():
    h = Harness(leg())
    assert h.frames(1000) == (legs.EXIT_DONE, 80)  # 80 frames of 0.125 s = 10 s


def test_one_frame_at_50_arcsec_restarts_the_settle_timer():
    h = Harness(leg())
    assert h.frames(40) == (EXIT_NONE, 40)
    assert h.settle_s == 5.0
    assert h.frame(fine=np.array([50.0, 0.0, 1.0])) == EXIT_NONE
    assert h.settle_s == 0.0
    assert h.frames(1000) == (legs.EXIT_DONE, 80)


def test_only_the_signals_of_the_mask_must_settle():
    wide = np.array([20.0, 9000.0, 1.0])  # tracker pitch far off: not in the optical mask
    h = Harness(leg())
    assert h.frames(1000, trk=wide) == (legs.EXIT_DONE, 80)
    h = Harness(leg(mask=1 << legs.SIG_TRACKER_PITCH))
    assert h.frames(200, trk=wide) == (EXIT_NONE, 200)


def test_an_absent_sun_never_settles():
    h = Harness(leg(), closed=())  # not in use: no abort either
    assert h.frames(200, fine=np.array([0.0, 0.0, 0.0])) == (EXIT_NONE, 200)


def test_computed_errors_are_watched_from_cpu_22():
    mask = (1 << legs.SIG_ERROR_ROLL) | (1 << legs.SIG_ERROR_PITCH) | (1 << legs.SIG_ERROR_YAW)
    off = np.array([0.0, 0.0, 0.0, 10.0, 60.0, 10.0])  # pitch error 60": not settled
    assert Harness(leg(mask=mask)).frames(200, cpu=off) == (EXIT_NONE, 200)
    on = np.array([0.0, 0.0, 0.0, 10.0, -49.0, 10.0])
    assert Harness(leg(mask=mask)).frames(200, cpu=on) == (legs.EXIT_DONE, 80)


def test_watched_signals_read_absent_sensors_as_far_off():
    sig = np.zeros(legs.N_SIGNALS)
    watched_signals(np.array([1.0, 2.0, 0.0]), STAR, np.arange(6.0), sig)
    assert sig[legs.SIG_SUN_PITCH] == sig[legs.SIG_SUN_YAW] == ABSENT_ARCSEC
    assert sig[legs.SIG_TRACKER_YAW] == 20.0 and sig[legs.SIG_TRACKER_PITCH] == 5.0
    assert sig[legs.SIG_ERROR_ROLL:].tolist() == [3.0, 4.0, 5.0]


# -- hand-over and elapsed time --------------------------------------------------------------

def test_hand_over_waits_for_the_blanking():
    h = Harness(leg(legs.WATCH_HANDOVER, blank_s=10.0), closed=(14, 15))
    # Star inside 7200" from the start, but the first 10 s are blanked (Mode 4).
    assert h.frames(1000) == (legs.EXIT_DONE, 81)  # first frame with t > 10 s


def test_hand_over_inside_7200_arcsec():
    far = np.array([7200.0, 0.0, 1.0])
    h = Harness(leg(legs.WATCH_HANDOVER))
    assert h.frames(100, trk=far) == (EXIT_NONE, 100)
    assert h.frame(trk=np.array([7199.0, 0.0, 1.0])) == legs.EXIT_DONE


def test_elapsed_leg_ends_on_time():
    h = Harness(leg(legs.WATCH_ELAPSED, hold_s=40.0))
    assert h.frames(1000, fine=np.array([3000.0, 3000.0, 1.0])) == (legs.EXIT_DONE, 320)


# -- aborts ------------------------------------------------------------------------------------

def test_sensors_in_use_are_those_switched_into_an_amplifier():
    cases = {(): (False, False), (14,): (True, False), (15,): (True, False),
             (12,): (False, True), (13,): (False, True), (12, 15): (True, True),
             (9, 10, 11, 16, 18): (False, False)}
    for closed, expect in cases.items():
        bank = new_bank()
        bank[list(closed)] = 1
        assert sensors_in_use(bank, ROUTING) == expect, closed

GONE = np.array([0.0, 0.0, 0.0])


def test_sun_lost_while_s14_s15_are_in_use():
    h = Harness(leg(), closed=(14, 15))
    # Absent for more than 5 s: the 41st frame of 0.125 s (5.125 s).
    assert h.frames(1000, fine=GONE) == (legs.EXIT_SUN_LOST, 41)


def test_sun_lost_with_either_sun_switch():
    for closed in ((14,), (15,)):
        assert Harness(leg(), closed=closed).frames(1000, fine=GONE)[0] == legs.EXIT_SUN_LOST


def test_an_absent_sun_not_in_use_is_no_abort():
    h = Harness(leg(legs.WATCH_ELAPSED, hold_s=40.0), closed=(12, 13))  # star in use only
    assert h.frames(1000, fine=GONE) == (legs.EXIT_DONE, 320)


def test_sun_back_in_time_resets_the_loss_clock():
    h = Harness(leg(legs.WATCH_ELAPSED, hold_s=40.0), closed=(14, 15))
    for _ in range(6):
        assert h.frames(39, fine=GONE) == (EXIT_NONE, 39)  # 4.875 s absent
        assert h.frame() == EXIT_NONE
        assert h.sun_gone_s == 0.0


def test_star_lost_while_s12_s13_are_in_use():
    for closed in ((12,), (13,)):
        h = Harness(leg(), closed=closed)
        assert h.frames(1000, trk=GONE) == (legs.EXIT_STAR_LOST, 41)


def test_an_empty_tank_ends_the_leg_first():
    h = Harness(leg(legs.WATCH_ELAPSED, hold_s=0.0))
    assert h.frame(tank_ok=False) == legs.EXIT_PROPELLANT


def test_an_elapsed_leg_times_its_settle_mask_for_the_next_leg():
    """Mode 3: the count ends on time, whatever the errors, having timed how long they settled.

    40 s of settled errors with one bad frame at 30 s: the count ends at 40 s
    (320 frames of 0.125 s) with 10 s of settle time, which a leg carrying it
    on needs only one more settled frame to complete.
    """
    h = Harness(leg(legs.WATCH_ELAPSED, hold_s=40.0))
    bad = np.array([60.0, 0.0, 1.0])  # sun pitch at 60", above the 50" band
    assert h.frames(239)[0] == EXIT_NONE and h.settle_s == 239 * DT_S
    assert h.frame(fine=bad) == EXIT_NONE and h.settle_s == 0.0
    code, n = h.frames(100)
    assert (code, n, h.t_s) == (legs.EXIT_DONE, 80, 40.0)
    assert h.settle_s == 10.0
    h.leg = leg(hold_s=10.0)._replace(carry_settle=1)
    h.n = 0
    assert h.frame() == legs.EXIT_DONE


def test_an_elapsed_leg_without_signals_leaves_the_settle_time_alone():
    h = Harness(leg(legs.WATCH_ELAPSED, mask=0, hold_s=1.0))
    h.frames(8)
    assert h.settle_s == 0.0
