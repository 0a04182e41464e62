"""The readable mission report and the ``allsky run`` entry point."""

import sys
from typing import NamedTuple

from allsky.apps import telemetry_files
from allsky.apps.summaries import summary_text
from allsky.apps.verdict import unwritten
from allsky.sim.journal import DRIFT_DAC
from allsky.sim.results import calibration_errors
from allsky.units import RAD2ARCSEC
from allsky.vocabulary import AXES


def _mode_in_progress(summary):
    """The journal's ``mode_start`` of a mode that had not ended when the mission stopped."""
    for e in reversed(summary.get("events") or ()):
        if e["kind"] == "mode_end":
            return None
        if e["kind"] == "mode_start":
            return e
    return None


#: [columns] Widest line of the report (a narrower terminal narrows it, to :data:`MIN_WIDTH`).
WIDTH = 100
#: [columns] Narrowest the report is wrapped to.
MIN_WIDTH = 72


def report_width(stream=None) -> int:
    """The report's width on ``stream`` (default stdout) [columns].

    :data:`WIDTH`, or a narrower terminal's, never under :data:`MIN_WIDTH`.
    """
    import os

    stream = sys.stdout if stream is None else stream
    try:
        columns = os.get_terminal_size(stream.fileno()).columns if stream.isatty() else WIDTH
    except (AttributeError, OSError, ValueError):
        columns = WIDTH
    return max(MIN_WIDTH, min(WIDTH, columns))


def angle_text(arcsec, spec=".1f") -> str:
    """Angle ``arcsec`` [arcsec] formatted by ``spec``, with degrees past 1 deg."""
    text = f"{format(arcsec, spec)} arcsec"
    if abs(arcsec) >= 3600.0:
        text += f" ({arcsec / 3600.0:.3f} deg)"
    return text


class _Row(str):
    """A table row: kept whole whatever the width (a table's columns do not fold)."""


class _Hanging(str):
    """A table row whose last column folds, continued under that column (``indent``)."""

    indent = 0


def _wrap(lines, width) -> list:
    """Each line longer than ``width`` folded at spaces, continued two columns in.

    Table rows (:class:`_Row`) are kept whole: they are at most :data:`WIDTH` wide.
    """
    import textwrap

    out = []
    for line in lines:
        if len(line) <= width or isinstance(line, _Row):
            out.append(line)
            continue
        lead = len(line) - len(line.lstrip(" "))
        mark = "  " if line.lstrip(" ").startswith("! ") else ""
        hang = line.indent if isinstance(line, _Hanging) and line.indent < width - 20 \
            else lead + 2 + len(mark)
        out += textwrap.wrap(line, width, initial_indent="", subsequent_indent=" " * hang,
                             break_on_hyphens=False, drop_whitespace=True) or [line]
    return out


def _header_lines(summary, scenario) -> list:
    """The first line (the judgement, the scenario's name), the description, the first warning."""
    from allsky.apps.verdict import judge

    j = judge(summary)
    status = j["label"]
    if summary["status"] == "running":
        status = "not finished (stopped before the end)"
    name = (scenario or {}).get("name")
    lines = [f"allsky mission: {status}" + (f"; scenario {name}" if name else "")]
    about = (scenario or {}).get("title")  # the description: allsky scenarios NAME
    if about:
        lines.append(f"  {about}")
    if summary["abort_reason"]:
        lines.append(f"  abort reason: {summary['abort_reason']}")
    if j["tone"] == "amber":
        lines.append(f"  ! the first of {j['warnings']} warnings: {j['first_warning']}"
                     if j["warnings"] > 1 else f"  ! {j['first_warning']}")
    return lines


def format_report(summary: dict, tracker_star=None, scenario=None, width=WIDTH) -> str:
    """A plain-text report of mission ``summary`` (:meth:`Mission.summary`).

    The machine's judgement (status, the mode timeline, the computer's
    calibration) and, beside it, what happened: the drift each DAC applies,
    the truth at the end of the flight (``end``), the faults flown, the
    wheels, and the ``warnings``. The first line is the judgement
    (:func:`allsky.apps.verdict.judge`: "complete, as the sequencer judged"
    when the summary has warnings, the first of them below it) and the
    scenario's name.

    Parameters
    ----------
    summary : dict
        The mission's summary.
    tracker_star : allsky.vehicle.sky.Star, optional
        The planned reference star, named; one line says so when the
        tracker locked another star.
    scenario : dict, optional
        ``{"name", "title", "description"}``
        (:func:`allsky.apps.replay.describe_scenario`), named at the top.
    width : int
        [columns] Lines are folded to this width.
    """
    lines = _header_lines(summary, scenario)
    warnings = summary.get("warnings") or []
    if warnings:
        lines += ["", f"Warnings ({len(warnings)})"] + [f"  ! {w}" for w in warnings]
    lines += _faults_lines(summary)
    lines += ["", "Mode timeline", f"  {'mode':<5}{'start s':>9}{'end s':>9}{'dur s':>8}  exit"]
    for r in summary["modes"]:
        row = _Hanging(f"  {r['mode']:<5}{r['start_s']:>9.1f}{r['end_s']:>9.1f}"
                       f"{r['end_s'] - r['start_s']:>8.1f}  {r['exit']}")
        row.indent = 35  # under the exit column
        lines.append(row)
    now = _mode_in_progress(summary)
    if now is not None:
        lines.append(f"  {now['mode']:<5}{now['t_s']:>9.1f}{'-':>9}{'-':>8}  in progress")
    lines += _calibration_lines(summary)
    tgt = summary["target"]
    name = tgt.get("star") or (f"RA {tgt['ra_deg'] / 15.0:.3f} h, "
                               f"Dec {tgt['dec_deg']:+.2f} deg")
    lines += ["", f"Target: {name}"]
    if tracker_star is not None:
        lines.append(f"  tracker star {tracker_star.name} (magnitude "
                     f"{tracker_star.magnitude:+.2f}, RA {tracker_star.ra_deg / 15.0:.3f} h, "
                     f"Dec {tracker_star.dec_deg:+.2f} deg): the planned reference star")
    planned, locked = summary.get("reference_star"), summary.get("locked_star")
    if locked is not None and locked != planned:
        lines.append(f"  the tracker locked {locked}, not the planned {planned}: the "
                     "programmed angles point from the wrong star")
    if tgt["programmed_roll_deg"] is not None:
        lines.append(f"  programmed roll {tgt['programmed_roll_deg']:+.4f} deg, "
                     f"yaw {tgt['programmed_yaw_deg']:+.4f} deg")
    targets = summary.get("targets") or []
    lines += _targets_lines(targets)
    hold = (targets[-1].get("hold") if targets else None) or summary.get("hold")
    if hold is not None:
        drift = hold["drift_arcsec_per_min"]
        on = f" on {targets[-1]['name']}" if len(targets) > 1 else ""
        lines += ["", f"Hold on target{on} ({hold['hold_s']:.1f} s, gyros alone)",
                  (f"  pointing error {angle_text(hold['start_pointing_error_arcsec'])} at "
                   f"the start, {angle_text(hold['end_pointing_error_arcsec'])} at the end"),
                  "  drift [arcsec/min] " + ", ".join(f"{ax} {drift[ax]:+.3f}"
                                                      for ax in AXES)]
    lines += _end_lines(summary)
    lines += _wheels_lines(summary)
    flagged = [k for k, v in summary["counter_overflow"].items() if v]
    if flagged:
        lines.append(f"Counter overflow flagged: {', '.join(flagged)}")
    return "\n".join(_wrap(lines, width))


#: ANSI colours of the judgement on a terminal, by tone (:func:`allsky.apps.verdict.judge`).
ANSI = {"ok": "\033[32m", "amber": "\033[33m", "failed": "\033[31m", "open": ""}


def coloured(report, summary, stream=None) -> str:
    """``report`` with its first line in the judgement's colour on a terminal.

    Green complete, amber "complete, as the sequencer judged", red aborted:
    only when ``stream`` (default stdout) is a terminal and ``NO_COLOR`` is
    unset; ``summary`` is the mission's.
    """
    import os

    from allsky.apps.verdict import judge

    stream = sys.stdout if stream is None else stream
    try:
        tty = stream.isatty()
    except (AttributeError, ValueError):
        tty = False
    code = ANSI[judge(summary)["tone"]]
    if not tty or os.environ.get("NO_COLOR") or not code:
        return report
    first, _, rest = report.partition("\n")
    return f"{code}{first}\033[0m" + ("\n" + rest if rest else "")


def _faults_lines(summary) -> list:
    """The faults flown: kind, onset, duration [s], acting at the end, in words."""
    from allsky.config.faults import describe

    faults = summary.get("faults") or []
    if not faults:
        return []
    spans = {}
    for e in summary.get("events") or ():
        if e.get("kind") == "fault":
            on, off = spans.setdefault(e["fault"], [None, None])
            if e["active"] and on is None:
                spans[e["fault"]][0] = e["t_s"]
            elif not e["active"]:
                spans[e["fault"]][1] = e["t_s"]
    end_s = summary.get("mission_time_s")
    lines = ["", f"Faults ({len(faults)})",
             f"  {'#':>2} {'kind':<22}{'onset s':>9}{'dur s':>9}  {'at the end':<12}what"]
    for i, f in enumerate(faults):
        on, off = spans.get(i, [None, None])
        on = f.get("onset_s") if on is None else on
        if on is None:
            onset, dur, state = "-", "-", "never began"
        elif off is None:
            onset, state = f"{on:.1f}", "acting"
            dur = f"{end_s - on:.1f}" if end_s is not None else "-"
        else:
            onset, dur, state = f"{on:.1f}", f"{off - on:.1f}", "ended"
        try:
            what = describe(f)
        except (KeyError, TypeError, ValueError):
            what = ""
        lines.append(f"  {i + 1:>2} {f['kind']:<22}{onset:>9}{dur:>9}  {state:<12}{what}")
    return lines


def _wheels_lines(summary) -> list:
    """The reaction wheels: peak momentum against the limit, unloads, unloading propellant."""
    w = summary.get("wheels")
    if not w:
        return []
    unloads = sum(1 for e in summary.get("events") or ()
                  if e.get("kind") == "saturation" and e.get("what") == "wheel_unloading"
                  and e.get("active"))
    return [(f"  wheels: peak momentum {100.0 * w['peak_momentum_fraction']:.1f} % of the "
             f"limit, {unloads} unload{'s' * (unloads != 1)}, unloading propellant "
             f"{w['unloading_propellant_kg']:.3f} kg")]


def _calibration_lines(summary) -> list:
    """The calibration: counted and applied drift, register 23, each beside the truth."""
    cal, truth = summary["calibration"], summary["truth"]
    if cal is None:
        return []
    err = calibration_errors(cal, truth)
    applied = cal.get("drift_applied_deg_h", cal["drift_deg_h"])
    clipped = summary.get("drift_dac_clipped") or {}
    never = unwritten(summary)
    lines = ["", "Calibration             counted      applied        truth  error (applied)"]
    for ax in AXES:
        m, a, t = cal["drift_deg_h"][ax], applied[ax], truth["drift_deg_h"][ax]
        if ("drift_deg_h", ax) in never:
            lines.append(f"  drift {ax:<6}[deg/h] {never['drift_deg_h', ax]:>23} {t:>12.4f}")
            continue
        flag = "  CLIPPED" if clipped.get(ax) else ""
        lines.append(f"  drift {ax:<6}[deg/h] {m:>10.4f} {a:>12.4f} {t:>12.4f} "
                     f"{err['drift_deg_h'][ax]:>+12.4f}{flag}")
    for ax in AXES:
        if clipped.get(ax):
            lines.append(f"  ! drift DAC {DRIFT_DAC[AXES.index(ax)]} ({ax}) applies its full "
                         f"scale {applied[ax]:+.4f} deg/h, not the {cal['drift_deg_h'][ax]:+.4f}"
                         " deg/h counted")
    lines.append("                         stored                     truth        error")
    for ax in ("roll", "yaw"):
        m, t = cal["scale_factor"][ax], truth["scale_factor"][ax]
        e = err["scale_factor_ppm"][ax]
        if ("scale_factor", ax) in never:
            lines.append(f"  scale factor {ax:<4}    {never['scale_factor', ax]:<25}{t:>12.7f}")
            continue
        lines.append(f"  scale factor {ax:<4}    {m:>12.7f} {t:>25.7f} {e:>+9.1f} ppm")
    for k, t in truth["cross_coupling"].items():
        m, e = cal["cross_coupling"][k], err["cross_coupling_arcsec"][k]
        if ("cross_coupling", k) in never:
            lines.append(f"  {k:<16}[arcsec] {never['cross_coupling', k]:<25}"
                         f"{t * RAD2ARCSEC:>9.2f}")
            continue
        lines.append(f"  {k:<16}[arcsec] {m * RAD2ARCSEC:>9.2f} {t * RAD2ARCSEC:>25.2f}"
                     f" {e:>+12.2f}")
    return lines


def _end_lines(summary) -> list:
    """The truth at the end of the flight: the last target, its true error, rates, gas."""
    end = summary.get("end")
    if end is None:  # a summary written before the journal
        return ["", (f"Propellant used {summary['propellant_kg']:.3f} kg; "
                     f"mission time {summary['mission_time_s']:.1f} s")]
    applied = "" if summary["calibration_applied"] else " (calibration NOT applied)"
    rates = end["body_rate_deg_s"]
    final = "final" if summary["status"] != "running" else "at the stop,"
    return ["", f"End (what really happened) at t = {end['t_s']:.1f} s, Mode {end['mode']}",
            (f"  {final} true pointing error {angle_text(end['true_pointing_error_arcsec'])} "
             f"to {end['target']}{applied}"),
            "  body rates [deg/s] " + ", ".join(f"{ax} {rates[ax]:+.5f}" for ax in AXES),
            (f"  propellant used {end['propellant_kg']:.3f} kg "
             f"({end['propellant_remaining_kg']:.3f} kg left); "
             f"mission time {summary['mission_time_s']:.1f} s")]


def _targets_lines(targets) -> list:
    """The table of a sequence's targets: angles, true errors [arcsec] and rates, times [s]."""
    if not targets:
        return []
    head = ("#", "target", "roll deg", "yaw deg", "6-2 err\"", "rate deg/s", "hold end\"",
            "start s", "end s")
    lines = ["", (f"Targets ({len(targets)}): programmed angles; where Mode 6-2 declared each "
                  "on target, the true pointing error and the largest body rate; the true "
                  "error at the end of the hold"),
             _Row(f"  {head[0]:>2} {head[1]:<24}{head[2]:>10}{head[3]:>10}{head[4]:>10}"
                  f"{head[5]:>11}{head[6]:>11}{head[7]:>9}{head[8]:>9}")]

    def cell(v, spec, width):
        return f"{'-':>{width}}" if v is None else f"{format(v, spec):>{width}}"

    for i, t in enumerate(targets, 1):
        rates = t.get("body_rate_deg_s")
        rate = max(map(abs, rates.values())) if rates else None
        lines.append(_Row(f"  {i:>2} {t['name'][:23]:<24}{cell(t['programmed_roll_deg'], '+.3f', 10)}"
                     f"{cell(t['programmed_yaw_deg'], '+.3f', 10)}"
                     f"{cell(t['pointing_error_arcsec'], '.1f', 10)}"
                     f"{cell(rate, '.4f', 11)}"
                     f"{cell(t['hold_end_pointing_error_arcsec'], '.1f', 11)}"
                     f"{cell(t['start_s'], '.1f', 9)}{cell(t['end_s'], '.1f', 9)}"))
    return lines


def tracker_star(cfg):
    """The planned reference star ``star_tracker.reference_star``, at the mission date.

    Both are scenario ``cfg``'s; returns a :class:`allsky.vehicle.sky.Star`.
    """
    from allsky.vehicle import sky

    return sky.star(cfg.star_tracker.reference_star, cfg.mission.date_utc)


def where_stopped(m) -> str:
    """Where interrupted or stopped mission ``m`` is: mission time and mode."""
    mode = m.current_mode or (m.plan[m.next_mode] if not m.finished else None)
    return f"t = {m.now_s():.1f} s" + (f", in Mode {mode}" if mode else "")


def write_outputs(outputs) -> tuple[list, list]:
    """Write each ``(what, write)`` of ``outputs``; go on past a failure.

    Returns
    -------
    (list of str, list of OutputError)
        What was written, and the writes that failed.
    """
    from allsky.apps.output import OutputError

    written, failed = [], []
    for what, write in outputs:
        try:
            write()
            written.append(what)
        except OutputError as e:
            failed.append(e)
    return written, failed


class Flown(NamedTuple):
    """A mission flown by :func:`fly_drawn`: whole, or up to an interruption."""

    mission: object  #: the :class:`allsky.sim.mission.Mission`, as it stopped
    summary: dict  #: its summary; ``dispersions`` holds the values drawn, when any were
    interrupted: bool  #: stopped by Ctrl-C (or SIGTERM) before the end


def fly_drawn(cfg, drawn, telemetry=True, fly=None, plan=None) -> Flown:
    """Fly a scenario whose dispersions were drawn; Ctrl-C keeps the part flown.

    The one flight of ``allsky run`` and of :func:`allsky.fly`.

    Parameters
    ----------
    cfg : allsky.config.Scenario
        The scenario with its dispersions drawn
        (:func:`allsky.config.dispersions.disperse`).
    drawn : dict
        The values drawn; the summary carries them as ``dispersions``.
    telemetry : bool
        Record telemetry.
    fly : callable, optional
        ``fly(mission) -> summary``: how to fly it (a progress line,
        :func:`allsky.apps.progress.fly`); default :meth:`Mission.run
        <allsky.sim.mission.Mission.run>`.
    plan : tuple of str, optional
        The modes to fly (:data:`allsky.sequencer.modes.PLANS`); default the
        patent's.

    Returns
    -------
    Flown
        After a Ctrl-C (KeyboardInterrupt) or SIGTERM turned into one, the
        mission as it stopped and the summary of the part flown, with
        ``interrupted`` True.
    """
    from allsky.sim.mission import LEGACY_PLAN, Mission

    m = Mission(cfg, telemetry=telemetry, plan=LEGACY_PLAN if plan is None else plan)
    interrupted = False
    try:
        summary = m.run() if fly is None else fly(m)
    except KeyboardInterrupt:
        interrupted = True
        summary = m.summary()
    if drawn:
        summary["dispersions"] = drawn
    return Flown(m, summary, interrupted)


def session_log(args, cfg) -> tuple:
    """``(scenario, commands)`` of ``allsky run --commands FILE``.

    The log's own scenario unless SCENARIO was given (``args.scenario``),
    with ``--set`` over it; the commands checked against it. ``args`` is
    the parsed command line (``args.commands``: the log's path), ``cfg`` the
    scenario it loaded, flown when the log holds none.
    """
    from allsky.config import scenario_from_dict
    from allsky.sim import commands

    scenario, raw = commands.read_log(args.commands)
    if scenario is not None and getattr(args, "scenario", None) is None:
        cfg = scenario_from_dict(scenario, getattr(args, "overrides", ()))
    return cfg, commands.validate_log(raw, cfg)


def fly_commands(m, log, path) -> dict:
    """Fly ``m`` with a saved session's commands (:func:`session_log`); its summary.

    ``log`` holds the validated commands, each with ``t_s`` [s]; ``path`` is the
    log file's, named in the error a refused command raises.
    """
    from allsky.config import ConfigError
    from allsky.sim import commands

    try:
        commands.fly_log(m, log)
    except commands.Refused as e:
        raise ConfigError(None, rule=f"--commands {path}: at t = {m.now_s():.2f} s: {e}"
                          ) from None
    return m.summary()


def run_from_cli(cfg, args) -> int:
    """``allsky run``: fly, report, write --json, --telemetry, --plots and --html.

    Every output path is checked before flying. Interrupted (Ctrl-C, SIGTERM),
    the report, ``--json`` and ``--telemetry`` of the part flown are still
    written and :class:`~allsky.apps.output.Interrupted` says so; a file that
    cannot be written does not stop the others.

    ``cfg`` is the scenario the command line loaded (``--scenario``, ``--set``)
    and ``args`` the parsed command line (:mod:`allsky.apps.cli`); returns the
    exit status.
    """
    from allsky.apps.output import (
        TELEMETRY_SUFFIXES,
        Interrupted,
        OutputError,
        check_output,
        is_null_device,
        write_atomic,
    )
    from allsky.apps.progress import fly
    from allsky.config.dispersions import disperse, format_drawn

    json_path = getattr(args, "json", None)
    to_stdout = json_path == "-"  # machine output: the JSON alone on stdout
    say = (lambda *a, **k: None) if to_stdout else print
    tlm_path = getattr(args, "telemetry", None)
    plots_dir = getattr(args, "plots", None)
    html_path = getattr(args, "html", None)
    quiet = getattr(args, "quiet", False) or to_stdout
    check_output("--json", json_path)  # before flying: no mission lost to a typo
    check_output("--telemetry", tlm_path, suffixes=TELEMETRY_SUFFIXES)
    if tlm_path and not is_null_device(tlm_path):  # the null device takes any suffix
        telemetry_files.file_format(tlm_path)
    check_output("--plots", plots_dir, directory=True)
    check_output("--html", html_path, suffixes=(".html", ".htm"))
    log = None
    if getattr(args, "commands", None):  # a saved ground-control session, flown again
        cfg, log = session_log(args, cfg)
    cfg, drawn = disperse(cfg)  # the scenario's [dispersions], drawn for its mission.seed
    if drawn:
        say(format_drawn(cfg.mission.seed, drawn) + "\n")
    def fly_it(mission):
        if log is None:
            return fly(mission, quiet=quiet)
        return fly_commands(mission, log, args.commands)

    m, summary, interrupted = fly_drawn(cfg, drawn, fly=fly_it,
                                        telemetry=bool(tlm_path or plots_dir or html_path))
    from allsky.apps.replay import describe_scenario

    about = describe_scenario(getattr(args, "scenario", None), getattr(args, "overrides", ()))
    say(coloured(format_report(summary, tracker_star(cfg), scenario=about, width=report_width()),
                 summary))
    outputs = []
    if to_stdout:
        print(summary_text(summary), end="")
    elif json_path:
        outputs.append((f"JSON summary {json_path}", lambda: write_atomic(
            json_path, summary_text(summary), option="--json")))
    if tlm_path:
        outputs.append((f"telemetry {tlm_path}", lambda: telemetry_files.write(
            tlm_path, m.telemetry(), option="--telemetry")))
    if html_path and len(m.telemetry()):
        from allsky.apps.replay import write_replay

        outputs.append((f"replay {html_path}", lambda: write_replay(
            html_path, m.telemetry(), summary, cfg, option="--html", scenario=about)))
    written, failed = write_outputs(outputs)
    for what in written:
        say(f"wrote {what}" + (" (the part flown)" if interrupted else ""))
    if interrupted:
        saved = ", ".join(["the report"] * (not to_stdout) + written) or "nothing"
        failures = "".join(f"; {e}" for e in failed)
        raise Interrupted(f"mission stopped at {where_stopped(m)}; written: {saved}"
                          f"{' (figures not drawn)' if plots_dir else ''}{failures}")
    if plots_dir:
        from allsky.apps import plots

        try:
            say(plots.format_written(plots.write_plots(m.telemetry(), plots_dir, summary,
                                                       progress=not quiet)))
        except OSError as e:
            failed.append(OutputError("--plots", plots_dir, str(e.strerror or e)))
        except KeyboardInterrupt:
            raise Interrupted(f"while drawing the figures; written: {', '.join(written)}; "
                              "figures already in the directory are complete") from None
    if failed:
        for e in failed:
            print(f"allsky: error: {e}", file=sys.stderr)
        return 2
    if getattr(args, "strict", False):
        from allsky.apps.verdict import strict_failure

        why = strict_failure(summary)
        if why is not None:
            print(f"allsky: --strict: {why}", file=sys.stderr)
            return 1
    # 0 complete, or a saved session's flight ended where its `end` command stood; 1 aborted
    return 1 if summary["status"] == "aborted" else 0
