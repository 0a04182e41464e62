"""``allsky analyze``: the PWPF static characteristic (closed form and simulation) and the command.

Truth for the static characteristic (derivation in
:func:`allsky.studies.analysis.pwpf_duty_cycle`; Wie, *Space Vehicle Dynamics and
Control*, 2nd ed., sec. 7.4):

* the cycle mean of the filter equation gives ``D = (K e - f_mean) / (K U_m)``
  with ``U_off < f_mean < U_on``, so ``D`` lies between
  ``e/U_m - U_on/(K U_m)`` and ``e/U_m - U_off/(K U_m)``;
* at the midpoint of the linear region, ``K e = (U_on + U_off + K U_m) / 2``,
  the on- and off-phase logarithms have the same argument: ``D = 1/2``, and
  the curve is point-symmetric about it, ``D(mid + x) = 1 - D(mid - x)``;
* the simulated modulator (:func:`allsky.hardware.pwpf.pwpf_step`) converges on the
  continuous formulas as the step shrinks.
"""

import copy
import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from allsky.apps import analyze as analyze_app
from allsky.apps import plots
from allsky.apps.cli import main
from allsky.config.scenario import load_scenario
from allsky.hardware import pwpf
from allsky.studies import analysis

DEFAULT = {"filter_gain": 1.0, "time_constant_s": 0.1, "on_threshold_v": 0.001,
           "off_threshold_v": 0.0003, "full_on_v": 0.008}

designs = st.fixed_dictionaries({
    "filter_gain": st.floats(0.5, 5.0),
    "time_constant_s": st.floats(0.05, 0.5),
    "on_threshold_v": st.floats(1e-4, 1e-2),
    "off_ratio": st.floats(0.05, 0.9),  # U_off / U_on
    "m_ratio": st.floats(1.5, 20.0),  # K U_m / U_on: a linear region exists
})


def design(d):
    k, u_on = d["filter_gain"], d["on_threshold_v"]
    return {"filter_gain": k, "time_constant_s": d["time_constant_s"], "on_threshold_v": u_on,
            "off_threshold_v": d["off_ratio"] * u_on, "full_on_v": d["m_ratio"] * u_on / k}


def limits(p):
    """(dead-zone edge U_on/K, saturation U_m + U_off/K) [V]."""
    k = p["filter_gain"]
    return p["on_threshold_v"] / k, p["full_on_v"] + p["off_threshold_v"] / k


@pytest.fixture(scope="module")
def default_result(default_cfg):
    return analysis.analyze(default_cfg)


# -- the closed form -------------------------------------------------------------------

@settings(max_examples=200, deadline=None)
@given(d=designs, frac=st.floats(0.001, 0.999))
def test_duty_cycle_within_the_cycle_mean_bounds(d, frac):
    p = design(d)
    lo, hi = limits(p)
    e = lo + frac * (hi - lo)
    duty = analysis.pwpf_duty_cycle(**p, input_v=e)
    k, u_m = p["filter_gain"], p["full_on_v"]
    tol = 1e-9
    assert e / u_m - p["on_threshold_v"] / (k * u_m) - tol <= duty
    assert duty <= e / u_m - p["off_threshold_v"] / (k * u_m) + tol


@settings(max_examples=200, deadline=None)
@given(d=designs, x=st.floats(0.0, 0.499))
def test_duty_cycle_is_one_half_at_the_midpoint_and_point_symmetric(d, x):
    p = design(d)
    lo, hi = limits(p)
    mid, half = 0.5 * (lo + hi), hi - lo
    assert analysis.pwpf_duty_cycle(**p, input_v=mid) == pytest.approx(0.5, abs=1e-12)
    up = analysis.pwpf_duty_cycle(**p, input_v=mid + x * half)
    down = analysis.pwpf_duty_cycle(**p, input_v=mid - x * half)
    assert up + down == pytest.approx(1.0, abs=1e-9)


def test_dead_zone_saturation_and_odd_symmetry():
    lo, hi = limits(DEFAULT)
    assert analysis.pwpf_duty_cycle(**DEFAULT, input_v=0.0) == 0.0
    assert analysis.pwpf_duty_cycle(**DEFAULT, input_v=lo) == 0.0
    assert analysis.pwpf_duty_cycle(**DEFAULT, input_v=1.0001 * hi) == 1.0
    assert analysis.pwpf_duty_cycle(**DEFAULT, input_v=-0.004) == \
        analysis.pwpf_duty_cycle(**DEFAULT, input_v=0.004)


def test_duty_cycle_is_on_time_over_period():
    t_on, t_off = pwpf.static_on_off_times_s(*DEFAULT.values(), 0.003)
    assert analysis.pwpf_duty_cycle(**DEFAULT, input_v=0.003) == t_on / (t_on + t_off)


# -- the simulated modulator against the closed form -------------------------------------

def test_default_simulated_fine_matches_the_closed_form(default_result):
    pw = default_result["pwpf"]
    assert pw["fine_step_s"] == pytest.approx(1e-4)
    # Measured 3e-4; the bound allows a few steps of switching error per cycle.
    assert pw["max_error_fine"] < 2e-3
    sim, ana = np.array(pw["duty_simulated_fine"]), np.array(pw["duty_analytic"])
    assert np.allclose(sim, ana, atol=2e-3)


def test_default_simulated_at_the_frame_stays_near_the_closed_form(default_result):
    # At the 10 ms frame with the 10 ms valve minimum on-time the modulator switches
    # only at frame boundaries: the duty is off by up to ~0.025 (measured), 0 and 1
    # exactly in the dead zone and saturation.
    pw = default_result["pwpf"]
    assert pw["max_error_frame"] < 0.04
    sim, ana = np.array(pw["duty_simulated_frame"]), np.array(pw["duty_analytic"])
    assert np.array_equal(sim[ana == 0.0], ana[ana == 0.0])
    assert np.array_equal(sim[ana == 1.0], ana[ana == 1.0])
    assert np.all(np.diff(sim) >= -0.03)  # monotone up to the frame quantisation


@settings(max_examples=10, deadline=None)
@given(d=designs, frac=st.floats(0.1, 0.9))
def test_simulated_duty_cycle_matches_for_any_thresholds(d, frac):
    p = design(d)
    lo, hi = limits(p)
    e = lo + frac * (hi - lo)
    t_on, t_off = pwpf.static_on_off_times_s(*p.values(), e)
    dt = (t_on + t_off) / 2000.0
    params = pwpf.make_params(*p.values(), dt, dt)
    duty = analysis.simulated_duty_cycle(params, e, dt, 30.0 * (t_on + t_off))
    assert duty == pytest.approx(t_on / (t_on + t_off), abs=0.005)


def test_characteristic_spans_dead_zone_linear_region_and_saturation(default_result):
    pw = default_result["pwpf"]
    e = np.array(pw["input_v"])
    assert np.all(np.diff(e) > 0)
    assert e[0] == 0.0 and e[-1] > pw["saturation_v"]
    assert pw["dead_zone_v"] == pytest.approx(0.001)
    assert pw["saturation_v"] == pytest.approx(0.0083)
    inside = (e > pw["dead_zone_v"]) & (e < pw["saturation_v"])
    assert inside.sum() >= 20
    dead, sat = e <= pw["dead_zone_v"], e >= pw["saturation_v"]
    assert dead.sum() >= 3 and sat.sum() >= 2
    assert all(t is None for t, d in zip(pw["t_off_s"], dead) if d)  # never fires
    assert all(t is None for t, s in zip(pw["t_on_s"], sat) if s)  # never shuts
    assert all(math.isfinite(t_on) and math.isfinite(t_off)
               for t_on, t_off, i in zip(pw["t_on_s"], pw["t_off_s"], inside) if i)


# -- analyze() and the command ---------------------------------------------------------

def test_analyze_gives_the_margins_of_loop_margins(default_cfg, default_result):
    assert default_result["margins"] == analysis.loop_margins(
        **analysis.scenario_loop_arguments(default_cfg))
    text = analyze_app.format_analysis(default_result)
    assert "roll position" in text and "yaw rate S17/S19" in text
    table = analyze_app.format_margins(default_result["margins"])
    assert len(table.splitlines()) == 2 + 3 + 2  # head, rule, three position and two rate loops
    assert table.splitlines()[2].split()[:4] == ["roll", "position", "7.96", "14.54"]
    assert "PWPF modulators 34-36, static characteristic: K 1, tau 0.1 s" in text
    assert "e [mV]  T_on [ms] T_off [ms]" in text
    assert "largest |simulated - analytic| duty" in text


def test_scenario_loops_are_the_five_loops(default_cfg):
    loops = analysis.scenario_loops(default_cfg)
    assert list(loops) == ["position roll", "position pitch", "position yaw", "rate roll",
                           "rate yaw"]
    w = np.logspace(-1, 2, 50)
    fr = analysis.frequency_responses(loops, w)
    wc = analysis.loop_margins(**analysis.scenario_loop_arguments(default_cfg))[
        "position"]["roll"]["crossover_rad_s"]
    _, mag, _ = analysis.frequency_responses({"r": loops["position roll"]}, [wc])["r"]
    assert mag[0] == pytest.approx(1.0, rel=1e-6)  # |L| = 1 at the gain crossover
    assert all(v[0].shape == v[1].shape == v[2].shape == (50,) for v in fr.values())


def test_analysis_figure_has_bode_and_static_curve_panels(default_cfg, default_result):
    fr = analysis.frequency_responses(analysis.scenario_loops(default_cfg),
                                      np.logspace(-2, 2, 100))
    fig = plots.analysis(default_result, fr)
    mag, phase, duty = fig.axes
    assert mag.get_ylabel() == "|L(jω)| [dB]"
    assert phase.get_ylabel() == "phase [deg]" and phase.get_xlabel() == "frequency ω [rad/s]"
    assert duty.get_xlabel() == "constant input e [mV]"
    assert duty.get_ylabel().startswith("duty cycle")
    assert mag.get_title(loc="left").startswith("Loop transfer functions")
    assert duty.get_title(loc="left").startswith("PWPF modulators 34-36, static characteristic")
    assert [line.get_label() for line in mag.lines if not line.get_label().startswith("_")] == \
        ["position roll", "position pitch", "position yaw", "rate roll", "rate yaw"]
    assert "position roll   PM 14.5°" in phase.texts[0].get_text()
    labels = [t.get_text() for t in duty.get_legend().get_texts()]
    assert labels[0] == "analytic (continuous time)" and len(labels) == 4


@pytest.fixture(scope="module")
def default_responses(default_cfg):
    return analysis.frequency_responses(analysis.scenario_loops(default_cfg),
                                        np.logspace(-2, 2, 100))


def test_analysis_figure_keeps_every_axis_visible(default_result, default_responses):
    """Pitch and yaw position loops nearly coincide: distinct looks, pitch drawn over yaw."""
    _, m_pitch, _ = default_responses["position pitch"]
    _, m_yaw, _ = default_responses["position yaw"]
    assert np.max(np.abs(20 * np.log10(m_pitch / m_yaw))) < 0.5  # [dB]: one curve to the eye
    fig = plots.analysis(default_result, default_responses)
    mag = fig.axes[0]
    lines = {line.get_label(): line for line in mag.lines if not line.get_label().startswith("_")}
    looks = {(ln.get_linestyle(), ln.get_marker(), ln.get_linewidth()) for ln in lines.values()}
    assert len(looks) == len(lines) == 5
    pitch, yaw = lines["position pitch"], lines["position yaw"]
    assert pitch.get_zorder() > yaw.get_zorder()  # on top
    assert pitch.get_linewidth() < yaw.get_linewidth()  # yaw shows as a band around it
    assert {ln.get_marker() for ln in lines.values()} == {"o", "^", "s"}
    assert not any("UNSTABLE" in t.get_text() for t in mag.texts)
    assert "UNSTABLE" not in fig.get_suptitle()


def test_analysis_figure_flags_an_unstable_loop(default_result, default_responses):
    result = copy.deepcopy(default_result)
    roll = result["margins"]["position"]["roll"]
    roll.update(gain_margin_db=-74.0, phase_margin_deg=-20.0, stable=False)
    fig = plots.analysis(result, default_responses)
    mag, phase, _ = fig.axes
    (flag,) = [t for t in mag.texts if "UNSTABLE" in t.get_text()]
    assert flag.get_text() == "UNSTABLE position roll: GM -74.0 dB, PM -20.0°"
    assert flag.get_color() == "red"
    assert "UNSTABLE" in fig.get_suptitle()
    # |L| at the phase crossover is -GM = +74 dB: a red cross there, inside the axes.
    (cross,) = [ln for ln in mag.lines if ln.get_marker() == "X"]
    assert cross.get_xdata()[0] == roll["phase_crossover_rad_s"]
    assert cross.get_ydata()[0] == 74.0 and cross.get_color() == "red"
    assert mag.get_ylim()[1] > 74.0
    (on_phase,) = [ln for ln in phase.lines if ln.get_marker() == "X"]
    assert on_phase.get_xydata().tolist() == [[roll["phase_crossover_rad_s"], -180.0]]


def test_a_loop_made_unstable_by_a_slow_frame_is_flagged(default_cfg, default_result,
                                                       default_responses):
    """A 50 ms frame adds 0.05 s of delay: every loop loses its margins and its stability."""
    cfg = load_scenario(overrides=["mission.frame_s=0.05", "jets.min_on_time_s=0.05"])
    margins = analysis.loop_margins(**analysis.scenario_loop_arguments(cfg))
    assert not any(m["stable"] for kind in margins.values() for m in kind.values())
    fig = plots.analysis({**default_result, "margins": margins}, default_responses)
    (flag,) = [t for t in fig.axes[0].texts if "UNSTABLE" in t.get_text()]
    assert len(flag.get_text().splitlines()) == 5
    assert [name for name, _ in plots.unstable_loops(margins)] == list(default_responses)


def _strict(text):
    def refuse(c):
        raise ValueError(f"non-standard JSON constant {c}")
    return json.loads(text, parse_constant=refuse)


def test_analyze_command_prints_and_writes_json_and_plot(tmp_path, capsys, default_result):
    js, png = tmp_path / "a.json", tmp_path / "a.png"
    assert main(["analyze", "--json", str(js), "--plot", str(png)]) == 0
    out = capsys.readouterr().out
    assert out.startswith("Loop margins")
    assert f"plot: {png}" in out
    data = _strict(js.read_text())
    assert set(data) == {"margins", "pwpf"}
    assert data["pwpf"]["duty_analytic"] == default_result["pwpf"]["duty_analytic"]
    assert data["pwpf"]["t_off_s"][0] is None  # infinite in the dead zone: null in JSON
    assert data["margins"]["position"]["pitch"]["phase_margin_deg"] == pytest.approx(
        default_result["margins"]["position"]["pitch"]["phase_margin_deg"])
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_analyze_command_follows_the_scenario(tmp_path, capsys):
    js = tmp_path / "a.json"
    assert main(["analyze", "--set", "pwpf.off_threshold_v=0.0005", "--json", str(js)]) == 0
    pw = _strict(js.read_text())["pwpf"]
    assert pw["off_threshold_v"] == 0.0005
    assert pw["saturation_v"] == pytest.approx(0.0085)


def test_analyze_command_bad_override_exit_2(capsys):
    assert main(["analyze", "--set", "pwpf.time_constant_s=-1"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("allsky: error: pwpf.time_constant_s")
