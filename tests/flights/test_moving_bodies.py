"""The Moon and the planets in the tracker's sky, flown in orbit.

On 2026-11-28 (the Mariner cards' date) Jupiter at -2.17 mag crosses the
slit band 99.1 deg from the Sun, its cone angle 1.78 deg from Canopus's
(tests/vehicle/test_bodies.py). A magnitude window that passes it lets the
roll search of Mode 2 meet it first: the tracker locks it, as Mariner 4's
tracker locked the wrong objects, unless a cone-angle check under 1.78 deg
refuses it.
"""

import json

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from allsky.config import load_scenario
from allsky.sim import sky_rows
from allsky.sim.mission import Mission
from allsky.vehicle import environment
from tests.sim.test_commands import live, same_bits

JUPITER_SKY = ["mission.date_utc=2026-11-28T00:00:00Z",
               "star_tracker.magnitude_window=[-2.5,-0.3]"]


def _fly(*overrides, telemetry=False):
    m = Mission(load_scenario("shuttle-free-flyer", overrides=[*JUPITER_SKY, *overrides]),
                telemetry=telemetry)
    return m, m.run()


def _locks(summary):
    return [(e["mode"], e["star"]) for e in summary["events"] if e["kind"] == "star_lock"]


@pytest.fixture(scope="module")
def unchecked():
    return _fly("star_tracker.cone_angle_check_deg=0.0", telemetry=True)


def test_the_tracker_locks_jupiter_and_the_journal_names_it(unchecked):
    m, s = unchecked
    assert "Jupiter" in sky_rows.sky_rows(m.cfg).names
    assert _locks(s)[0] == ("2", "Jupiter")
    lock = next(e for e in s["events"] if e["kind"] == "star_lock")
    # its cone angle, where Canopus's is -10.99 deg: 1.8 deg off
    assert lock["cone_angle_deg"] == pytest.approx(-9.19, abs=0.05)


def test_a_one_degree_cone_check_refuses_jupiter():
    _, s = _fly("star_tracker.cone_angle_check_deg=1.0")
    refused = [e for e in s["events"] if e["kind"] == "lock_rejected"]
    assert refused and refused[0]["star"] == "Jupiter" and refused[0]["mode"] == "2"
    assert abs(refused[0]["cone_angle_deg"] - refused[0]["reference_cone_angle_deg"]) > 1.0
    assert _locks(s)[0] == ("2", "Canopus")
    assert s["status"] == "complete" and s["locked_star"] == "Canopus"


def test_moving_bodies_off_leaves_them_out_of_the_sky():
    m, s = _fly("star_tracker.cone_angle_check_deg=0.0", 'star_tracker.moving_bodies="off"')
    assert sky_rows.sky_rows(m.cfg).names == ["Sirius", "Canopus"]
    assert "Jupiter" not in {star for _, star in _locks(s)}


def test_auto_flies_no_body_without_an_orbit():
    cfg = load_scenario(overrides=JUPITER_SKY)
    rows = sky_rows.sky_rows(cfg)
    assert rows.body_names == [] and rows.names == ["Sirius", "Canopus"]
    on = sky_rows.sky_rows(load_scenario(overrides=[*JUPITER_SKY,
                                                    'star_tracker.moving_bodies="on"']))
    # the window's stars brightest first, then the bodies inside it in their order
    assert on.names == ["Sirius", "Canopus", "Mercury", "Jupiter"]
    assert list(on.body_rows) == [-1, 2, -1, -1, 3, -1]


@settings(max_examples=3, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(seed=st.integers(0, 2**31 - 1))
def test_a_flight_among_the_bodies_paused_at_random_is_the_flight(unchecked, seed):
    """The bodies' rows move with the frame index alone: pauses anywhere change nothing."""
    plain, s = unchecked
    m, station = live(plain.cfg, [], seed=seed)
    assert station.log == []
    assert m.summary() == s
    assert same_bits(m.telemetry(), plain.telemetry())


def test_the_journal_names_jupiters_occultation_at_its_frame():
    """Ejected at argument of latitude 210 deg, the Earth rises over Jupiter in Mode 4.

    The journal's entry is at the frame the Earth's disk first covers the
    body's row (tests/vehicle/test_environment.py holds that frame to the
    orbit's closed form).
    """
    m, s = _fly("star_tracker.cone_angle_check_deg=1.0", "orbit.arg_latitude_deg=210.0")
    hidden = [e for e in s["events"] if e["kind"] == "occultation" and e["body"] == "Jupiter"]
    assert hidden and hidden[0]["active"]
    o = m.params.orbit
    j = sky_rows.sky_rows(m.cfg).body_names.index("Jupiter")
    series = environment.occulted_bodies_series(o, 0, m.frame)[:, j]
    first = int(np.argmax(series))
    assert series[first] and hidden[0]["t_s"] == pytest.approx(first * m.params.frame_s,
                                                               abs=1e-9)
    assert 600.0 < hidden[0]["t_s"] < 660.0


def test_allsky_stars_lists_the_bodies_in_the_window(capsys):
    from allsky.apps.cli import main

    args = ["stars", "--window", "--date", "2026-11-28T00:00:00Z",
            "--set", "star_tracker.magnitude_window=[-2.5,-0.3]"]
    assert main([*args, "--json", "-"]) == 0
    body = json.loads(capsys.readouterr().out)
    assert [b["name"] for b in body["moving_bodies"]] == ["Mercury", "Jupiter"]
    jupiter = body["moving_bodies"][1]
    assert jupiter["magnitude"] == pytest.approx(-2.17, abs=0.01)
    assert jupiter["phase"] == pytest.approx(0.99, abs=0.005)
    assert jupiter["elongation_deg"] == pytest.approx(99.1, abs=0.05)
    assert body["moving_bodies_seen"] is False  # the default mission: no orbit, "auto"
    assert main([*args, "shuttle-free-flyer"]) == 0
    table = capsys.readouterr().out
    row = next(ln for ln in table.splitlines() if ln.strip().startswith("Jupiter"))
    assert row.split()[1:] == ["-2.17", "9.920", "+13.50", "0.99", "in"]
    assert "Moving bodies inside: 2 (the tracker sees them)" in table
    assert max(len(ln) for ln in table.splitlines()[1:]) <= 100


def test_the_bright_gate_counts_the_moons_light_and_moves_it():
    """The Moon (-11.6 mag) on the boresight fills the slit 10^4.6 times a magnitude-0 star."""
    from allsky.hardware.star_tracker import slit_flux
    from allsky.vehicle import quaternion

    gate = [*JUPITER_SKY, "star_tracker.bright_gate=true"]
    m = Mission(load_scenario("shuttle-free-flyer", overrides=gate), telemetry=False)
    rows = sky_rows.sky_rows(m.cfg)
    j = rows.body_names.index("Moon")
    moon = rows.gate_directions[rows.gate_rows[j]]
    x = np.cross(moon, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    q = quaternion.from_dcm(np.array([x, np.cross(moon, x), moon]))
    flux = slit_flux(m.params.tracker, q)
    assert flux >= 10 ** (0.4 * 11.5)
    off = Mission(load_scenario("shuttle-free-flyer",
                                overrides=[*gate, 'star_tracker.moving_bodies="off"']),
                  telemetry=False)
    assert slit_flux(off.params.tracker, q) < 10.0  # the stars alone
    m.run()
    o = m.params.orbit
    k = int(o.body_k[0])
    assert k > 0 and np.array_equal(o.tracker.gate_stars_inertial[rows.gate_rows[j]],
                                    o.bodies_i[k, j])
