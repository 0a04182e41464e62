"""``allsky compare``: the patent's calibration (Modes 4-5) against the dither method.

Both methods fly the same vehicle: same scenario, same gyro errors, same
seed, hence the same ejection and the same noise through Mode 3. Then the
legacy mission turns 360 deg in roll and in yaw (Modes 4 and 5) while the
comparison mission dithers in the Sun-and-star hold; each flies Mode 6 to
the target with its own calibration. Per method: scale-factor and
cross-coupling errors, calibration time, the largest excursion from the
attitude the mission wanted (the disruption), the propellant the
calibration used, and the final pointing error. With several runs
(seeds), mean, standard deviation and 95th percentile, beside the analytic
expectation of each method's scale-factor spread (docs/comparison.md).
"""

import json
import math
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from allsky import units
from allsky.sequencer.dither_mode import analyse
from allsky.sim.mission import DITHER_PLAN, LEGACY_PLAN, Mission

AXES = ("roll", "yaw")
CC_KEYS = ("roll_into_pitch", "roll_into_yaw", "yaw_into_pitch", "yaw_into_roll")
#: [arcsec] 1-sigma attitude jitter of the optical hold at an instant (the
#: +-1" PWPF dead band; measured from the Mode 3 drift spread, docs/error_budget.md)
HOLD_JITTER_ARCSEC = 0.3
#: Record lengths [dither periods of the slowest axis] for the error-versus-time curve.
PREFIX_PERIODS = (2, 4, 8, 16)


def _fly(cfg, plan):
    """Fly one mission; returns (mission, calibration time [s], excursion [arcsec],
    calibration propellant [kg], duration of each calibration mode [s])."""
    m = Mission(cfg, telemetry=False, plan=plan)
    cal_modes = ("4", "5") if plan is LEGACY_PLAN else ("dither",)
    t_cal, prop = 0.0, 0.0
    durations = {}
    while not m.finished:
        name = m.plan[m.next_mode]
        if name == cal_modes[0]:
            m.state.excursion_ref_q[:] = m.state.x[0:4]
        p0 = m.state.propellant_kg[0]
        rec = m.run_mode()
        if name in cal_modes:
            t_cal += rec.end_s - rec.start_s
            durations[name] = rec.end_s - rec.start_s
            prop += p0 - m.state.propellant_kg[0]
        if name == cal_modes[-1]:
            m.state.excursion_ref_q[:] = 0.0
    return m, t_cal, float(m.state.max_excursion_rad[0] * units.RAD2ARCSEC), prop, durations


def _metrics(m, t_cal, excursion, prop, durations):
    s = m.summary()
    out = {"status": s["status"], "abort_reason": s["abort_reason"], "time_s": t_cal,
           "mode_time_s": durations,
           "max_excursion_arcsec": excursion, "propellant_kg": prop,
           "mission_propellant_kg": s["propellant_kg"],
           "pointing_error_arcsec": s["target"]["pointing_error_arcsec"]}
    if s["calibration"] is not None:
        c, t = s["calibration"], s["truth"]
        out["scale_factor_error_ppm"] = {a: 1e6 * (c["scale_factor"][a] - t["scale_factor"][a])
                                         for a in AXES}
        out["cross_coupling_error_arcsec"] = {
            k: units.RAD2ARCSEC * (c["cross_coupling"][k] - t["cross_coupling"][k])
            for k in CC_KEYS}
    return out, s


def fly_pair(args):
    """Legacy and dither missions for one seed: ``(scenario_dict, seed)`` -> metrics."""
    from allsky.config import scenario_from_dict

    data, seed = args
    cfg = scenario_from_dict(data, [f"mission.seed={seed}"])
    m, *rest = _fly(cfg, LEGACY_PLAN)
    legacy, _ = _metrics(m, *rest)
    m, *rest = _fly(cfg, DITHER_PLAN)
    dith, s = _metrics(m, *rest)
    if m.dither_estimates is not None:
        truth = s["truth"]["scale_factor"]
        est = m.dither_estimates
        tcc = s["truth"]["cross_coupling"]
        pairs = {"roll_into_pitch": ("roll", "pitch"), "roll_into_yaw": ("roll", "yaw"),
                 "yaw_into_pitch": ("yaw", "pitch"), "yaw_into_roll": ("yaw", "roll")}
        dith["cross_coupling_error_arcsec"] = {
            k: units.RAD2ARCSEC * (est[a]["cross"][b] - tcc[k])
            for k, (a, b) in pairs.items() if a in est}
        dith["scale_factor_error_command_ppm"] = {
            a: 1e6 * (est[a]["scale_factor_command"] - truth[a]) for a in AXES if a in est}
        dith["tracking_ratio"] = {a: est[a]["tracking_ratio"] for a in est}
        dith["prefix_error_ppm"] = _prefix_errors(m, truth)
    return {"seed": seed, "legacy": legacy, "dither": dith}


def _prefix_errors(m, truth):
    """Scale-factor error [ppm] of the dither estimate from shorter records."""
    d = m.cfg.dither
    p = m.params.dither
    slow = max(d.period_s[i] for i in range(3) if d.amplitude_urad[i] != 0.0)
    out = {}
    for k in PREFIX_PERIODS:
        rec_s = k * slow
        if rec_s > d.record_s + 1e-9:
            continue
        est = analyse(m.dither_record, d.sample_s, d.lead_in_s, rec_s, p.amplitude_arcsec,
                      p.omega_rad_s, "lsq" if d.detector == "lsq" else "hann"
                      if d.detector == "hann" else "fft")
        key = "scale_factor_optical" if d.estimator == "optical" else "scale_factor_command"
        out[f"{rec_s:g}"] = {a: 1e6 * (est[a][key] - truth[a]) for a in AXES if a in est}
    return out


def _stats(values):
    v = np.asarray(values, dtype=float)
    return {"mean": float(v.mean()), "std": float(v.std(ddof=1)) if v.size > 1 else 0.0,
            "p95": float(np.percentile(np.abs(v), 95))}


def _aggregate(rows, method):
    ok = [r[method] for r in rows if r[method]["status"] == "complete"]
    out = {"runs": len(rows), "complete": len(ok)}
    if not ok:
        return out
    for key in ("scale_factor_error_ppm", "cross_coupling_error_arcsec",
                "scale_factor_error_command_ppm", "tracking_ratio"):
        if key in ok[0]:
            out[key] = {a: _stats([r[key][a] for r in ok]) for a in ok[0][key]}
    for key in ("time_s", "max_excursion_arcsec", "propellant_kg", "mission_propellant_kg",
                "pointing_error_arcsec"):
        out[key] = _stats([r[key] for r in ok])
    if "prefix_error_ppm" in ok[0]:
        out["prefix_rms_ppm"] = {
            t: {a: float(np.sqrt(np.mean([r["prefix_error_ppm"][t][a] ** 2 for r in ok])))
                for a in ok[0]["prefix_error_ppm"][t]}
            for t in ok[0]["prefix_error_ppm"]}
    return out


def predicted(cfg, legacy_time_s=None) -> dict:
    """Analytic 1-sigma scale-factor errors [ppm] of both methods.

    Dither (estimator "optical"): gyro angle random walk and optical-sensor
    noise, each through a least-squares/DFT amplitude estimate::

        sigma^2 = (N sqrt(2/T) / (A w))^2 + (sigma_opt sqrt(2/n) / A)^2

    (N ARW density, T record length, n samples, A amplitude, w frequency;
    the "command" estimator has only the first term, plus its tracking bias).
    Legacy: the counted 360 deg is off by the drift residual over the count,
    the ARW over the count and the hold jitter at both ends::

        sigma^2 = ((sigma_d T_c)^2 + N^2 T_c + 2 j^2) / (1296000")^2,
        sigma_d^2 = N^2 / T_d + 2 j^2 / T_d^2
    """
    n_arw = cfg.gyro.arw_deg_rt_h * 60.0  # arcsec/sqrt(s)
    d = cfg.dither
    opt_noise = {"roll": cfg.star_tracker.noise_arcsec, "yaw": cfg.sun_sensor.noise_arcsec}
    out = {"dither": {}, "legacy": {}}
    n_samples = d.record_s / d.sample_s
    for i, a in ((0, "roll"), (2, "yaw")):
        amp = d.amplitude_urad[i] * 1e-6 * units.RAD2ARCSEC
        if amp == 0:
            continue
        w = 2 * math.pi / d.period_s[i]
        gyro_term = n_arw * math.sqrt(2.0 / d.record_s) / (amp * w)
        opt_term = opt_noise[a] * math.sqrt(2.0 / n_samples) / amp
        out["dither"][a] = 1e6 * math.hypot(gyro_term, opt_term if d.estimator == "optical"
                                            else 0.0)
    j, t_d = HOLD_JITTER_ARCSEC, cfg.sequencer.drift_count_s
    sigma_d = math.sqrt(n_arw ** 2 / t_d + 2 * j ** 2 / t_d ** 2)
    for a in AXES:
        # Default: a 360 deg turn at the rate command plus ~20 % for spin-up and settling.
        t_c = (legacy_time_s or {}).get(a, 1.2 * 360.0 / cfg.electronics.rate_command_deg_s)
        out["legacy"][a] = 1e6 * math.sqrt((sigma_d * t_c) ** 2 + n_arw ** 2 * t_c
                                           + 2 * j ** 2) / 1296000.0
    return out


def compare(cfg, runs=1, workers=2, progress=False) -> dict:
    """Fly both methods over ``runs`` seeds (from the scenario's seed on); return the results."""
    data = cfg.as_dict()
    seeds = [int(cfg.mission.seed) + k for k in range(runs)]
    jobs = [(data, s) for s in seeds]
    if runs == 1 or workers <= 1:
        it = map(fly_pair, jobs)
        pool = None
    else:
        pool = ProcessPoolExecutor(workers)
        it = pool.map(fly_pair, jobs)
    if progress:
        from tqdm import tqdm

        it = tqdm(it, total=runs, desc="missions", unit="pair")
    try:
        rows = list(it)
    finally:
        if pool is not None:
            pool.shutdown()
    result = {"runs": runs, "seeds": [seeds[0], seeds[-1]]}
    if runs == 1:
        result["legacy"], result["dither"] = rows[0]["legacy"], rows[0]["dither"]
    else:
        result["legacy"], result["dither"] = _aggregate(rows, "legacy"), _aggregate(rows,
                                                                                     "dither")
    result["predicted_scale_factor_sigma_ppm"] = predicted(cfg, _legacy_times(rows))
    result["rows"] = rows
    return result


def _legacy_times(rows):
    """Mean durations of Mode 4 (roll count) and Mode 5 (yaw count) [s]."""
    ok = [r["legacy"]["mode_time_s"] for r in rows if r["legacy"]["status"] == "complete"]
    if not ok:
        return None
    return {"roll": float(np.mean([t["4"] for t in ok])),
            "yaw": float(np.mean([t["5"] for t in ok]))}


def _fmt(v, spec=".1f"):
    if isinstance(v, dict):
        return f"{v['mean']:{spec}} ± {v['std']:{spec}} (p95 {v['p95']:{spec}})"
    return "-" if v is None else f"{v:{spec}}"


def format_compare(result) -> str:
    """Side-by-side table of a comparison."""
    leg, dit = result["legacy"], result["dither"]
    pred = result["predicted_scale_factor_sigma_ppm"]
    n = result["runs"]
    head = (f"Calibration methods compared on the same vehicle ({n} run{'s' if n > 1 else ''},"
            f" seeds {result['seeds'][0]}-{result['seeds'][1]})")
    rows = [head, "", f"  {'figure':<34}{'legacy (Modes 4-5)':>34}{'dither':>34}"]

    def line(name, a, b, spec=".1f"):
        rows.append(f"  {name:<34}{_fmt(a, spec):>34}{_fmt(b, spec):>34}")

    for ax in AXES:
        line(f"scale-factor error {ax} [ppm]", leg.get("scale_factor_error_ppm", {}).get(ax),
             dit.get("scale_factor_error_ppm", {}).get(ax))
    for ax in AXES:
        line(f"  predicted 1-sigma {ax} [ppm]", pred["legacy"].get(ax), pred["dither"].get(ax))
        if n > 1:
            line(f"  measured 1-sigma {ax} [ppm]",
                 leg.get("scale_factor_error_ppm", {}).get(ax, {}).get("std"),
                 dit.get("scale_factor_error_ppm", {}).get(ax, {}).get("std"))
    for k in CC_KEYS:
        line(f"{k} error [arcsec]", leg.get("cross_coupling_error_arcsec", {}).get(k),
             dit.get("cross_coupling_error_arcsec", {}).get(k), ".2f")
    line("calibration time [s]", leg.get("time_s"), dit.get("time_s"))
    line("largest excursion [arcsec]", leg.get("max_excursion_arcsec"),
         dit.get("max_excursion_arcsec"))
    line("calibration propellant [kg]", leg.get("propellant_kg"), dit.get("propellant_kg"), ".3f")
    line("final pointing error [arcsec]", leg.get("pointing_error_arcsec"),
         dit.get("pointing_error_arcsec"))
    if "tracking_ratio" in dit:
        for ax, v in dit["tracking_ratio"].items():
            rows.append(f"  dither tracking {ax}: optical amplitude / commanded = "
                        f"{_fmt(v, '.4f')}")
    if n > 1:
        for method in ("legacy", "dither"):
            r = result[method]
            if r.get("complete", 0) < n:
                rows.append(f"  {method}: {n - r.get('complete', 0)} of {n} missions aborted")
    return "\n".join(rows)


def plot(result, path) -> Path:
    """PNG: scale-factor error against calibration time for both methods."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 4.8))
    rows = [r for r in result["rows"] if r["legacy"]["status"] == "complete"]
    for a, mk in (("roll", "o"), ("yaw", "s")):
        t = [r["legacy"]["time_s"] for r in rows]
        e = [abs(r["legacy"]["scale_factor_error_ppm"][a]) for r in rows]
        ax.scatter(t, e, marker=mk, s=14, alpha=0.5, label=f"legacy |error| {a}")
    drows = [r for r in result["rows"] if r["dither"]["status"] == "complete"
             and "prefix_error_ppm" in r["dither"]]
    if drows:
        lead = drows[0]["dither"]["time_s"] - float(max(drows[0]["dither"]["prefix_error_ppm"],
                                                        key=float))
        for a, mk in (("roll", "o"), ("yaw", "s")):
            ts = sorted(drows[0]["dither"]["prefix_error_ppm"], key=float)
            if a not in drows[0]["dither"]["prefix_error_ppm"][ts[0]]:
                continue
            rms = [np.sqrt(np.mean([r["dither"]["prefix_error_ppm"][t][a] ** 2 for r in drows]))
                   for t in ts]
            ax.plot([float(t) + lead for t in ts], rms, marker=mk, label=f"dither RMS error {a}")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("calibration time [s]")
    ax.set_ylabel("scale-factor error [ppm]")
    ax.set_title("Gyro scale-factor calibration: 360° turns vs dither")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def run_from_cli(cfg, args) -> int:
    """``allsky compare``: print the table, write --json and the plot."""
    runs = int(args.runs)
    result = compare(cfg, runs=runs, workers=int(args.workers), progress=runs > 1)
    print(format_compare(result))
    if args.json:
        out = {k: v for k, v in result.items() if k != "rows"}
        Path(args.json).write_text(json.dumps(out, indent=2) + "\n")
    if args.plot:
        print(f"plot: {plot(result, args.plot)}")
    return 0
