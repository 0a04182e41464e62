"""Scenario loading, overrides and validation (allsky.config)."""

import math
from datetime import UTC, datetime

import pytest

from allsky.config import DEFAULT_SCENARIO_PATH, ConfigError, load_scenario, scenario_from_dict


def err(overrides=(), data=None):
    with pytest.raises(ConfigError) as e:
        if data is not None:
            scenario_from_dict(data, overrides)
        else:
            load_scenario(overrides=overrides)
    return str(e.value)


def test_default_loads_with_units_in_every_key():
    cfg = load_scenario()
    assert cfg.mission.date_utc == datetime(2026, 11, 22, 12, tzinfo=UTC)
    assert cfg.gyro.drift_deg_h == (1.2, -0.8, 1.5)
    assert cfg.target.star == "Sirius" and cfg.target.ra_deg is None
    units = ("_s", "_deg", "_deg_h", "_ppm", "_arcsec", "_kg_m2", "_n", "_m", "_kg", "_v", "_hz",
             "_pps", "_bits", "_frames", "_per_s", "_deg_s", "_rt_h", "_arcsec_s", "_utc",
             "_v_per_arcsec", "_v_per_arcsec_s")
    unitless = {"seed", "attitude", "magnitude_window", "counter_overflow", "star", "apply",
                "filter_gain"}
    for sec, table in cfg.as_dict().items():
        for k in table:
            assert k in unitless or k.endswith(units), f"{sec}.{k} has no unit in its name"


def test_overrides_in_toml_value_syntax():
    cfg = load_scenario(overrides=["gyro.scale_factor_error_ppm=[800,-300,1500]",
                                   "mission.date_utc=2027-03-01T00:00:00Z",
                                   "mission.seed=7", "calibration.apply=false",
                                   "sequencer.timeout_s.6-2=123"])
    assert cfg.gyro.scale_factor_error_ppm == (800.0, -300.0, 1500.0)
    assert cfg.mission.date_utc == datetime(2027, 3, 1, tzinfo=UTC)
    assert cfg.mission.seed == 7 and cfg.calibration.apply is False
    assert cfg.sequencer.timeout_s["6-2"] == 123.0


def test_date_forms():
    iso = load_scenario(overrides=['mission.date_utc="2026-06-21T06:30:00+02:00"'])
    assert iso.mission.date_utc == datetime(2026, 6, 21, 4, 30, tzinfo=UTC)
    local = load_scenario(overrides=["mission.date_utc=2026-06-21T04:30:00"])
    assert local.mission.date_utc == iso.mission.date_utc
    assert "ephemeris range" in err(["mission.date_utc=1850-01-01T00:00:00Z"])
    assert "ISO-8601" in err(['mission.date_utc="yesterday"'])


def test_unknown_key_names_the_nearest():
    msg = err(["gyro.drift_deg_hr=[0,0,0]"])
    assert msg.startswith("gyro.drift_deg_hr") and "gyro.drift_deg_h" in msg
    assert "unknown key" in err(data={"gyros": {"drift_deg_h": [0, 0, 0]}})


def test_target_forms_replace_each_other():
    cfg = load_scenario(overrides=["target.ra_deg=10.5", "target.dec_deg=-20"])
    assert cfg.target.star is None and cfg.target.ra_deg == 10.5
    cfg2 = load_scenario(overrides=["target.ra_deg=10.5", "target.dec_deg=-20",
                                    "target.star=Vega"])
    assert cfg2.target.star == "Vega" and cfg2.target.ra_deg is None
    # A file's target replaces the default's as a whole.
    f = scenario_from_dict({"target": {"ra_deg": 1.0, "dec_deg": 2.0}})
    assert f.target.star is None
    assert "not both" in err(data={"target": {"star": "Vega", "ra_deg": 1.0, "dec_deg": 2.0}})
    assert "both target.ra_deg" in err(data={"target": {"ra_deg": 1.0}})
    assert "Canopus" in err(["target.star=Canopis"])
    assert load_scenario(overrides=["target.star=vega"]).target.star == "Vega"
    assert load_scenario(overrides=["target.star=Vega"]).target.star == "Vega"  # bare word


@pytest.mark.parametrize("override, words", [
    ("gyro.arw_deg_rt_h=-1.0", "must be >= 0"),
    ("gyro.drift_deg_h=[1,2]", "list of 3"),
    ("gyro.drift_deg_h=[1,nan,2]", "finite"),
    ("gyro.drift_deg_h=[1,inf,2]", "finite"),
    ("gyro.drift_deg_h=\"fast\"", "list of 3"),
    ("jets.thrust_n=[0.5,true,0.5]", "number"),
    ("mission.seed=1.5", "integer"),
    ("mission.seed=-1", "between"),
    ("mission.frame_s=0.02", "too coarse for the jet minimum on-time"),
    ("vehicle.inertia_kg_m2=[[100,0,0],[0,-650,0],[0,0,680]]", "positive definite"),
    ("vehicle.inertia_kg_m2=[[100,5,0],[0,650,0],[0,0,680]]", "symmetric"),
    ("vehicle.inertia_kg_m2=[[100,0,0],[0,100,0],[0,0,680]]", "triangle inequality"),
    ("gyro.misalignment_arcsec=[[5,0,0],[0,0,0],[0,0,0]]", "diagonal must be 0"),
    ("gyro.misalignment_arcsec=[[0,4000,0],[0,0,0],[0,0,0]]", "3600"),
    ("electronics.counter_overflow=\"explode\"", "wrap"),
    ("electronics.counter_bits=70", "between"),
    ("pwpf.off_threshold_v=0.01", "below pwpf.on_threshold_v"),
    ("star_tracker.magnitude_window=[1,0]", "brightest < faintest"),
    ("ejection.attitude=[0,0,0,0]", "must not be zero"),
    ("ejection.attitude=\"upside down\"", "random"),
    ("calibration.apply=1", "true or false"),
    ("sequencer.timeout_s.7=10", "mode must be one of"),
    ("sequencer.timeout_s={\"1\"=5}", "exactly the modes"),
    ("target.ra_deg=360", "[0, 360)"),
    ("target.dec_deg=91", "between"),
    ("sun_sensor.presence_half_angle_deg=1", "linear range"),
    ("gyro", "KEY=VALUE"),
    ("a.b.c=1", "SECTION.NAME"),
])
def test_each_rule_names_key_value_and_rule(override, words):
    msg = err([override])
    assert words in msg
    key = override.split("=")[0]
    if "." in key and key != "a.b.c" and not key.startswith("sequencer.timeout_s."):
        assert msg.startswith(key.split("=")[0]), msg


def test_ints_accepted_where_floats_expected():
    cfg = load_scenario(overrides=["jets.propellant_kg=3"])
    assert cfg.jets.propellant_kg == 3.0 and isinstance(cfg.jets.propellant_kg, float)


def test_quaternion_attitude_is_normalised():
    cfg = load_scenario(overrides=["ejection.attitude=[2,0,0,0]"])
    assert cfg.ejection.attitude == (1.0, 0.0, 0.0, 0.0)


def test_round_trip_through_toml(tmp_path):
    cfg = load_scenario(overrides=["target.ra_deg=12.25", "target.dec_deg=-33.5",
                                   "mission.seed=42"])
    p = tmp_path / "resolved.toml"
    p.write_text(cfg.to_toml())
    assert load_scenario(p) == cfg
    assert scenario_from_dict(cfg.as_dict()) == cfg


def test_scenario_is_frozen():
    cfg = load_scenario()
    with pytest.raises(AttributeError):
        cfg.gyro = None
    with pytest.raises(AttributeError):
        cfg.gyro.drift_deg_h = (0, 0, 0)
    with pytest.raises(TypeError):
        cfg.sequencer.timeout_s["1"] = 1.0


def test_files_errors(tmp_path):
    assert "not found" in str(pytest.raises(ConfigError, load_scenario, tmp_path / "x.toml").value)
    bad = tmp_path / "bad.toml"
    bad.write_text("[gyro\n")
    assert "not valid TOML" in str(pytest.raises(ConfigError, load_scenario, bad).value)


def test_packaged_default_path_exists():
    assert DEFAULT_SCENARIO_PATH.is_file()
    assert not math.isnan(load_scenario(DEFAULT_SCENARIO_PATH).mission.frame_s)
