"""``allsky run`` and ``allsky compare`` from the command line: exit codes and outputs.

(The ``config`` commands and the property test over mutated scenario files
are in test_cli_config.py.)"""

import json

from allsky.apps.cli import main
from allsky.sim.recorder import FORMAT


def test_bad_override_exit_2(capsys):
    assert main(["run", "--set", "gyro.arw_deg_rt_h=-1"]) == 2
    assert "gyro.arw_deg_rt_h = -1.0: must be >= 0" in capsys.readouterr().err


def test_run_writes_json_and_telemetry(tmp_path, capsys):
    js, tl = tmp_path / "s.json", tmp_path / "t.csv"
    assert main(["run", "--json", str(js), "--telemetry", str(tl)]) == 0
    report = capsys.readouterr().out
    assert "Mode timeline" in report and "final true pointing error" in report
    s = json.loads(js.read_text())
    assert s["status"] == "complete" and s["abort_reason"] is None
    assert [m["mode"] for m in s["modes"]] == ["1", "2", "3", "4", "5", "6-1", "6-2"]
    assert set(s["calibration"]) == {"drift_deg_h", "drift_applied_deg_h", "scale_factor",
                                     "cross_coupling"}
    assert set(s["truth"]) - {"gyro_drift_deg_h", "integrator_drift_deg_h"} == {
        "drift_deg_h", "scale_factor", "cross_coupling"}
    for part in ("calibration", "truth"):
        assert set(s[part]["cross_coupling"]) == {"roll_into_pitch", "roll_into_yaw",
                                                  "yaw_into_pitch", "yaw_into_roll"}
    assert set(s["truth"]) >= {"gyro_drift_deg_h", "integrator_drift_deg_h"}
    assert s["reference_star"] == s["locked_star"] == "Canopus"
    assert set(s["target"]) >= {"programmed_roll_deg", "programmed_yaw_deg",
                                "pointing_error_arcsec"}
    assert s["propellant_kg"] > 0
    # Truth beside belief: the end, the saturations, the warnings (none here), the journal.
    assert s["end"]["target"] == "Sirius" and s["end"]["true_pointing_error_arcsec"] > 0
    assert s["drift_dac_clipped"] == {"roll": False, "pitch": False, "yaw": False}
    assert s["warnings"] == []
    assert [e["mode"] for e in s["events"] if e["kind"] == "mode_start"] == [
        m["mode"] for m in s["modes"]]
    first, header = tl.read_text().splitlines()[:2]
    assert first.startswith(f"# allsky telemetry format {FORMAT}; rows ")
    assert header.startswith("time [s],mode [-],q_w")


def test_aborted_mission_exit_1(capsys):
    assert main(["run", "--set", "jets.propellant_kg=0.05"]) == 1
    assert "aborted" in capsys.readouterr().out


def test_unwritable_output_exit_2(tmp_path, capsys):
    assert main(["run", "--json", str(tmp_path / "no" / "such" / "dir.json")]) == 2


def test_compare_writes_table_json_and_plot(tmp_path, capsys):
    js, png = tmp_path / "c.json", tmp_path / "c.png"
    assert main(["compare", "--json", str(js), "--plot", str(png)]) == 0
    out = capsys.readouterr().out
    assert "legacy (Modes 4-5)" in out and "dither" in out
    s = json.loads(js.read_text())
    for method in ("legacy", "dither"):
        r = s[method]
        assert set(r["scale_factor_error_ppm"]) == {"roll", "yaw"}
        for k in ("time_s", "max_excursion_arcsec", "propellant_kg", "pointing_error_arcsec"):
            assert isinstance(r[k], float)
    # The legacy turns take the vehicle 180 deg away; the dither stays within arcseconds.
    assert s["legacy"]["max_excursion_arcsec"] > 170 * 3600
    assert s["dither"]["max_excursion_arcsec"] < 120
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_compare_rejects_bad_runs(capsys):
    assert main(["compare", "--runs", "0"]) == 2


def test_console_script_entry_point_resolves():
    """The ``allsky`` command of pyproject.toml names a function that exists."""
    import importlib
    import tomllib
    from pathlib import Path

    meta = tomllib.loads((Path(__file__).resolve().parents[2] / "pyproject.toml").read_text())
    module, func = meta["project"]["scripts"]["allsky"].split(":")
    assert callable(getattr(importlib.import_module(module), func))
