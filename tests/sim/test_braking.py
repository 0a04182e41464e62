"""The roll braking after a star hand-over against the slit (allsky.sim.braking)."""

import math

import pytest

from allsky.apps.cli import main
from allsky.config.scenario import load_scenario
from allsky.sim.braking import handover_braking, handover_warning
from allsky.sim.mission import Mission

BLOWDOWN = ['jets.supply="blowdown"', "jets.tank_pressure_initial_bar=20.0",
            "jets.tank_pressure_final_bar=5.0"]


def test_the_stop_and_the_propellant_it_needs_are_the_closed_form():
    """Default vehicle: w = 1.5 deg/s, I_xx = 100 kg m^2, roll couple 2 x 0.25 N x 0.5 m =
    0.25 N m: the stop is w^2 I / (2 T) = (1.5 pi/180)^2 100 / 0.5 rad = 7.854 deg, against
    2 deg (hand-over) + 8 deg (half-slit): phi_min = 0.7854. On blow-down from 20 to 5 bar
    (f = 0.25) with 4 kg: m_min = 4 (0.7854 - 0.25) / 0.75 = 2.855 kg."""
    b = handover_braking(load_scenario(overrides=BLOWDOWN))
    stop = (1.5 * math.pi / 180.0) ** 2 * 100.0 / (2.0 * 0.25)
    assert b["stop_deg"] == pytest.approx(math.degrees(stop), rel=1e-12)
    assert b["stop_deg"] == pytest.approx(7.854, abs=1e-3)
    assert b["room_deg"] == pytest.approx(10.0, rel=1e-12)
    assert b["min_thrust_fraction"] == pytest.approx(math.degrees(stop) / 10.0, rel=1e-12)
    assert b["final_thrust_fraction"] == 0.25
    assert b["min_propellant_kg"] == pytest.approx(4.0 * (b["min_thrust_fraction"] - 0.25)
                                                   / 0.75, rel=1e-12)
    assert b["min_propellant_kg"] == pytest.approx(2.855, abs=1e-3)
    assert handover_warning(load_scenario()) is None  # regulated: full thrust to the end
    assert handover_warning(load_scenario(overrides=[*BLOWDOWN, 'actuators.kind="wheels"'])) \
        is None


@pytest.mark.parametrize("share, lost", [(0.80, False), (0.77, True)])
def test_the_flight_loses_the_star_where_the_closed_form_says(share, lost):
    """Mode 2 flown with the roll jets at a share of their thrust (a regulated feed, so the
    share holds throughout): the closed form puts the limit at 0.785; at 0.80 the star stays
    in the slit, at 0.77 the stop carries it out and Mode 2 aborts."""
    cfg = load_scenario(overrides=[f"jets.thrust_n=[{0.25 * share!r}, 0.5, 0.5]"])
    assert (handover_warning(cfg) is not None) == lost
    m = Mission(cfg, telemetry=False)
    m.run_mode()
    r = m.run_mode()
    assert r.mode == "2"
    assert r.exit.startswith("aborted: Mode 2: star lost") == lost


def test_a_small_blowdown_tank_is_warned_of_and_loses_the_star_below_the_limit(capsys):
    """1 kg on blow-down: the limit is 1 (0.7854 - 0.25)/0.75 = 0.714 kg, after 0.286 kg;
    Mode 1 uses more than that, and Mode 2's stop overshoots. config check and the summary
    say so, with the propellant at which it starts."""
    sets = [*BLOWDOWN, "jets.propellant_kg=1.0"]
    assert main(["config", "check", *[a for s in sets for a in ("--set", s)]]) == 0
    out = capsys.readouterr().out
    assert "warning: the roll braking after a star hand-over" in out and "0.714 kg" in out
    m = Mission(load_scenario(overrides=sets), telemetry=False)
    s = m.run()
    assert s["status"] == "aborted" and s["abort_reason"].startswith("Mode 2: star lost")
    assert 1.0 - s["propellant_kg"] < 0.714
    assert "0.714 kg" in s["warnings"][0] and s["warnings"][0].endswith("below it")
    from allsky.apps.replay import _warnings  # the replay's list: the same sentence at 0 s

    assert _warnings(s, m.cfg)[0] == {"t_s": 0.0, "text": s["warnings"][0]}
