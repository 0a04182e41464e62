"""Master sequencer 20's watch: what ends a leg, checked once a frame.

The sequencer (:mod:`allsky.sequencer.master_sequencer`) sets the switches
and hands the frame loop a leg (:mod:`allsky.sequencer.legs`); this watch,
compiled into the loop, decides after every frame whether the leg is over:

1. abort when the propellant is gone, or when the Sun or the star has been
   absent for longer than ``sensor_loss_s`` while one of its outputs is
   switched into a control amplifier (S14/S15 for sun sensor 104, S12/S13
   for star tracker 105; :data:`allsky.hardware.wiring.ROUTING`);
2. otherwise, end the leg when its condition holds: WATCH_SETTLE (every
   signal of the settle mask below the settle threshold, 50", for
   ``hold_frames``, 10 s), WATCH_HANDOVER (the watched signal inside the
   hand-over threshold, 7200", once ``blank_frames`` have passed) or
   WATCH_ELAPSED (``hold_frames`` of the leg). Every time is a count of
   frames (:mod:`allsky.clock`), never a sum of frame steps. An elapsed leg with a settle
   mask also times how long its signals have been settled, for a following
   leg that carries the settle time on (``Leg.carry_settle``).
"""

from allsky.jit import njit_stage
from allsky.sequencer.legs import (
    EXIT_DONE,
    EXIT_PROPELLANT,
    EXIT_STAR_LOST,
    EXIT_SUN_LOST,
    N_SIGNALS,
    SIG_ERROR_PITCH,
    SIG_ERROR_ROLL,
    SIG_ERROR_YAW,
    SIG_SUN_PITCH,
    SIG_SUN_YAW,
    SIG_TRACKER_PITCH,
    SIG_TRACKER_YAW,
    WATCH_ELAPSED,
    WATCH_HANDOVER,
)

EXIT_NONE = 0  #: the watch lets the leg go on
#: [arcsec] what a watched optical signal reads while its Sun or star is absent.
ABSENT_ARCSEC = 1e9


@njit_stage
def any_closed(bank, numbers):
    """True when any switch of ``numbers`` is closed in ``bank``."""
    for k in numbers:
        if bank[k] == 1:
            return True
    return False


@njit_stage
def watched_signals(fine, trk, cpu, sig):
    """Fill ``sig`` (N_SIGNALS,) [arcsec], indexed by the SIG_* numbers.

    ``fine`` and ``trk`` are the sun sensor 104 and star tracker 105 outputs
    (pitch or yaw, yaw or pitch, present); an absent Sun or star reads
    :data:`ABSENT_ARCSEC`, so that it neither settles nor hands over.
    ``cpu`` is CPU 22's working store, errors in entries 3-5.
    """
    sig[SIG_SUN_PITCH] = fine[0] if fine[2] > 0.5 else ABSENT_ARCSEC
    sig[SIG_SUN_YAW] = fine[1] if fine[2] > 0.5 else ABSENT_ARCSEC
    sig[SIG_TRACKER_YAW] = trk[0] if trk[2] > 0.5 else ABSENT_ARCSEC
    sig[SIG_TRACKER_PITCH] = trk[1] if trk[2] > 0.5 else ABSENT_ARCSEC
    sig[SIG_ERROR_ROLL] = cpu[3]
    sig[SIG_ERROR_PITCH] = cpu[4]
    sig[SIG_ERROR_YAW] = cpu[5]


@njit_stage
def leg_condition(sq, leg, sig, n_leg, settle_frames):
    """Whether the leg's condition holds after this frame.

    ``n_leg`` is the frames flown in the leg, this one included;
    ``settle_frames`` the frames the settle condition has held so far.
    Returns ``(done, settle_frames)``, the settle count advanced by one, or
    reset to 0 when a watched signal is at or above the threshold.

    Parameters
    ----------
    sq : SequencerParams
        Thresholds of the watch (settle, hand-over [arcsec]).
    leg : allsky.sequencer.legs.Leg
        The leg flown: its condition (``watch``), settle mask, hand-over
        signal, ``blank_frames`` and ``hold_frames``.
    sig : numpy.ndarray
        [arcsec] the watched signals (:func:`watched_signals`).
    """
    if leg.watch == WATCH_HANDOVER:
        return (n_leg > leg.blank_frames
                and abs(sig[leg.handover_signal]) < sq.handover_arcsec), settle_frames
    if leg.watch != WATCH_ELAPSED or leg.settle_mask:
        ok = True
        for k in range(N_SIGNALS):
            if (leg.settle_mask >> k) & 1 and abs(sig[k]) >= sq.settle_threshold_arcsec:
                ok = False
        settle_frames = settle_frames + 1 if ok else 0
    if leg.watch == WATCH_ELAPSED:
        return n_leg >= leg.hold_frames, settle_frames
    return settle_frames >= leg.hold_frames, settle_frames


@njit_stage
def sensors_in_use(bank, routing):
    """Whether sun sensor 104 and star tracker 105 are in use: ``(sun, star)``.

    A sensor is in use while one of its outputs is switched into a control
    amplifier (``routing.sun_switches``, ``routing.tracker_switches``).
    ``bank`` is the switch bank S1-S19 (entry k for Sk, 1 = closed);
    ``routing`` the wiring as index arrays (:data:`allsky.hardware.wiring.ROUTING`).
    """
    return any_closed(bank, routing.sun_switches), any_closed(bank, routing.tracker_switches)


@njit_stage
def watch(sq, leg, sun_in_use, star_in_use, tank_ok, fine, trk, cpu, sig, n_leg,
          settle_frames, sun_gone, star_gone):
    """One frame of the watch: abort, end the leg, or let it go on.

    Parameters
    ----------
    sq : SequencerParams
        Thresholds (settle, hand-over [arcsec]; sensor loss [frames]).
    leg : allsky.sequencer.legs.Leg
    sun_in_use, star_in_use : bool
        Whether the Sun and the star are in use (:func:`sensors_in_use`).
    tank_ok : bool
        False once jets 39-41 have run the tank dry.
    fine, trk, cpu, sig : numpy.ndarray
        As in :func:`watched_signals`.
    n_leg : int
        Frames flown in the leg, this one included.
    settle_frames, sun_gone, star_gone : int
        Frames the settle condition has held, and the Sun and the star have
        been absent while in use, as left by the previous frame.

    Returns
    -------
    tuple
        ``(exit_code, settle_frames, sun_gone, star_gone)``: EXIT_NONE while
        the leg goes on, else an EXIT_* code of :mod:`allsky.sequencer.legs`.
    """
    if not tank_ok:
        return EXIT_PROPELLANT, settle_frames, sun_gone, star_gone
    sun_gone = sun_gone + 1 if (sun_in_use and fine[2] < 0.5) else 0
    star_gone = star_gone + 1 if (star_in_use and trk[2] < 0.5) else 0
    if sun_gone > sq.sensor_loss_frames:
        return EXIT_SUN_LOST, settle_frames, sun_gone, star_gone
    if star_gone > sq.sensor_loss_frames:
        return EXIT_STAR_LOST, settle_frames, sun_gone, star_gone
    watched_signals(fine, trk, cpu, sig)
    done, settle_frames = leg_condition(sq, leg, sig, n_leg, settle_frames)
    return (EXIT_DONE if done else EXIT_NONE), settle_frames, sun_gone, star_gone
