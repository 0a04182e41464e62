"""The dither trade study: the grid, the crossover, the command.

Truth: the crossover of made-up points is a log-log interpolation worked
by hand; a flown grid's largest excursion grows with the dither amplitude
(the disruption is the amplitude, 1 µrad = 0.206″, plus the hold's limit
cycle); bad ``--sweep`` values exit 2 naming the option or the key.
"""

import argparse
import math

import pytest

from allsky.apps.cli import main
from allsky.apps.dither_sweep import format_sweep, grid_from_args, sweep_axis
from allsky.config import ConfigError
from allsky.config.scenario import load_scenario
from allsky.studies.dither_sweep import crossover, point_overrides, sweep


def test_sweep_axis_parses_names_and_positive_numbers():
    assert sweep_axis("amplitude_urad=100,1e3") == ("amplitude_urad", (100.0, 1000.0))
    assert sweep_axis("record_s=204.8") == ("record_s", (204.8,))
    for bad in ("amplitude=1", "record_s", "record_s=a", "record_s=-1", "record_s=inf"):
        with pytest.raises(argparse.ArgumentTypeError):
            sweep_axis(bad)


def test_grid_keeps_the_scenario_value_of_a_name_not_given_and_refuses_one_given_twice():
    cfg = load_scenario()
    amps, records = grid_from_args(cfg, [("amplitude_urad", (300.0, 100.0, 300.0))])
    assert amps == [100.0, 300.0] and records == [819.2]
    with pytest.raises(ConfigError, match="--sweep"):
        grid_from_args(cfg, [("record_s", (1.0,)), ("record_s", (2.0,))])


def test_point_sets_the_amplitude_on_the_dithered_axes_only():
    cfg = load_scenario(overrides=["dither.amplitude_urad=[0,0,100]"])
    assert point_overrides(cfg, 500, 409.6) == ["dither.amplitude_urad=[0.0,0.0,500.0]",
                                                "dither.record_s=409.6"]


def _pt(a, t, e, time_s=100.0):
    return {"amplitude_urad": a, "record_s": t, "time_s": time_s,
            "max_excursion_arcsec": 0.2 * a, "scale_factor_rms_error_same_misalignment_ppm": e}


def test_crossover_interpolates_log_log_and_says_when_it_is_not_bracketed():
    pts = [_pt(100, 1, {"roll": 1000.0, "yaw": 4.0}), _pt(1000, 1, {"roll": 10.0, "yaw": 3.0}),
           _pt(100, 2, {"roll": 50.0, "yaw": 40.0}), _pt(1000, 2, {"roll": 20.0, "yaw": 30.0})]
    c = crossover(pts, {"roll": 100.0, "yaw": 5.0})
    # roll: 1000 -> 10 ppm over a decade of amplitude, 100 ppm half way: 316 µrad.
    assert c["1"]["roll"]["amplitude_urad"] == pytest.approx(math.sqrt(1e5))
    assert c["1"]["roll"]["max_excursion_arcsec"] == pytest.approx(0.2 * math.sqrt(1e5))
    assert c["1"]["roll"]["bracketed"]
    assert c["1"]["yaw"] == {"amplitude_urad": 100, "time_s": 100.0,
                             "max_excursion_arcsec": 20.0, "bracketed": False}
    assert c["2"]["roll"]["amplitude_urad"] == 100 and c["2"]["yaw"] is None


def test_a_flown_grid_reports_errors_costs_and_the_legacy_reference():
    cfg = load_scenario(overrides=["dither.record_s=204.8"])
    r = sweep(cfg, [100.0, 1000.0], [204.8], runs=1, workers=1)
    small, large = r["points"]
    assert small["complete"] == large["complete"] == 1
    # The disruption is the dither: 100 µrad = 20.6", 1000 µrad = 206" on roll and yaw.
    assert 20.0 < small["max_excursion_arcsec"] < 60.0
    assert 200.0 < large["max_excursion_arcsec"] < 400.0
    assert large["predicted_sigma_ppm"]["roll"] == pytest.approx(
        small["predicted_sigma_ppm"]["roll"] / 10.0)
    assert set(large["scale_factor_rms_error_same_misalignment_ppm"]) == {"roll", "yaw"}
    assert r["legacy"]["scale_factor_rms_error_ppm"]["roll"] < 20.0
    assert r["legacy"]["max_excursion_arcsec"] > 600000.0  # the 180 deg of a 360 deg turn
    assert "reaches the legacy accuracy" in format_sweep(r)


@pytest.mark.parametrize("argv, says", [
    (["--sweep", "amplitude_urad=x"], "--sweep"),
    (["--sweep", "record_s=100.1"], "dither.record_s"),
])
def test_bad_sweeps_exit_2_naming_the_option_or_the_key(argv, says, capsys):
    assert main(["compare", *argv]) == 2
    assert says in capsys.readouterr().err
