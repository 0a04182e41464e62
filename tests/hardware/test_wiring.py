"""The wiring table (allsky.hardware.wiring) against the patent's connections (SPEC section 3)."""

import numpy as np

from allsky.hardware import wiring
from allsky.hardware.wiring import PITCH, ROLL, ROUTING, SWITCHES, YAW


def test_every_switch_once_in_order():
    assert [s.number for s in SWITCHES] == list(range(1, 20))


def test_coupled_pairs_are_the_patents():
    # S16 with S18, S17 with S19 (rate commands), S7 with S8 (dashed line 132).
    assert sorted(wiring.COUPLED_PAIRS) == [(7, 8), (16, 18), (17, 19)]
    for s in SWITCHES:
        if s.coupled_with:
            assert wiring.BY_NUMBER[s.coupled_with].coupled_with == s.number
    assert wiring.SELECTORS == (7, 8)


def test_connections_of_spec_section_3():
    expect = {1: ("7", "4"), 2: ("9", "5"), 3: ("11", "6"), 4: ("8", "13"), 5: ("10", "15"),
              6: ("12", "17"), 9: ("28", "31"), 10: ("29", "32"), 11: ("30", "33"),
              12: ("105", "31"), 13: ("105", "32"), 14: ("104", "32"), 15: ("104", "33"),
              16: ("120", "4"), 17: ("128", "6"), 18: ("4", "31"), 19: ("6", "33")}
    for k, (src, dst) in expect.items():
        s = wiring.BY_NUMBER[k]
        assert (s.source, s.destination) == (src, dst), k


def test_routing_arrays_follow_the_table():
    assert ROUTING.drift_switch.tolist() == [1, 2, 3]
    assert ROUTING.drift_count_switch.tolist() == [4, 5, 6]
    assert ROUTING.rate_command_switch.tolist() == [16, wiring.NONE, 17]
    assert ROUTING.rate_mode_switch.tolist() == [18, wiring.NONE, 19]
    routes = ROUTING.position_routes
    assert routes.dtype == np.int64
    # Every position switch appears once, on its own axis, carrying its own source.
    assert sorted(routes[:, 0].tolist()) == [9, 10, 11, 12, 13, 14, 15]
    for k, src, axis in routes:
        s = wiring.BY_NUMBER[int(k)]
        assert s.axis == axis
        assert wiring.POSITION_SOURCES[src] == (s.source, s.source_port)
    by_axis = {a: [int(k) for k, _, ax in routes if ax == a] for a in (ROLL, PITCH, YAW)}
    assert by_axis == {ROLL: [12, 9], PITCH: [13, 14, 10], YAW: [15, 11]}


def test_labels_name_the_switch_and_destination():
    assert wiring.label(12) == "S12 tracker yaw -> 31"
    assert wiring.label(1) == "S1 7 -> 4"
