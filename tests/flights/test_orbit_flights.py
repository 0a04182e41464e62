"""Missions in orbit: the free flyer, orbit sunset in Mode 5, and when to eject."""

import json

import numpy as np
import pytest

from allsky.apps.cli import main
from allsky.config.scenario import load_scenario
from allsky.sim.mission import Mission
from allsky.studies.window import ejection_window, period_s


@pytest.fixture(scope="module")
def sunset():
    m = Mission(load_scenario("shuttle-free-flyer-sunset"), telemetry=True)
    return m, m.run()


@pytest.fixture(scope="module")
def free_flyer():
    m = Mission(load_scenario("shuttle-free-flyer"), telemetry=False)
    return m, m.run()


def test_the_free_flyer_completes_in_daylight(free_flyer):
    _, s = free_flyer
    assert s["status"] == "complete"
    orb = s["orbit"]
    assert orb["kind"] == "circular" and orb["sunlit_fraction"] == 1.0
    assert orb["sunlit_margin_s"] > 1500.0
    # ejected in the umbra 3 minutes before sunrise: Mode 1 meets the Sun as it rises
    ecl = [(e["mode"], e["phase"]) for e in s["events"] if e["kind"] == "eclipse"]
    assert ecl == [("1", "umbra"), ("1", "penumbra"), ("1", "sunlit")]
    assert 140.0 < orb["eclipsed_s"] < 187.0
    # the sunlit Earth blinds the tracker only where the sequencer does not need a star
    glare = [e for e in s["events"] if e["kind"] == "earth_glare"]
    assert {e["mode"] for e in glare} == {"4", "6-1"}
    assert not any(e["in_use"] for e in glare if e["active"])
    gg = orb["torques"]["gravity_gradient"]
    # the figure: about 1.2e-3 N m at most on this inertia at 300 km
    assert 5e-4 < gg["peak_n_m"] < 1.3e-3
    assert orb["torques"]["aerodynamic"]["peak_n_m"] < gg["peak_n_m"]
    assert orb["torques"]["solar_pressure"]["peak_n_m"] < 1e-5


def test_orbit_sunset_in_mode_5_aborts_for_the_reason_the_journal_names(sunset):
    _, s = sunset
    assert s["status"] == "aborted" and s["abort_reason"].startswith("Mode 5: Sun")
    ecl = [e for e in s["events"] if e["kind"] == "eclipse"]
    assert [e["phase"] for e in ecl] == ["penumbra", "umbra"]
    assert all(e["mode"] == "5" for e in ecl)
    # the penumbra: seconds, its fraction falling from 1; then the umbra, fraction 0
    assert 5.0 < ecl[1]["t_s"] - ecl[0]["t_s"] < 15.0
    assert ecl[1]["sunlit_fraction"] == 0.0
    assert any("orbit night" in w for w in s["warnings"])
    assert s["orbit"]["sunlit_fraction"] == 0.0 and s["orbit"]["sunlit_margin_s"] == 0.0


def test_the_orbits_telemetry_follows_the_journal(sunset):
    m, s = sunset
    rows = m.orbit_telemetry()
    assert rows.shape == (m.telemetry().shape[0], 6)
    # the glare flag follows the journal's earth_glare entries
    for e in (e for e in s["events"] if e["kind"] == "earth_glare"):
        after = rows[rows[:, 0] >= e["t_s"] - 1e-9]
        assert after[0, 5] == (1.0 if e["active"] else 0.0)
    penumbra = next(e["t_s"] for e in s["events"] if e["kind"] == "eclipse")
    dark = rows[rows[:, 2] == 1.0, 0]
    assert dark[0] == pytest.approx(penumbra, abs=0.1 + 1e-9)
    assert rows[rows[:, 0] < penumbra - 0.1, 1].min() == 1.0
    ax, az = rows[:, 3], rows[:, 4]
    assert ((ax >= 0) & (ax <= 180) & (az >= 0) & (az <= 180)).all()
    # +x and +z are perpendicular: their angles from one direction obey the triangle rule
    assert (np.abs(ax - az) <= 90 + 1e-9).all() and (ax + az >= 90 - 1e-9).all()
    assert Mission(load_scenario(), telemetry=False).orbit_telemetry() is None


def test_no_orbit_flies_nothing_of_the_orbit():
    m = Mission(load_scenario(), telemetry=False)
    assert m.params.orbit.n == 0
    from allsky.sim import frame_loop

    assert frame_loop.leg_entry(m.params) is frame_loop._run_leg_plain


def test_the_window_agrees_with_the_eclipse_geometry():
    cfg = load_scenario("shuttle-free-flyer")
    every = 600.0
    result = ejection_window(cfg, every, workers=2)
    rows = result["rows"]
    assert len(rows) == int(np.ceil(period_s(cfg) / every))
    assert rows[0]["status"] == "complete"
    # the margin of a complete mission in daylight: next sunset less the mission's end,
    # the sunset of the first candidate moving closer by the ejection's delay
    first = rows[0]
    sunset_t = first["sunlit_margin_s"] + first["mission_time_s"]
    for r in rows[1:]:
        if r["status"] == "complete" and r["sunlit_margin_s"] and r["offset_s"] < sunset_t:
            expected = sunset_t - r["offset_s"] - r["mission_time_s"]
            assert r["sunlit_margin_s"] == pytest.approx(expected, abs=1.0)
    # one ejected into the night with the Sun to set within the calibration aborts
    assert any(r["status"] == "aborted" for r in rows)


def test_window_without_an_orbit_exits_2(capsys):
    assert main(["window", "--quiet"]) == 2
    assert "orbit" in capsys.readouterr().err


def test_window_bad_orbit_flag_exits_2(capsys):
    assert main(["window", "--orbit", "300", "--quiet"]) == 2
    assert "--orbit" in capsys.readouterr().err


def test_window_cli_writes_its_json(tmp_path, capsys):
    out = tmp_path / "w.json"
    assert main(["window", "--orbit", "300,28.5,0,124", "--every", "2700", "--workers", "1",
                 "--json", str(out), "--quiet"]) == 0
    data = json.loads(out.read_text())
    assert len(data["rows"]) == 3 and data["rows"][0]["status"] == "complete"
    assert "Ejection window" in capsys.readouterr().out


def test_the_sunlit_earth_takes_canopus_from_a_faulted_loop_too():
    """A fault that changes nothing flies the orbit's flight exactly, the Earth included.

    Ejected at argument of latitude 250 deg (ascending node 315 deg), the
    sunlit Earth enters the tracker's slit in Mode 5 (633.2 s), as the yaw
    calibration begins to turn the slit about Canopus: the tracker is
    blinded, loses Canopus, and the sequencer aborts. The loop with faults
    takes the orbit's tracker (its hidden stars, its blinding) as its tracker
    without a fault.
    """
    orbit = ["orbit.arg_latitude_deg=250.0", "orbit.raan_deg=315.0"]
    inert = ['faults=[{kind="gyro_bias_step", axis="roll", start_s=1.0, size_deg_h=0.0}]']
    flights = []
    for extra in ([], inert):
        m = Mission(load_scenario("shuttle-free-flyer", overrides=orbit + extra))
        flights.append((m, m.run()))
    (plain, a), (faulted, b) = flights
    assert faulted.params.faults.n == 1
    blinded = [e for e in b["events"] if e["kind"] == "earth_glare" and e["active"]]
    assert [(e["mode"], e["star"], e["in_use"]) for e in blinded][-1] == ("5", "Canopus", True)
    assert blinded[-1]["t_s"] == pytest.approx(633.2, abs=0.05)
    assert b["status"] == "aborted" and "star lost" in b["abort_reason"]
    assert np.array_equal(plain.telemetry(), faulted.telemetry())
    # the same journal, but for the fault's own entry (and the abort naming it)
    assert [(e["t_s"], e["kind"]) for e in a["events"]] == \
        [(e["t_s"], e["kind"]) for e in b["events"] if e["kind"] != "fault"]
