"""The readable mission report and the ``allsky run`` entry point."""

import json
from pathlib import Path

from allsky.sim import telemetry

PPM = 1e6
RAD2ARCSEC = 206264.80624709636


def format_report(summary: dict) -> str:
    """A plain-text report of a mission summary (:meth:`allsky.sim.mission.Mission.summary`)."""
    status = summary["status"]
    if status == "running":
        status = "not finished (stopped before the end)"
    lines = [f"allsky mission: {status}"]
    if summary["abort_reason"]:
        lines.append(f"  abort reason: {summary['abort_reason']}")
    lines += ["", "Mode timeline", f"  {'mode':<5}{'start s':>9}{'end s':>9}{'dur s':>8}  exit"]
    for r in summary["modes"]:
        lines.append(f"  {r['mode']:<5}{r['start_s']:>9.1f}{r['end_s']:>9.1f}"
                     f"{r['end_s'] - r['start_s']:>8.1f}  {r['exit']}")
    cal, truth = summary["calibration"], summary["truth"]
    if cal is not None:
        lines += ["", "Calibration (stored)      measured        truth        error"]
        for ax in ("roll", "pitch", "yaw"):
            m, t = cal["drift_deg_h"][ax], truth["drift_deg_h"][ax]
            lines.append(f"  drift {ax:<6} [deg/h] {m:>12.4f} {t:>12.4f} {m - t:>+12.4f}")
        for ax in ("roll", "yaw"):
            m, t = cal["scale_factor"][ax], truth["scale_factor"][ax]
            lines.append(f"  scale factor {ax:<4}    {m:>12.7f} {t:>12.7f} {PPM * (m - t):>+9.1f} ppm")
        for k, t in truth["cross_coupling"].items():
            m = cal["cross_coupling"][k]
            lines.append(f"  {k:<16}[arcsec] {m * RAD2ARCSEC:>9.2f} {t * RAD2ARCSEC:>12.2f}"
                         f" {(m - t) * RAD2ARCSEC:>+12.2f}")
    tgt = summary["target"]
    name = tgt.get("star") or f"RA {tgt.get('ra_deg')} deg, Dec {tgt.get('dec_deg')} deg"
    lines += ["", f"Target: {name}"]
    if tgt["programmed_roll_deg"] is not None:
        lines.append(f"  programmed roll {tgt['programmed_roll_deg']:+.4f} deg, "
                     f"yaw {tgt['programmed_yaw_deg']:+.4f} deg")
    if tgt["pointing_error_arcsec"] is not None:
        applied = "" if summary["calibration_applied"] else " (calibration NOT applied)"
        lines.append(f"  final pointing error {tgt['pointing_error_arcsec']:.1f} arcsec{applied}")
    lines += ["", (f"Propellant used {summary['propellant_kg']:.3f} kg; "
                  f"mission time {summary['mission_time_s']:.1f} s")]
    flagged = [k for k, v in summary["counter_overflow"].items() if v]
    if flagged:
        lines.append(f"Counter overflow flagged: {', '.join(flagged)}")
    return "\n".join(lines)


def run_from_cli(cfg, args) -> int:
    """``allsky run``: fly the mission, print the report, write --json / --telemetry / --plots."""
    from allsky.apps.progress import fly
    from allsky.config.dispersions import disperse, format_drawn
    from allsky.sim.mission import Mission

    json_path = getattr(args, "json", None)
    to_stdout = json_path == "-"  # machine output: the JSON alone on stdout
    say = (lambda *a, **k: None) if to_stdout else print
    cfg, drawn = disperse(cfg)  # the scenario's [dispersions], drawn for its mission.seed
    if drawn:
        say(format_drawn(cfg.mission.seed, drawn) + "\n")
    tlm_path = getattr(args, "telemetry", None)
    plots_dir = getattr(args, "plots", None)
    if tlm_path:
        telemetry.file_format(tlm_path)  # refuse a bad suffix before flying
    m = Mission(cfg, telemetry=bool(tlm_path or plots_dir))
    summary = fly(m, quiet=getattr(args, "quiet", False) or to_stdout)
    if drawn:
        summary["dispersions"] = drawn
    say(format_report(summary))
    if to_stdout:
        print(json.dumps(summary, indent=2))
    elif json_path:
        Path(json_path).write_text(json.dumps(summary, indent=2) + "\n")
    if tlm_path:
        telemetry.write(tlm_path, m.telemetry())
    if plots_dir:
        from allsky.apps import plots

        say(plots.format_written(plots.write_plots(
            m.telemetry(), plots_dir, summary,
            progress=not (getattr(args, "quiet", False) or to_stdout))))
    return 0 if summary["status"] == "complete" else 1
