"""The frame loop's journal stages (allsky.sim.journal), each in a tiny harness.

Truth: an entry is written exactly when what it watches changes, once per
change, with the values of that frame; a full buffer counts what it could
not hold; draining moves the rows into the journal, decoded, and empties the
buffer.
"""

import numpy as np
import pytest

from allsky import clock
from allsky.config.faults import describe
from allsky.hardware import star_tracker as trk
from allsky.hardware.star_tracker import FALSE_TARGET, new_lock
from allsky.sim import journal as J
from allsky.vocabulary import EVENT_KINDS

WHEELS, FAULTS = 4, 2


def buffer():
    return J.new_buffer(WHEELS, FAULTS)


def decoder(frame_s=1.0):
    """A decoder whose clock turns frame k into k * frame_s seconds."""
    faults = [{"kind": "tracker_dropout", "duration_s": 5.0},
              {"kind": "gyro_dead", "axis": "pitch"}]
    return J.Decoder(["Canopus", "Avior"], faults, describe, 0.0025, clock.clock(frame_s),
                     reference_cone_deg=-9.95, cone_check_deg=2.0, gate_magnitude=-2.88)


def drained(buf, n, mode="2", frame_s=1.0):
    j = J.Journal()
    j.drain(buf, n, mode, decoder(frame_s))
    return j


def test_the_star_in_the_slit_is_journaled_at_each_change_only():
    buf, n, seen = buffer()
    overflow = np.zeros(6, dtype=np.int64)
    stars = [-1, -1, 0, 0, 0, -1, 1, FALSE_TARGET, -1]
    for k, star in enumerate(stars):
        J.note_frame(buf, n, seen, k, star, 1.0, -36000.0 * (star >= 0), overflow, new_lock())
    j = drained(buf, n, frame_s=0.01)  # times from frames: exact decimals
    assert [(e["t_s"], e["star"], e["previous"]) for e in j.events] == [
        (0.02, "Canopus", None), (0.05, None, "Canopus"), (0.06, "Avior", None),
        (0.07, "stray light", "Avior"), (0.08, None, "stray light")]
    assert j.events[0]["cone_angle_deg"] == pytest.approx(-10.0) and j.events[0]["in_use"]
    assert j.events[1]["cone_angle_deg"] is None
    assert n[0] == 0 and not buf.any()  # drained and empty


def test_a_refusal_and_a_drop_are_journaled_in_the_frame_the_tracker_flags_them():
    """The tracker flags a refusal (cone-angle check) or a drop (bright gate) for one
    frame; each becomes one entry with the values of that frame."""
    buf, n, seen = buffer()
    overflow = np.zeros(6, dtype=np.int64)
    for k in range(6):
        lock = new_lock()
        if k == 1:
            lock[trk.NEW_REFUSAL] = 1  # Avior
            lock[trk.REFUSED_CONE_ARCSEC] = 6.83 * 3600.0
        if k == 2:
            lock[trk.NEW_REFUSAL] = FALSE_TARGET
            lock[trk.REFUSED_CONE_ARCSEC] = 0.0
        if k == 4:
            lock[trk.NEW_DROP] = 0  # Canopus, in a slit of -4.1 mag
            lock[trk.SEEN_MAG] = -4.1
        J.note_frame(buf, n, seen, float(k), -1, 1.0, 0.0, overflow, lock)
    j = drained(buf, n)
    assert [(e["t_s"], e["kind"], e["star"]) for e in j.events] == [
        (1.0, "lock_rejected", "Avior"), (2.0, "lock_rejected", "stray light"),
        (4.0, "lock_dropped", "Canopus")]
    assert j.events[0]["cone_angle_deg"] == pytest.approx(6.83)
    assert j.events[0]["reference_cone_angle_deg"] == -9.95 and j.events[0]["check_deg"] == 2.0
    assert j.events[2]["magnitude"] == pytest.approx(-4.1)
    assert j.events[2]["gate_magnitude"] == -2.88 and j.events[2]["in_use"]


def test_each_overflow_latch_is_journaled_once():
    buf, n, seen = buffer()
    overflow = np.zeros(6, dtype=np.int64)
    for k in range(10):
        if k == 3:
            overflow[1] = 1  # counter 16
        if k == 6:
            overflow[3] = 1  # drift counter 13
        J.note_frame(buf, n, seen, float(k), -1, 0.0, 0.0, overflow, new_lock())
    j = drained(buf, n)
    assert [(e["t_s"], e["block"], e["axis"]) for e in j.events] == [
        (3.0, "16", "pitch"), (6.0, "13", "roll")]
    assert all(e["what"] == "counter_overflow" and e["active"] for e in j.events)


def test_a_drift_dac_clip_starts_when_its_switch_feeds_it_and_ends_when_opened():
    buf, n, seen = buffer()
    counts = np.array([2418, -320, -2048], dtype=np.int64)  # 12-bit DACs: -2048..2047
    for t, gate in ((1.0, [0.0, 0.0, 0.0]), (2.0, [1.0, 1.0, 1.0]), (3.0, [1.0, 1.0, 1.0]),
                    (4.0, [0.0, 1.0, 1.0])):
        J.note_clip(buf, n, seen, t, counts, np.array(gate), 2047, -2048)
    j = drained(buf, n)
    assert [(e["t_s"], e["axis"], e["active"]) for e in j.events] == [
        (2.0, "roll", True), (4.0, "roll", False)]
    e = j.events[0]
    assert (e["block"], e["counted_pulses"], e["applied_pulses"]) == ("7", 2418, 2047)
    assert e["applied_deg_h"] == pytest.approx(5.1175) and e["counted_deg_h"] == pytest.approx(
        6.045)


def test_wheels_at_their_limit_and_the_unloader_with_a_band():
    buf, n, seen = buffer()
    limit = np.array([4.0, 4.0, 4.0])
    for k, (h0, unloading) in enumerate([(3.9, 0.0), (4.0, 0.0), (3.98, 1.0), (3.97, 1.0),
                                         (3.5, 0.0)]):
        h = np.array([h0, 0.0, 0.0, 0.0])
        J.note_wheels(buf, n, seen, float(k), unloading, h, limit)
    j = drained(buf, n)
    got = [(e["t_s"], e["what"], e["active"]) for e in j.events]
    # At 4.0 it holds its limit; 3.98 and 3.97 stay inside the 1 % band; 3.5 leaves it.
    assert got == [(1.0, "wheel_momentum_limit", True), (2.0, "wheel_unloading", True),
                   (4.0, "wheel_unloading", False), (4.0, "wheel_momentum_limit", False)]


def test_a_fault_s_onset_and_end():
    buf, n, seen = buffer()
    first = J.SEEN_WHEEL + WHEELS
    state = np.zeros((3, FAULTS))
    state[0] = [2.0, 5.0]  # onsets [frames]
    duration = np.array([5, clock.NEVER], dtype=np.int64)  # [frames]
    for k in range(12):
        J.note_faults(buf, n, seen, first, float(k), 2, state, 0, duration)
    j = drained(buf, n, mode="4")
    assert [(e["t_s"], e["fault_kind"], e["active"]) for e in j.events] == [
        (2.0, "tracker_dropout", True), (5.0, "gyro_dead", True),
        (7.0, "tracker_dropout", False)]
    assert j.events[1]["text"] == "pitch gyro dead" and j.events[1]["mode"] == "4"


def test_a_full_buffer_counts_what_it_lost():
    buf, n, seen = buffer()
    overflow = np.zeros(6, dtype=np.int64)
    for k in range(J.ROWS + 7):  # a change every frame
        J.note_frame(buf, n, seen, float(k), k % 2, 0.0, 0.0, overflow, new_lock())
    assert n[0] == J.ROWS and n[1] == 7
    j = drained(buf, n)
    assert len(j) == J.ROWS and j.lost == 7 and n[1] == 0


def test_an_unknown_kind_is_refused():
    with pytest.raises(ValueError, match="unknown journal kind"):
        J.Journal().note(0.0, "1", "weather")


def test_a_misspelt_or_missing_field_is_an_error():
    """The journal's fields are declared (vocabulary.EVENT_KINDS) and checked where written."""
    j = J.Journal()
    with pytest.raises(ValueError, match="undeclared field"):
        j.note(0.0, None, "abort", reson="typo")
    with pytest.raises(ValueError, match="missing field"):
        j.note(0.0, None, "abort")
    with pytest.raises(ValueError, match="unknown journal kind"):
        j.note(0.0, None, "aborted", reason="x")
    j.note(0.0, None, "ground_command", command="fault", fault_kind="gyro_dead", axis="roll",
           text="a fault", fault=0)
    assert len(j) == 1


def test_every_declared_field_has_a_unit_and_a_meaning():
    for kind in EVENT_KINDS:
        assert kind.fields and all(f.meaning for f in kind.fields), kind.name
        assert len(kind.names) == len(kind.fields), kind.name
