"""Scenario loading, overrides, validation and the frozen result (allsky.config).

Covers the modules of the package through the scenario they build: rules,
schema, toml_io, dispersion_table and scenario.
"""

import math
import pickle
import tomllib
from datetime import UTC, datetime, timedelta
from types import MappingProxyType

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from allsky.config import (
    DEFAULT_SCENARIO_PATH,
    RULES,
    ConfigError,
    Scenario,
    cross_rules,
    load_scenario,
    scenario_from_dict,
    schema,
)
from allsky.config.rules import EPHEMERIS_END_UTC, EPHEMERIS_START_UTC, MODE_KEYS
from allsky.config.toml_io import toml_dumps

DEFAULT = tomllib.loads(DEFAULT_SCENARIO_PATH.read_text())


def error(overrides=(), data=None) -> ConfigError:
    """The ConfigError raised by the default merged with ``data`` and ``overrides``."""
    with pytest.raises(ConfigError) as e:
        scenario_from_dict(data or {}, overrides)
    return e.value


def write(tmp_path, text, name="s.toml"):
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


# -- the default and the schema ---------------------------------------------------

def test_default_loads_with_frozen_types():
    cfg = load_scenario()
    assert isinstance(cfg, Scenario) and cfg == load_scenario(DEFAULT_SCENARIO_PATH)
    assert cfg.mission.date_utc == datetime(2026, 11, 22, 12, tzinfo=UTC)
    assert cfg.mission.date_utc.tzinfo is UTC
    assert cfg.gyro.drift_deg_h == (1.2, -0.8, 1.5)
    assert all(type(x) is float for x in cfg.gyro.drift_deg_h)
    assert cfg.vehicle.inertia_kg_m2[1] == (1.5, 650.0, 2.0)
    assert isinstance(cfg.vehicle.inertia_kg_m2, tuple)
    assert isinstance(cfg.sequencer.timeout_s, MappingProxyType)
    assert dict(cfg.sequencer.timeout_s) == {"1": 900.0, "2": 600.0, "3": 300.0, "4": 600.0,
                                             "5": 900.0, "6-1": 600.0, "6-2": 600.0}
    assert cfg.target.star == "Sirius" and cfg.target.ra_deg is None and cfg.target.dec_deg is None
    assert cfg.ejection.attitude == "random" and cfg.calibration.apply is True
    assert type(cfg.electronics.counter_bits) is int


def test_every_default_key_has_its_unit_in_its_name():
    units = ("_s", "_deg", "_deg_h", "_ppm", "_arcsec", "_kg_m2", "_n", "_m", "_kg", "_v",
             "_pps", "_bits", "_frames", "_per_s", "_deg_s", "_rt_h", "_arcsec_s", "_utc", "_urad",
             "_bar", "_km", "_m2")
    unitless = {"j2", "tle_line1", "tle_line2", "gravity_gradient", "aerodynamic",
                "drag_coefficient", "solar_pressure", "srp_reflectivity",
                "seed", "attitude", "magnitude_window", "counter_overflow", "star", "allocation",
                "reference_star", "apply", "between_targets",
                "filter_gain", "feedforward", "inertia_estimate_scale", "estimator", "detector",
                "store_cross_coupling", "kind", "axes", "unload_fraction",
                "unload_end_fraction", "recovery", "bright_gate", "supply",
                "moving_bodies"}
    for sec, table in DEFAULT.items():
        for k in table:
            assert k in unitless or k.endswith(units), f"{sec}.{k} has no unit in its name"


def test_rule_table_covers_exactly_the_schema():
    schema = {f"{s}.{k}" for s, t in DEFAULT.items() for k in t}
    assert set(RULES) == schema | {"target.ra_deg", "target.dec_deg", "target.sequence"}
    assert set(DEFAULT["sequencer"]["timeout_s"]) == set(MODE_KEYS)


def test_ephemeris_range_matches_sky():
    from allsky.vehicle.sky import EPHEMERIS_YEARS

    assert (EPHEMERIS_START_UTC.year, EPHEMERIS_END_UTC.year) == EPHEMERIS_YEARS


# -- files and overrides ---------------------------------------------------------

def test_file_is_merged_over_the_default(tmp_path):
    p = write(tmp_path, "[gyro]\ndrift_deg_h = [0, 0, 0.5]\n"
                        '[sequencer]\ntimeout_s = { "3" = 30 }\n')
    cfg = load_scenario(p)
    assert cfg.gyro.drift_deg_h == (0.0, 0.0, 0.5)
    assert cfg.gyro.arw_deg_rt_h == 0.001  # from the default
    assert cfg.sequencer.timeout_s["3"] == 30.0 and cfg.sequencer.timeout_s["1"] == 900.0


def test_overrides_in_toml_value_syntax():
    cfg = load_scenario(overrides=["gyro.scale_factor_error_ppm=[800,-300,1500]",
                                   "mission.date_utc=2027-03-01T00:00:00Z",
                                   'target.star="Vega"', "mission.seed=7",
                                   "calibration.apply=false", "sequencer.timeout_s.6-1=123",
                                   'sequencer.timeout_s={ "2" = 50 }',
                                   "jets={ isp_s = 70, propellant_kg = 3 }"])
    assert cfg.gyro.scale_factor_error_ppm == (800.0, -300.0, 1500.0)
    assert cfg.mission.date_utc == datetime(2027, 3, 1, tzinfo=UTC)
    assert cfg.target.star == "Vega" and cfg.mission.seed == 7 and cfg.calibration.apply is False
    assert cfg.sequencer.timeout_s["6-1"] == 123.0 and cfg.sequencer.timeout_s["2"] == 50.0
    assert (cfg.jets.isp_s, cfg.jets.propellant_kg, cfg.jets.min_on_time_s) == (70.0, 3.0, 0.01)


def test_override_bare_word_is_a_string():
    assert load_scenario(overrides=["target.star=Vega"]).target.star == "Vega"
    assert load_scenario(overrides=["target.star=Rigil Kentaurus"]).target.star == \
        "Rigil Kentaurus"
    assert load_scenario(overrides=["electronics.counter_overflow=saturate"]
                         ).electronics.counter_overflow == "saturate"


def test_overrides_apply_after_the_file_in_order(tmp_path):
    p = write(tmp_path, "[mission]\nseed = 5\n")
    assert load_scenario(p, ["mission.seed=6", "mission.seed=9"]).mission.seed == 9
    assert load_scenario(p, "mission.seed=8").mission.seed == 8  # one string, not characters


@pytest.mark.parametrize("item, words", [
    ("gyro", "must be KEY=VALUE"),
    ("=1", "dotted path"),
    ("a..b=1", "dotted path"),
    ("gyro drift=1", "dotted path"),
])
def test_malformed_override(item, words):
    assert words in str(error([item]))


@pytest.mark.parametrize("where, key, nearest", [
    (["gyro.drift_deg_hr=[0,0,0]"], "gyro.drift_deg_hr", "gyro.drift_deg_h"),
    (["gyro.inertia_kg_m2=1"], "gyro.inertia_kg_m2", "vehicle.inertia_kg_m2"),
    (["gyros.arw_deg_rt_h=1"], "gyros", "gyro"),
    (["sequencer.timeout_s.6-3=1"], "sequencer.timeout_s.6-3", "sequencer.timeout_s.6-2"),
    ({"jet": {"isp_s": 60}}, "jet", "jets"),
    ({"star_tracker": {"fov_long_deg": 10}}, "star_tracker.fov_long_deg",
     "star_tracker.fov_long_half_deg"),
])
def test_unknown_key_names_the_nearest(where, key, nearest):
    e = error(where) if isinstance(where, list) else error(data=where)
    assert e.key == key
    assert str(e).startswith(f"{key}: unknown key") and nearest in str(e)


def test_unknown_key_without_a_near_one_lists_the_valid_ones():
    assert "valid keys here: arw_deg_rt_h" in str(error(["gyro.zzzzzzzz=1"]))
    assert "valid sections: mission, ejection" in str(error(["qqqqq.x=1"]))


def test_section_must_be_a_table():
    e = error(data={"gyro": 5})
    assert (e.key, e.rule) == ("gyro", "must be a table, not an integer")
    assert "must be a table" in str(error(["sequencer.timeout_s=5"]))


# -- ConfigError -----------------------------------------------------------------

def test_config_error_is_one_line_key_value_rule():
    e = error(["gyro.arw_deg_rt_h=-1.0"])
    assert str(e) == "gyro.arw_deg_rt_h = -1.0: must be >= 0"
    assert (e.key, e.value, e.rule) == ("gyro.arw_deg_rt_h", -1.0, "must be >= 0")
    assert pickle.loads(pickle.dumps(e)).args == e.args
    assert str(pickle.loads(pickle.dumps(error(["target.ra_deg=1"])))) == \
        ("target.dec_deg: missing: give target.star, both target.ra_deg and target.dec_deg, "
         "or target.sequence")
    assert "\n" not in str(error(['target.star="Ve\nga"']))
    assert "\n" not in str(error(data={"a\nb": {}}))


def test_config_error_with_rule_keeps_key_and_value():
    shown = error(["gyro.arw_deg_rt_h=-1"]).with_rule("must be >= 0 (drawn)")
    assert str(shown) == "gyro.arw_deg_rt_h = -1.0: must be >= 0 (drawn)"
    hidden = error(["target.ra_deg=1"]).with_rule("missing (drawn)")
    assert str(hidden) == "target.dec_deg: missing (drawn)" and hidden.value is None
    assert pickle.loads(pickle.dumps(hidden)).args == hidden.args


# -- one test per rule -----------------------------------------------------------

RULE_CASES = [
    # types
    ("jets.isp_s", "true", "must be a number, not a boolean"),
    ("jets.isp_s", '"65"', "must be a number, not a string"),
    ("jets.isp_s", "[65]", "must be a number, not an array"),
    ("jets.isp_s", "nan", "must be finite"),
    ("jets.isp_s", "inf", "must be finite"),
    ("jets.isp_s", "-inf", "must be finite"),
    ("jets.isp_s", "1" + "0" * 400, "must be finite"),
    ("gyro.drift_deg_h", "[1, 2]", "must be an array of 3 numbers, not 2 elements"),
    ("gyro.drift_deg_h", "[1, 2, 3, 4]", "must be an array of 3 numbers, not 4 elements"),
    ("gyro.drift_deg_h", '"fast"', "must be an array of 3 numbers, not a string"),
    ("gyro.drift_deg_h", "[1, nan, 2]", "element 1 must be finite"),
    ("gyro.drift_deg_h", "[1, 2, -inf]", "element 2 must be finite"),
    ("jets.thrust_n", "[0.5, true, 0.5]", "element 1 must be a number, not a boolean"),
    # mission
    ("mission.seed", "1.5", "must be an integer, not a float"),
    ("mission.seed", "true", "must be an integer, not a boolean"),
    ("mission.seed", "-1", "must be in [0, 4294967295] (2**32 - 1"),
    ("mission.seed", str(2**32), "must be in [0, 4294967295] (2**32 - 1"),
    ("mission.frame_s", "0", "must be >= 0.0001"),
    ("mission.frame_s", "1e-12", "must be >= 0.0001 (a hundredth of the default 10 ms valve"),
    ("mission.frame_s", "1e-300", "must be >= 0.0001"),
    ("mission.frame_s", "0.02", "frame too coarse for the jet minimum on-time"),
    ("mission.telemetry_every_frames", "0", "must be in [1, 100000000]"),
    ("mission.telemetry_every_frames", "2.0", "must be an integer"),
    ("mission.telemetry_every_frames", "100000001", "must be in [1, 100000000] (the most frames"),
    ("mission.date_utc", "1899-12-31T23:59:59Z", "ephemeris range 1900-01-01..2100-12-31"),
    ("mission.date_utc", "2101-01-01T00:00:00Z", "ephemeris range"),
    # the default's longest mission, 4500 s, must end by 2100-12-31T23:59:59.999999Z
    ("mission.date_utc", "2100-12-31T23:00:00Z", ("must be <= 2100-12-31T22:44:59.999999Z: the "
                                                 "mission would end after the ephemeris range")),
    ("mission.date_utc", "2100-12-31T23:30:00-01:00", "ephemeris range"),  # 2101 in UTC
    ("mission.date_utc", "0001-01-01T00:00:00+01:00", "ephemeris range"),
    ("mission.date_utc", '"yesterday"', "must be an ISO-8601 date-time"),
    ("mission.date_utc", "12:00:00", "not a time"),
    ("mission.date_utc", "2026", "not an integer"),
    # ejection
    ("ejection.attitude", '"upside down"', 'must be "random" or a quaternion'),
    ("ejection.attitude", "[0, 0, 0, 0]", "must not be all zero"),
    ("ejection.attitude", "[1, 0, 0]", "array of 4 numbers"),
    ("ejection.attitude", "[1, 0, nan, 0]", "element 2 must be finite"),
    ("ejection.tipoff_rate_max_deg_s", "-0.1", "must be >= 0"),
    # vehicle
    ("vehicle.inertia_kg_m2", "[[100,5,0],[0,650,0],[0,0,680]]", "must be symmetric"),
    ("vehicle.inertia_kg_m2", "[[100,0,0],[0,-650,0],[0,0,680]]", "must be positive definite"),
    ("vehicle.inertia_kg_m2", "[[0,0,0],[0,0,0],[0,0,0]]", "must be positive definite"),
    ("vehicle.inertia_kg_m2", "[[1,1,0],[1,1,0],[0,0,1]]", "must be positive definite"),
    ("vehicle.inertia_kg_m2", "[[100,0,0],[0,100,0],[0,0,680]]", "triangle inequality"),
    ("vehicle.inertia_kg_m2", "[[100,0],[0,100],[0,0]]", "3x3 array"),
    ("vehicle.inertia_kg_m2", "[[1e308,1e308,0],[1e308,1e308,0],[0,0,1e308]]",
     "positive definite"),
    # gyro
    ("gyro.misalignment_arcsec", "[[5,0,0],[0,0,0],[0,0,0]]",
     "diagonal must be 0: scale-factor error is set by gyro.scale_factor_error_ppm"),
    ("gyro.misalignment_arcsec", "[[0,3600.5,0],[0,0,0],[0,0,0]]", "<= 3600 arcsec"),
    ("gyro.scale_factor_error_ppm", "[0, -100001, 0]", "element 1 magnitude must be <= 100000"),
    ("gyro.arw_deg_rt_h", "-1e-9", "must be >= 0"),
    ("gyro.rrw_deg_h_rt_h", "-1", "must be >= 0"),
    ("gyro.range_deg_s", "0", "must be > 0"),
    # sun sensor
    ("sun_sensor.linear_range_arcsec", "0", "must be > 0"),
    ("sun_sensor.presence_half_angle_deg", "0", "must be in (0, 90]"),
    ("sun_sensor.presence_half_angle_deg", "90.5", "must be in (0, 90]"),
    ("sun_sensor.presence_half_angle_deg", "1.5", "must be >= the sun sensor linear range"),
    ("sun_sensor.noise_arcsec", "-0.5", "must be >= 0"),
    ("sun_sensor.coarse_noise_deg", "-0.5", "must be >= 0"),
    # star tracker
    ("star_tracker.fov_long_half_deg", "0", "must be in (0, 90)"),
    ("star_tracker.fov_narrow_half_deg", "90", "must be in (0, 90)"),
    ("star_tracker.magnitude_window", "[1, 0]", "brightest < faintest"),
    ("star_tracker.magnitude_window", "[1, 1]", "brightest < faintest"),
    ("star_tracker.magnitude_window", "[1]", "array of 2 numbers"),
    ("star_tracker.noise_arcsec", "-2", "must be >= 0"),
    ("star_tracker.cone_angle_check_deg", "-1", "must be in [0, 90] (0 = no check)"),
    ("star_tracker.bright_gate", "1", "must be true or false"),
    # jets
    ("jets.thrust_n", "[0.25, 0, 0.5]", "element 1 must be > 0"),
    ("jets.moment_arm_m", "[0.5, 1.25, -1]", "element 2 must be > 0"),
    ("jets.min_on_time_s", "0", "must be in (0, 1]"),
    ("jets.min_on_time_s", "1e300", "must be in (0, 1] (cold-gas valves"),
    ("jets.isp_s", "-65", "must be > 0"),
    ("jets.propellant_kg", "0", "must be > 0"),
    ("jets.supply", '"pressure-fed"', 'must be "regulated" or "blowdown"'),
    ("jets.tank_pressure_initial_bar", "0", "must be > 0"),
    ("jets.tank_pressure_final_bar", "20", "must be < jets.tank_pressure_initial_bar (20 bar)"),
    # pwpf
    ("pwpf.filter_gain", "0", "must be > 0"),
    ("pwpf.time_constant_s", "0", "must be > 0"),
    ("pwpf.on_threshold_v", "0", "must be > 0"),
    ("pwpf.off_threshold_v", "-0.0001", "must be >= 0"),
    ("pwpf.off_threshold_v", "0.001", "must be < pwpf.on_threshold_v"),
    ("pwpf.full_on_v", "0", "must be > 0"),
    # control
    ("control.position_gain_v_per_arcsec", "[1e-3, 0, 1e-3]", "element 1 must be > 0"),
    ("control.rate_gain_v_per_arcsec_s", "[-5e-4, 5e-4, 5e-4]", "element 0 must be > 0"),
    ("control.position_limit_arcsec", "[500, 400, 0]", "element 2 must be > 0"),
    ("control.output_limit_v", "0", "must be > 0"),
    ("control.integral_time_s", "0", "must be > 0"),
    ("control.integral_limit_arcsec", "0", "must be > 0"),
    # electronics
    ("electronics.vfc_pulse_weight_arcsec", "0", "must be in (0, 3600]"),
    ("electronics.vfc_pulse_weight_arcsec", "1e12", "must be in (0, 3600] (1 deg: a 360 deg"),
    ("electronics.vfc_max_rate_pps", "0", "must be > 0"),
    # 1.5 deg/s = 5400 arcsec/s of turn over 0.1 arcsec pulses: 54000 pulses/s
    ("electronics.vfc_max_rate_pps", "54000", "must be > 54000: converters 8, 10, 12 saturate"),
    ("electronics.counter_bits", "7", "must be in [8, 62]"),
    ("electronics.counter_bits", "63", "must be in [8, 62]"),
    ("electronics.counter_bits", "28.0", "must be an integer"),
    ("electronics.drift_counter_bits", "3", "must be in [4, 62]"),
    ("electronics.drift_dac_bits", "33", "must be in [4, 32]"),
    ("electronics.register_bits", "3", "must be in [4, 32]"),
    ("electronics.counter_overflow", '"explode"', 'must be "wrap" or "saturate"'),
    ("electronics.counter_overflow", "1", 'must be "wrap" or "saturate"'),
    ("electronics.register_lsb_arcsec", "0", "must be > 0"),
    ("electronics.rate_command_deg_s", "0", "must be > 0"),
    ("electronics.computer_step_frames", "0", "must be in [1, 100000000]"),
    ("electronics.computer_step_frames", str(2**62), "must be in [1, 100000000]"),
    # sequencer
    ("sequencer.settle_threshold_arcsec", "0", "must be > 0"),
    ("sequencer.settle_time_s", "0", "must be > 0"),
    ("sequencer.handover_arcsec", "0", "must be > 0"),
    ("sequencer.drift_count_s", "0", "must be in (0, 86400]"),
    ("sequencer.tracker_blanking_s", "0", "must be > 0"),
    ("sequencer.sensor_loss_s", "0", "must be > 0"),
    ("sequencer.mode1_slew_rate_deg_s", "0", "must be > 0"),
    ("sequencer.mode1_slew_gain_per_s", "0", "must be > 0"),
    ("sequencer.turn_check_ppm", "-1", "must be in [0, 500000] (half a turn"),
    ("sequencer.turn_check_ppm", "500001", "must be in [0, 500000]"),
    ("sequencer.timeout_s.6-1", "0", "must be in (0, 86400] (a mission lasts at most a day)"),
    ("sequencer.timeout_s.1", "1e12", "must be in (0, 86400]"),
    ("sequencer.timeout_s.1", '"long"', "must be a number"),
    # the integrator drift of each chain into converters 8/10/12
    ("electronics.integrator_drift_deg_h", "[0, 101, 0]",
     "element 1 must be in [-100, 100] (an amplifier offset this large is a failed chain"),
    ("electronics.integrator_drift_deg_h", "[0, 0]", "3"),
    # the planned reference star: in the catalog, and inside the magnitude window
    # (Sirius V = -1.44, PyEphem's catalog; the default window is [-1.0, -0.3])
    ("star_tracker.reference_star", "Canopis", "not in the PyEphem star catalog; nearest: Canopus"),
    ("star_tracker.reference_star", "Sirius",
     "magnitude -1.44 is outside star_tracker.magnitude_window [-1, -0.3]"),
    # target
    ("target.star", "Canopis", "not in the PyEphem star catalog; nearest: Canopus"),
    ("target.star", "42", "must be a star name (a string), not an integer"),
    # calibration
    ("calibration.apply", "1", "must be true or false, not an integer"),
    ("calibration.apply", '"yes"', "must be true or false, not a string"),
    # dither (the comparison mode)
    ("dither.amplitude_urad", "[100, -1, 100]", "element 1 must be >= 0"),
    ("dither.period_s", "[51.2, 0, 25.6]", "element 1 must be > 0"),
    ("dither.period_s", "[51.2, 51.2, 0.15]", "element 2 must be > 2 x dither.sample_s"),
    ("dither.sample_s", "0", "must be in (0, 86400]"),
    ("dither.sample_s", "0.001", "must be >= mission.frame_s"),
    ("dither.sample_s", "0.015", "must be a whole number of frames (mission.frame_s = 0.01 s)"),
    ("dither.record_s", "0", "must be in (0, 86400]"),
    ("dither.record_s", "1e6", "must be in (0, 86400]"),
    # 1640 periods of 51.2 s: the dither plan takes 3000 + 51.2 + 83968 + 300 s
    ("dither.record_s", "83968", "the dither plan would take 87319.2 s"),
    ("dither.period_s", "[1000, 51.2, 25.6]", "element 0 must be <= dither.record_s (819.2 s)"),
    ("dither.period_s", "[50, 51.2, 25.6]", "element 0 goes 16.384 times into dither.record_s"),
    ("dither.lead_in_s", "-1", "must be in [0, 86400]"),
    ("dither.feedforward", "0", "must be true or false"),
    ("dither.inertia_estimate_scale", "-0.1", "must be >= 0"),
    ("dither.estimator", '"guess"', 'must be "optical" or "command"'),
    ("dither.detector", '"fit"', 'must be "fft", "hann" or "lsq"'),
    ("dither.store_cross_coupling", '"no"', "must be true or false"),
]


@pytest.mark.parametrize("key, value, words", RULE_CASES)
def test_each_rule_names_key_value_and_rule(key, value, words):
    e = error([f"{key}={value}"])
    assert e.key == key
    assert str(e).startswith(f"{key} = ") and words in str(e), str(e)


@pytest.mark.parametrize("target, words", [
    (["target.ra_deg=360", "target.dec_deg=0"], "target.ra_deg = 360.0: must be in [0, 360)"),
    (["target.ra_deg=-0.5", "target.dec_deg=0"], "target.ra_deg = -0.5: must be in [0, 360)"),
    (["target.ra_deg=10", "target.dec_deg=90.5"], "target.dec_deg = 90.5: must be in [-90, 90]"),
    (["target.ra_deg=10", "target.dec_deg=-91"], "target.dec_deg = -91.0: must be in [-90, 90]"),
])
def test_target_coordinate_ranges(target, words):
    assert str(error(target)) == words


@pytest.mark.parametrize("override", [
    "mission.seed=4294967295", "mission.seed=0", "mission.frame_s=0.005",
    "mission.date_utc=1900-01-01T00:00:00Z", "mission.date_utc=2100-12-31T22:44:59Z",
    "mission.telemetry_every_frames=100000000",
    "jets.min_on_time_s=1", "electronics.vfc_pulse_weight_arcsec=3600",
    "electronics.vfc_max_rate_pps=54001", "dither.sample_s=0.02",  # whole frames
    "dither.period_s=[51.2, 50, 25.6]",  # pitch's period: pitch is not dithered
    "sequencer.timeout_s.1=82800",  # 82800 + 3600 = 86400 s, a day
    "gyro.misalignment_arcsec=[[0,3600,-3600],[0,0,0],[0,0,0]]",
    "gyro.scale_factor_error_ppm=[100000,-100000,0]", "gyro.arw_deg_rt_h=0",
    "ejection.tipoff_rate_max_deg_s=0", "pwpf.off_threshold_v=0",
    "sun_sensor.presence_half_angle_deg=90", "sun_sensor.presence_half_angle_deg=2",
    "star_tracker.fov_long_half_deg=89.99", "electronics.counter_bits=62",
    "electronics.register_bits=4", "vehicle.inertia_kg_m2=[[1,0,0],[0,1,0],[0,0,2]]",
    "vehicle.inertia_kg_m2=[[100,0,0],[0,650,1e-8],[0,0,680]]",  # asymmetry below 1e-9 relative
    "dither.amplitude_urad=[100,0,100]", "dither.period_s=[51.2,0.1,25.6]",  # pitch not dithered
    "dither.inertia_estimate_scale=0",
])
def test_values_at_the_edge_of_a_rule_are_accepted(override):
    load_scenario(overrides=[override])


# -- what a mission costs, and how long the ephemeris serves it ------------------------------

def test_frame_count_of_the_longest_mission_is_bounded():
    # 10000 s + the six other modes' 3600 s over 0.1 ms frames: 1.36e8 frames
    e = error(["mission.frame_s=1e-4", "mission.telemetry_every_frames=1000",
               "sequencer.timeout_s.1=10000"])
    assert e.key == "mission.frame_s"
    assert str(e) == ("mission.frame_s = 0.0001: the longest mission (13600 s) would take "
                      "1.36e+08 frames; must be >= 0.000136 s (at most 1e+08 frames, about 40 s "
                      "of computing)")
    load_scenario(overrides=["mission.frame_s=0.0002", "mission.telemetry_every_frames=1000",
                             "sequencer.timeout_s.1=10000"])  # 6.8e7 frames


def test_telemetry_rows_of_the_longest_mission_are_bounded():
    # The default's 4500 s at 0.1 ms frames: 4.5e7 frames, 4.5e6 rows at every 10th
    e = error(["mission.frame_s=1e-4"])
    assert str(e) == ("mission.telemetry_every_frames = 10: the longest mission (4.5e+07 frames) "
                      "would record 4.5e+06 telemetry rows; must be >= 45 (at most 1e+06 rows, "
                      "320 MB)")
    load_scenario(overrides=["mission.frame_s=1e-4", "mission.telemetry_every_frames=45"])


def test_the_mission_lasts_at_most_a_day():
    e = error(["sequencer.timeout_s.1=86000"])  # + the six other modes' 3600 s
    assert e.key == "sequencer.timeout_s"
    assert "the modes' timeouts add up to 89600 s; a mission must fit in 86400 s" in str(e)


def test_dither_record_samples_are_bounded():
    # 0.01 s samples over 51.2 + 20480 s: 2053120 samples, more than 2^20; the most
    # record is 2^20 x 0.01 s - 51.2 s = 10434.56 s
    e = error(["dither.sample_s=0.01", "dither.record_s=20480"])
    assert e.key == "dither.record_s" and "2.053e+06 samples" in str(e)
    assert "must be <= 10434.6 s (at most 2^20 = 1048576 samples)" in str(e)


def test_longest_mission_is_what_the_mode_table_allows():
    """The schema's plan durations agree with the mode table the sequencer flies."""
    from allsky.sequencer import modes

    assert schema.DITHER_SETTLE_ALLOWANCE_S == modes.DITHER_SETTLE_ALLOWANCE_S
    for overrides in ([], ["dither.record_s=409.6", "sequencer.timeout_s.5=50"],
                      ["dither.lead_in_s=5000"]):
        cfg = load_scenario(overrides=overrides)
        flat = {f"{sec}.{k}": getattr(getattr(cfg, sec), k) for sec, k in
                (key.split(".") for key in RULES)}
        table = {name: sum(modes.timeout_s(cfg, m) for m in plan)
                 for name, plan in modes.PLANS.items()}
        assert cross_rules.plan_durations_s(flat) == pytest.approx(table, rel=1e-15)


def test_the_last_start_date_is_where_the_ephemeris_stops():
    """The last date accepted builds a mission; a second later the ephemeris refuses it."""
    from allsky.sim.mission import build_params
    from allsky.vehicle import sky

    # Timeouts of 10 s: the longest mission (the dither plan's 1220.4 s) is shorter than the
    # hour over which the Sun's rate is taken, so that hour sets the last start.
    short = [f"sequencer.timeout_s.{m}=10" for m in MODE_KEYS]
    last = EPHEMERIS_END_UTC - timedelta(seconds=schema.SUN_RATE_SPAN_S)
    cfg = load_scenario(overrides=[*short, f"mission.date_utc={last.isoformat()}"])
    build_params(cfg)  # the Sun at the start and an hour later
    later = last + timedelta(seconds=1)
    e = error([*short, f"mission.date_utc={later.isoformat()}"])
    assert e.key == "mission.date_utc" and "must be <= 2100-12-31T22:59:59.999999Z" in str(e)
    with pytest.raises(ValueError, match="outside the ephemeris range"):
        sky.sun_direction_inertial(later + timedelta(seconds=schema.SUN_RATE_SPAN_S))


def test_a_day_of_linear_sun_stays_near_the_ephemeris():
    """The frame loop's Sun (a line from its place and rate at the start) over MISSION_MAX_S."""
    from allsky.sim.mission import build_params
    from allsky.vehicle import sky

    for date in ("2026-01-03T00:00:00Z", "2026-07-04T00:00:00Z", "2026-11-22T12:00:00Z"):
        cfg = load_scenario(overrides=[f"mission.date_utc={date}"])
        p = build_params(cfg)
        line = p.sun0_inertial + p.sun_rate_inertial * schema.MISSION_MAX_S
        truth = sky.sun_direction_inertial(cfg.mission.date_utc
                                           + timedelta(seconds=schema.MISSION_MAX_S))
        assert sky.separation_deg(line / math.hypot(*line), truth) * 3600 < 1.4


@pytest.mark.parametrize("digits", [4301, 100_000])
def test_integers_too_long_to_read_are_refused_by_the_rule(tmp_path, digits):
    big = "9" * digits
    words = f"({digits} digits): must be in [0, 4294967295] (2**32 - 1: 32-bit seeds)"
    e = error([f"mission.seed={big}"])
    assert e.key == "mission.seed" and str(e).endswith(words) and len(str(e)) < 300
    assert str(error([f"mission.seed=-{big}"])).endswith(words)
    with pytest.raises(ConfigError) as in_file:
        load_scenario(write(tmp_path, f"[mission]\nseed = {big}  # a comment\n"))
    assert str(in_file.value) == str(e)
    assert str(error([f"jets.isp_s={big}"])).endswith("digits): must be finite")
    assert "element 1 must be finite" in str(error([f"gyro.drift_deg_h=[1, {big}, 2]"]))


def test_hexadecimal_integers_too_long_to_print_are_shown_by_their_size():
    e = error(["mission.seed=0x" + "f" * 10_000])  # 40000 bits: about 12042 decimal digits
    assert str(e) == ("mission.seed = an integer of about 12042 digits: must be in "
                      "[0, 4294967295] (2**32 - 1: 32-bit seeds)")
    assert "must be finite" in str(error(["gyro.drift_deg_h=[1, 0x" + "f" * 10_000 + ", 2]"]))


def test_ints_accepted_where_floats_expected():
    cfg = load_scenario(overrides=["jets.propellant_kg=3", "gyro.drift_deg_h=[1, 0, -1]"])
    assert type(cfg.jets.propellant_kg) is float and cfg.gyro.drift_deg_h == (1.0, 0.0, -1.0)
    assert all(type(x) is float for x in cfg.gyro.drift_deg_h)


def test_inertia_stored_exactly_symmetric():
    j = "[[100, 2, 0], [2.0000000001, 650, 0], [0, 0, 680]]"
    cfg = load_scenario(overrides=[f"vehicle.inertia_kg_m2={j}"])
    j = cfg.vehicle.inertia_kg_m2
    assert all(j[r][k] == j[k][r] for r in range(3) for k in range(3))


def test_quaternion_attitude_is_normalised():
    assert load_scenario(overrides=["ejection.attitude=[2,0,0,0]"]).ejection.attitude == \
        (1.0, 0.0, 0.0, 0.0)
    q = load_scenario(overrides=["ejection.attitude=[1,2,3,4]"]).ejection.attitude
    assert math.isclose(math.fsum(x * x for x in q), 1.0, rel_tol=1e-15)
    assert q[0] < q[1] < q[2] < q[3]  # order [w, x, y, z] kept
    for tiny_or_huge in ("[1e-320, 0, 0, 0]", "[1e308, 1e308, 1e308, 1e308]"):
        q = load_scenario(overrides=[f"ejection.attitude={tiny_or_huge}"]).ejection.attitude
        assert math.isclose(math.fsum(x * x for x in q), 1.0, rel_tol=1e-15)


# -- the target form -------------------------------------------------------------

def test_target_radec_override_replaces_the_star():
    cfg = load_scenario(overrides=["target.ra_deg=10.5", "target.dec_deg=-20"])
    assert (cfg.target.star, cfg.target.ra_deg, cfg.target.dec_deg) == (None, 10.5, -20.0)


def test_target_star_override_replaces_radec(tmp_path):
    p = write(tmp_path, "[target]\nra_deg = 1.0\ndec_deg = 2.0\n")
    cfg = load_scenario(p, ["target.star=vega"])
    assert (cfg.target.star, cfg.target.ra_deg, cfg.target.dec_deg) == ("Vega", None, None)


def test_file_radec_replaces_the_default_star(tmp_path):
    cfg = load_scenario(write(tmp_path, "[target]\nra_deg = 1.0\ndec_deg = 2.0\n"))
    assert (cfg.target.star, cfg.target.ra_deg, cfg.target.dec_deg) == (None, 1.0, 2.0)


def test_file_with_both_target_forms_is_an_error(tmp_path):
    p = write(tmp_path, '[target]\nstar = "Vega"\nra_deg = 1.0\ndec_deg = 2.0\n')
    with pytest.raises(ConfigError, match=r"set either target\.star or target\.ra_deg"):
        load_scenario(p)
    assert "not both" in str(error(['target={ star = "Vega", ra_deg = 1 }']))


def test_half_a_radec_target_is_an_error():
    e = error(["target.ra_deg=10"])
    assert e.key == "target.dec_deg" and "missing" in str(e)
    assert error(["target.ra_deg=10", "target.dec_deg=5", "target.star=Vega",
                  "target.dec_deg=6"]).key == "target.ra_deg"


def test_star_names_are_case_insensitive():
    assert load_scenario(overrides=["target.star= cAnOpUs "]).target.star == "Canopus"


# -- dates -----------------------------------------------------------------------

@pytest.mark.parametrize("value", [
    "2026-06-21T04:30:00Z",                # TOML offset date-time
    "2026-06-21T06:30:00+02:00",           # another offset
    "2026-06-21T04:30:00",                 # TOML local date-time: read as UTC
    "2026-06-21 04:30:00Z",                # TOML allows a space
    '"2026-06-21T04:30:00Z"',              # ISO-8601 strings
    '"2026-06-21T00:30:00-04:00"',
    '"2026-06-21T04:30:00"',
])
def test_date_forms(value):
    d = load_scenario(overrides=[f"mission.date_utc={value}"]).mission.date_utc
    assert d == datetime(2026, 6, 21, 4, 30, tzinfo=UTC) and d.tzinfo is UTC


def test_date_only_means_midnight_utc():
    for value in ("2026-06-21", '"2026-06-21"'):
        d = load_scenario(overrides=[f"mission.date_utc={value}"]).mission.date_utc
        assert d == datetime(2026, 6, 21, tzinfo=UTC)


# -- the frozen result and its text forms ---------------------------------------

def test_scenario_is_immutable():
    cfg = load_scenario()
    with pytest.raises(AttributeError):
        cfg.gyro = None
    with pytest.raises(AttributeError):
        del cfg.gyro
    with pytest.raises(AttributeError):
        cfg.gyro.drift_deg_h = (0.0, 0.0, 0.0)
    with pytest.raises(AttributeError):
        cfg.gyro.new_key = 1
    with pytest.raises(TypeError):
        cfg.sequencer.timeout_s["1"] = 1.0
    with pytest.raises(TypeError):
        cfg.vehicle.inertia_kg_m2[0][0] = 1.0
    with pytest.raises(AttributeError, match="no key 'drift'"):
        cfg.gyro.drift  # noqa: B018
    with pytest.raises(AttributeError, match=r"no section \[gyros\]"):
        cfg.gyros  # noqa: B018
    cfg.as_dict()["gyro"]["drift_deg_h"][0] = 99.0  # a copy
    assert cfg.gyro.drift_deg_h[0] == 1.2


def test_scenario_pickles():
    cfg = load_scenario(overrides=["target.ra_deg=1", "target.dec_deg=2"])
    assert pickle.loads(pickle.dumps(cfg)) == cfg


def test_as_dict_is_plain():
    d = load_scenario().as_dict()
    assert d["mission"]["date_utc"] == "2026-11-22T12:00:00Z"
    assert d["vehicle"]["inertia_kg_m2"][0] == [100.0, 1.5, -1.0]
    assert type(d["sequencer"]["timeout_s"]) is dict
    assert d["target"] == {"star": "Sirius", "hold_s": 0.0}


ROUND_TRIP_OVERRIDES = [
    [],
    ["target.ra_deg=12.25", "target.dec_deg=-33.5", "mission.seed=42",
     "ejection.attitude=[1,2,3,4]", "mission.date_utc=2030-01-02T03:04:05.123456+01:00",
     "gyro.drift_deg_h=[1e-300, -0.1, 3e5]", "electronics.counter_overflow=saturate"],
]


@pytest.mark.parametrize("overrides", ROUND_TRIP_OVERRIDES)
def test_to_toml_round_trip(tmp_path, overrides):
    cfg = load_scenario(overrides=overrides)
    text = cfg.to_toml()
    assert tomllib.loads(text)  # valid TOML
    again = load_scenario(write(tmp_path, text))
    assert again == cfg and again.to_toml() == text
    assert scenario_from_dict(cfg.as_dict()) == cfg


toml_scalars = st.one_of(
    st.booleans(), st.integers(-2**63, 2**63 - 1), st.floats(allow_nan=False), st.text(),
    st.datetimes(timezones=st.just(UTC)), st.dates())
toml_values = st.recursive(
    toml_scalars,
    lambda inner: st.one_of(st.lists(inner, max_size=4),
                            st.dictionaries(st.text(max_size=6), inner, max_size=4)),
    max_leaves=10)


@settings(max_examples=100, deadline=None)
@given(st.dictionaries(st.text(min_size=1, max_size=8),
                       st.dictionaries(st.text(max_size=8), toml_values, max_size=4),
                       max_size=4))
def test_toml_writer_round_trips(doc):
    assert tomllib.loads(toml_dumps(doc)) == doc


# -- files that cannot be used ----------------------------------------------------

def test_missing_file(tmp_path):
    with pytest.raises(ConfigError) as info:
        load_scenario(tmp_path / "x.toml")
    e = info.value
    assert e.key is None and str(e) == f"scenario file not found: {tmp_path / 'x.toml'}"


@pytest.mark.parametrize("what", ["directory", "latin1", "nul"])
def test_unreadable_files(tmp_path, what):
    p = tmp_path / "latin1.toml"
    p.write_bytes(b'[target]\nstar = "\xe9"\n')
    path = {"directory": tmp_path, "latin1": p, "nul": "a\0b"}[what]
    with pytest.raises(ConfigError, match="cannot read scenario file"):
        load_scenario(path)


def test_toml_syntax_error_gives_the_line(tmp_path):
    p = write(tmp_path, "[gyro]\narw_deg_rt_h = 0.001\nrange_deg_s = \n")
    with pytest.raises(ConfigError) as info:
        load_scenario(p)
    assert str(info.value).startswith(f"{p}: TOML syntax error") and "line 3" in str(info.value)
    deep = write(tmp_path, "x = " + "[" * 5000, "deep.toml")
    with pytest.raises(ConfigError, match="nested too deeply"):
        load_scenario(deep)


@pytest.mark.parametrize("text", [
    "[" + ".".join(["a"] * 20000) + "]\n",  # a table header: tomllib reads it without recursion
    "x = " + "[" * 100 + "]" * 100 + "\n",  # within tomllib's bound, past the scenario's
    "a." * 5000 + "b = 1\n",  # a dotted key
])
def test_toml_nesting_is_bounded_for_headers_and_dotted_keys(tmp_path, text):
    from allsky.config.toml_io import TOML_MAX_DEPTH

    p = write(tmp_path, text, "deep.toml")
    with pytest.raises(ConfigError, match=f"nested too deeply \\(over {TOML_MAX_DEPTH}"):
        load_scenario(p)


def test_scenario_from_dict_rejects_non_tables():
    with pytest.raises(ConfigError, match="table of sections"):
        scenario_from_dict([1])


def test_reference_star_inside_a_wider_window_is_accepted_in_catalog_spelling():
    # Sirius (V = -1.44) passes a window opened to -1.5.
    cfg = load_scenario(overrides=["star_tracker.magnitude_window=[-1.5, -0.3]",
                                   'star_tracker.reference_star="sirius"'])
    assert cfg.star_tracker.reference_star == "Sirius"


def test_symmetric_eigenvalues_match_numpys():
    """The closed form that validates inertia tensors and wheel arrays without NumPy."""
    import numpy as np

    from allsky.config.checkers import symmetric_eigenvalues

    rng = np.random.default_rng(7)
    cases = [np.diag([3.0, 1.0, 2.0]), np.eye(3), np.diag([1.0, 1.0, 4.0]),
             np.array([[2.0, 1.0, 0.0], [1.0, 2.0, 0.0], [0.0, 0.0, 5.0]]),  # a repeated pair
             np.array([[1.0, 1.0, 1.0]] * 3)]  # rank one
    for _ in range(500):
        a = rng.normal(size=(3, 3)) * 10.0 ** rng.uniform(-3, 3)
        cases.append(a + a.T)
    for m in cases:
        want = np.linalg.eigvalsh(m)
        got = symmetric_eigenvalues(m.tolist())
        scale = float(np.abs(want).max())
        assert np.allclose(got, want, rtol=0, atol=1e-13 * scale), (m, got, want)


def test_every_fault_field_of_the_vocabulary_has_a_rule():
    # validate_fault checks each field by name; a field the vocabulary adds without a rule
    # there would reach its last branch, which refuses it as a programming error.
    import inspect

    from allsky.config import faults as config_faults
    from allsky.vocabulary import FAULT_KINDS

    source = inspect.getsource(config_faults.validate_fault)
    fields = {f for k in FAULT_KINDS for f in (*k.fields, *k.optional)}
    assert fields and not [f for f in sorted(fields) if f'k == "{f}"' not in source]
