"""Journal entries in words (allsky.apps.events): the tracker's refusals and drops.

Truth: each entry's fields, stated in its line; the replay page's log gives
each row the part of the machine that wrote it.
"""

import pytest

from allsky.apps import events

REFUSAL = {"t_s": 245.04, "mode": "2", "kind": "lock_rejected", "star": "Avior",
           "cone_angle_deg": 6.826, "reference_cone_angle_deg": -9.951, "check_deg": 2.0,
           "in_use": False}
DROP = {"t_s": 280.01, "mode": "2", "kind": "lock_dropped", "star": "Canopus",
        "magnitude": -3.574, "gate_magnitude": -2.88, "in_use": True}


def test_a_refusal_says_the_star_its_cone_angle_and_how_far_from_the_reference():
    text = events.event_text(REFUSAL)
    assert text == ("tracker: Avior refused at cone angle +6.83 deg, 16.78 deg from the "
                    "reference star's (check 2 deg)")


def test_a_drop_says_the_light_seen_and_the_gate():
    assert events.event_text(DROP) == ("tracker: Canopus dropped, the slit at -3.57 mag, "
                                       "brighter than the gate (-2.88 mag)")


@pytest.mark.parametrize("entry, reason", [(REFUSAL, "the tracker's cone-angle check"),
                                           (DROP, "the tracker's bright gate")])
def test_the_replay_log_gives_each_its_row(entry, reason):
    (row,) = events.page_log([entry])
    assert row["kind"] == entry["kind"] and row["reason"] == reason
    assert row["text"] == events.event_text(entry)


@pytest.mark.parametrize("word", ["roll_into_pitch", "yaw_into_roll"])
def test_register_23_cross_coupling_is_in_arcsec_as_every_table_gives_it(word):
    """The register holds radians; the journal's line gives arcsec, the tables' unit."""
    e = {"kind": "register", "register": "23", "word": word, "value": 0.0008669753086419754,
         "unit": "-"}
    assert events.event_text(e) == f"register 23 {word} = +178.83 arcsec"  # 8.67e-4 rad
    sf = {"kind": "register", "register": "23", "word": "sf_roll", "value": 0.9985065,
          "unit": "-"}
    assert events.event_text(sf) == "register 23 sf_roll = 0.9985065"
