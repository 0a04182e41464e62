"""The three-axis multiplicative extended Kalman filter (allsky.studies.kalman_mekf).

The filter reads what the hardware gives (counters 14/16/18, sun sensor 104,
star tracker 105) from a recorded mission. Checked here: the samples it is
fed (counter differences across cleared counters, epochs, drift compensation)
reproduce the true motion; the measurement models reproduce the sensors; the
algebra from its inverse sensitivity to register 23 is exact; NEES over 50
missions whose gyro errors are drawn from its prior lies inside the chi-square
bounds; and the third method of ``allsky compare``.
"""

import ast
from pathlib import Path

import numpy as np
import pytest

from allsky import units
from allsky.apps.cli import main
from allsky.apps.compare import (
    format_information,
    format_kalman,
    information_figure,
    three_way_figure,
)
from allsky.apps.kalman_plots import observability_figure
from allsky.config import load_scenario
from allsky.hardware import gyro
from allsky.studies import kalman_mekf as K
from allsky.studies.compare import METHOD_KEYS, compare
from allsky.vehicle import quaternion


@pytest.fixture(scope="module")
def cfg():
    return load_scenario()


@pytest.fixture(scope="module")
def legacy(cfg):
    return K.fly(cfg, "legacy")


def _attitude_error_arcsec(q_true, q_est):
    e = quaternion.dcm_body_from_inertial(q_true) @ quaternion.dcm_body_from_inertial(q_est).T
    return 0.5 * np.array([e[1, 2] - e[2, 1], e[2, 0] - e[0, 2], e[0, 1] - e[1, 0]]) \
        * units.RAD2ARCSEC


def test_counter_samples_carry_the_true_motion(legacy):
    """Counters through the true sensitivity and drift follow the true attitude.

    Over Modes 3-5 (the counters are cleared twice, the drift DACs switched
    in, two full turns) the gyro-only attitude stays within a few arcsec of
    the truth: only the angle random walk (0.06"/s^0.5) is left.
    """
    s, m = legacy.estimate.samples, legacy.mission
    c = np.linalg.inv(np.asarray(m.params.gyro.sensitivity))
    bias = np.asarray(m.params.gyro.drift_arcsec_s) * units.ARCSEC2RAD
    q = s.truth_q[0].copy()
    worst = 0.0
    for k in range(1, s.time_s.size):
        d = c @ (s.gyro_rad[k] - bias * s.dt_s[k])
        n = np.linalg.norm(d)
        q = quaternion.multiply(q, np.array([np.cos(n / 2), *(np.sin(n / 2) / n * d)]))
        q /= np.linalg.norm(q)
        if k % 50 == 0 or s.leg_end[k]:
            worst = max(worst, np.max(np.abs(_attitude_error_arcsec(s.truth_q[k], q))))
    assert worst < 6.0


def test_measurement_models_reproduce_the_sensors(legacy):
    """Sensor outputs minus the models at the true attitude: white noise of the sensors.

    To the statistics of N residuals, not to a tenth of a sigma: the mean within 4
    standard errors (sigma/sqrt N: 0.02" for the tracker's ~15 000, below the 0.1-0.2"
    the filter knows the attitude to), the sample sigma within 4/sqrt(2N) of the data
    sheet's. A model wrong by a fraction of the attitude's uncertainty fails.
    """
    s, m = legacy.estimate.samples, legacy.mission
    model = K.filter_model(m)
    res = {"sun": [], "tracker": []}
    for k in np.flatnonzero(np.isfinite(s.truth_q[:, 0])):
        a = quaternion.dcm_body_from_inertial(s.truth_q[k])
        if s.sun[k, 2]:
            si = model.sun0_inertial + model.sun_rate_inertial * s.time_s[k]
            b = a @ (si / np.linalg.norm(si))
            res["sun"].append(s.sun[k, :2] - [np.arctan2(-b[2], b[0]), np.arctan2(b[1], b[0])])
        if s.tracker[k, 2]:
            b = a @ model.stars_inertial[0]
            res["tracker"].append(s.tracker[k, :2] - [np.arctan2(-b[1], b[2]),
                                                      np.arctan2(b[0], b[2])])
    for name, sigma in (("sun", model.sun_noise_rad), ("tracker", model.tracker_noise_rad)):
        r = np.array(res[name])
        n = r.shape[0]
        assert n > 1000
        assert np.all(np.abs(r.std(axis=0) / sigma - 1.0) < 4.0 / np.sqrt(2 * n)), name
        assert np.all(np.abs(r.mean(axis=0)) < 4.0 * sigma / np.sqrt(n)), name


def test_register_23_from_the_true_parameters_is_the_perfect_calibration(legacy):
    """Inverse sensitivity -> scale factors and cross-coupling: exact algebra."""
    m = legacy.mission
    truth = gyro.perfect_calibration(m.params.gyro)
    bias = np.asarray(m.params.gyro.drift_arcsec_s) * units.ARCSEC2RAD
    cal = K.calibration(K.true_parameters(m, bias))
    for a in ("roll", "yaw"):
        assert cal["scale_factor"][a] == pytest.approx(truth["scale_factor"][a], rel=1e-13)
    for k, v in truth["cross_coupling"].items():
        assert cal["cross_coupling"][k] == pytest.approx(v, rel=1e-11, abs=1e-15)
    for a in ("roll", "pitch", "yaw"):
        assert cal["drift_deg_h"][a] == pytest.approx(truth["drift_deg_h"][a], rel=1e-13)


def test_legacy_manoeuvres_calibrate_to_the_filters_own_sigma(legacy):
    """Through Modes 3-5 every estimate is within 4 sigma; Mode 6 points within 10"."""
    est, m = legacy.estimate, legacy.mission
    k = int(est.checkpoints[-1])
    err = K.errors_at(m, est, k)
    assert np.all(np.abs(err) < 4.0 * np.sqrt(np.diag(est.covariances[-1])))
    sig = K.sigmas(est.params[-1], est.covariances[-1])
    assert sig["scale_factor_ppm"]["roll"] < 5.0 and sig["scale_factor_ppm"]["yaw"] < 5.0
    assert all(v < 1.0 for v in sig["cross_coupling_arcsec"].values())
    assert est.counts[1] == 0 and est.counts[3] == 0  # no innovation rejected
    assert m.status == "complete" and m.pointing_error_arcsec() < 10.0


def test_nees_over_fifty_missions_is_inside_the_chi_square_bounds(cfg):
    """Gyro errors drawn from the prior: mean NEES (15 states) inside its 95 % bounds."""
    c = K.consistency(cfg, runs=50, seed=2026, plan_name="legacy")
    assert c.aborted == 0 and c.nees.shape[0] == 50
    lo, hi = c.bounds
    assert lo < c.mean_final < hi, (c.mean_final, c.bounds)
    assert lo < c.nees[:, 0].mean() < hi  # the end of Mode 3's drift count


def test_the_filter_reads_sensors_only():
    """No actuator, modulator or vehicle-dynamics module is imported by the filter."""
    tree = ast.parse(Path(K.__file__).read_text())
    names = {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
    names |= {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
    for banned in ("jets", "pwpf", "wheels", "plant", "control_amp"):
        assert not any(banned in (n or "") for n in names), banned


def test_compare_gives_the_filter_and_smoother_the_other_methods_keys(cfg):
    """``--methods legacy,dither,kalman,smoother``: the same keys, and figures that hold.

    Seed 1: the filter's and the smoother's scale-factor and cross-coupling
    errors within 4 of their own sigmas; the smoother's sigmas are the
    Cramer-Rao bound of Modes 3-5 (1 %), the filter's, reading a tenth of
    the frames, within 10 % of it; the legacy count's drift, which carries
    the Sun's apparent motion (0.03-0.045 deg/h), is the largest part of its
    pointing error and the filter's drift part is a fraction of it.
    """
    r = compare(cfg, runs=1, workers=1, methods=("legacy", "dither", "kalman", "smoother"))
    common = set(r["legacy"])
    assert {"drift_error_deg_h", "pointing_error_same_misalignment_arcsec",
            "pointing_error_tracker_architecture_arcsec", "pointing_decomposition"} <= common
    for section in ("dither", "kalman", "kalman_dither", "smoother"):
        assert r[section]["status"] == "complete"
        assert set(r[section]) - set(METHOD_KEYS[section]) == common, section
    bound = r["crlb_manoeuvres"]["modes3_5"]
    for section in ("kalman", "smoother"):
        sig = r[section]["filter_sigma"]
        for ax in ("roll", "yaw"):
            assert abs(r[section]["scale_factor_error_ppm"][ax]) < 4 * sig["scale_factor_ppm"][ax]
            assert r["crlb"][section]["scale_factor_error_ppm"][ax] == \
                bound["scale_factor_ppm"][ax]
        for k, v in r[section]["cross_coupling_error_arcsec"].items():
            assert abs(v) < 4 * sig["cross_coupling_arcsec"][k], (section, k)
        rel = 0.01 if section == "smoother" else 0.10
        for group in ("scale_factor_ppm", "cross_coupling_arcsec"):
            for k, v in sig[group].items():
                assert v == pytest.approx(bound[group][k], rel=rel), (section, group, k)
        assert r[section]["pointing_error_same_misalignment_arcsec"] > 0.0
        assert set(r["predicted_scale_factor_sigma_ppm"][section]) == {"roll", "yaw"}
    parts = {c: r[c]["pointing_decomposition"] for c in ("legacy", "kalman", "smoother")}
    assert parts["legacy"]["drift_arcsec"] > max(parts["legacy"]["scale_factor_arcsec"],
                                                 parts["legacy"]["misalignment_arcsec"])
    assert parts["kalman"]["drift_arcsec"] < 0.5 * parts["legacy"]["drift_arcsec"]
    assert "kalman" not in compare(cfg, runs=1, workers=1)
    text = format_kalman(r)
    assert "Kalman, Modes 3-5" in text and "NEES" in text and "smoother" in text
    info = format_information(r)
    assert "not observable" not in info.split("Final pointing")[0].split("\n")[3]
    assert "drift counters' part" in info
    assert len(three_way_figure(r).axes) == 2
    assert len(information_figure(r).axes) == 2


def test_observability_figure(legacy):
    obs = K.observability(legacy.estimate)
    assert obs.scale_factor_ppm.shape[1] == 3 and obs.misalignment_arcsec.shape[1] == 6
    # Before the roll nothing is known; after both turns roll and yaw are to a few ppm.
    assert obs.scale_factor_ppm[0, 0] > 2000.0 and obs.scale_factor_ppm[-1, [0, 2]].max() < 5.0
    assert len(observability_figure(obs, obs).axes) == 4


def test_cli_refuses_an_unknown_method(capsys):
    assert main(["compare", "--methods", "legacy,dither,guess"]) == 2
    assert "--methods" in capsys.readouterr().err
