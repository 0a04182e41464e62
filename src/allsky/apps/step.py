"""``allsky step``: fly a mission stop by stop and show the hardware at each stop.

A *stop* is a mode boundary (and, with ``every_s``, every so many simulated
seconds inside a mode); with several targets (``target.sequence``) the move
to the next target is a mode of its own, so each target's end is a stop. At
each stop :func:`snapshot` reads the mission state the way an engineer on
the console would: switch bank S1-S19, up/down
counters 14/16/18, drift counters 13/15/17 and drift DACs 7/9/11, storage
registers 25-27 and DACs 28-30, the sensor outputs, body rates, computed and
programmed word registers 23 and 24, propellant. :func:`format_stop` turns
it into a terminal block; :func:`step_mission` drives the mission and hands
each stop to a callback that may end the session.

Stopping never changes the flight: a mission stepped with pauses gives the
same state, bit for bit, as one flown straight through.
"""

import json
import sys
import zipfile
from pathlib import Path

import numpy as np

from allsky import gauss, units
from allsky.apps.events import event_text, worth_a_line
from allsky.computer import word_registers as wr
from allsky.hardware import switch_bank
from allsky.hardware.dac import dac
from allsky.hardware.star_tracker import star_tracker
from allsky.hardware.sun_sensor import sun_sensor
from allsky.sequencer.modes import MODE_TITLE, PLANS, target_count
from allsky.vehicle import quaternion
from allsky.vocabulary import AXES


class StopStepping(Exception):
    """Raised by a stop callback to end the session (the user pressed ``q``)."""


def _py(f):
    """The plain-Python body of a compiled block (the function itself when JIT is off)."""
    return getattr(f, "py_func", f)


def _sensor_view(m):
    """Noise-free sun sensor and star tracker outputs for the current attitude.

    The blocks are called with their noise set to zero and a scratch
    generator, so looking does not disturb the flight's noise stream.
    """
    p, s = m.params, m.state
    t = m.now_s()
    sun_i = p.sun0_inertial + p.sun_rate_inertial * t
    sun_i = sun_i / np.linalg.norm(sun_i)
    sun_b = quaternion.dcm_body_from_inertial(s.x[0:4]) @ sun_i
    fine, trk = np.zeros(3), np.zeros(3)
    _py(sun_sensor)(p.sun._replace(noise_arcsec=0.0), sun_b, fine, gauss.new_generator())
    _py(star_tracker)(p.tracker._replace(noise_arcsec=0.0), s.x, s.tracker_lock.copy(), trk,
                      gauss.new_generator())  # on a copy of its memory: looking changes nothing
    return fine, trk


def snapshot(m, kind, reason) -> dict:
    """What the console shows at a stop (JSON-serialisable).

    Parameters
    ----------
    m : allsky.sim.mission.Mission
    kind : str
        ``"mode end"`` or ``"every"``.
    reason : str
        Why the stop happened (the mode's exit text, or ``waiting for: ...``
        and the condition the leg under way waits for).
    """
    s, p = m.state, m.params
    el = p.electronics
    pw = float(p.vfc.pulse_weight_arcsec)
    mode = m.timeline[-1].mode if kind == "mode end" else m.current_mode
    fine, trk = _sensor_view(m)
    drift_arcsec_s = [float(dac(int(c), el.drift_dac_bits, el.drift_lsb_arcsec_s))
                      for c in s.drift_counters]
    axis_dac = [float(dac(int(r), el.register_bits, el.register_lsb_arcsec))
                for r in s.registers]
    closed = switch_bank.closed(s.switches)
    return {
        "kind": kind,
        "time_s": m.now_s(),
        "mode": mode,
        "mode_title": MODE_TITLE[mode],
        "reason": reason,
        "target": {"name": m.targets()[-1]["name"], "number": m.target_index + 1,
                   "of": target_count(m.cfg)},
        "status": m.status,
        "switches": {f"S{k}": k in closed for k in range(1, switch_bank.N_SWITCHES + 1)
                     if k not in switch_bank.SELECTORS},
        "selector_s7_s8": AXES[int(s.switches[7])],
        "counters_pulses": dict(zip(("14", "16", "18"), map(int, s.counters))),
        "counters_arcsec": dict(zip(("14", "16", "18"), (float(c) * pw for c in s.counters))),
        "drift_counters_pulses": dict(zip(("13", "15", "17"), map(int, s.drift_counters))),
        "drift_dacs_deg_h": dict(zip(("7", "9", "11"),
                                     (d * units.HOUR_S / units.DEG2ARCSEC
                                      for d in drift_arcsec_s))),
        "registers_lsb": dict(zip(("25", "26", "27"), map(int, s.registers))),
        "dacs_arcsec": dict(zip(("28", "29", "30"), axis_dac)),
        "computed_errors_arcsec": dict(zip(AXES, map(float, s.cpu[3:6]))),
        "sun_sensor": {"pitch_arcsec": float(fine[0]), "yaw_arcsec": float(fine[1]),
                       "present": bool(fine[2] > 0.5)},
        "star_tracker": {"yaw_arcsec": float(trk[0]), "pitch_arcsec": float(trk[1]),
                         "present": bool(trk[2] > 0.5)},
        "body_rates_deg_s": dict(zip(AXES, (float(w) * units.RAD2DEG for w in s.x[4:7]))),
        "register23": wr.computed_as_dict(s.word23),
        "register24_deg": {"roll": float(s.word24[wr.PROGRAMMED_ROLL]) / units.DEG2ARCSEC,
                           "yaw": float(s.word24[wr.PROGRAMMED_YAW]) / units.DEG2ARCSEC},
        "propellant_kg": float(s.propellant_kg[0]),
        "propellant_used_kg": float(m.cfg.jets.propellant_kg - s.propellant_kg[0]),
    }


def _row(label, values, spec):
    return f"  {label:<30}" + "".join(f"{format(v, spec):>14}" for v in values)


def format_stop(snap, number=None) -> str:
    """The terminal block of one stop.

    ``snap`` is the stop's :func:`snapshot`; ``number``, if given, counts the
    stops in its heading.
    """
    head = f"Stop {number} - " if number is not None else ""
    where = "end of" if snap["kind"] == "mode end" else "inside"
    target = snap.get("target")
    aim = (f" - target {target['name']} ({target['number']} of {target['of']})"
           if target and target["of"] > 1 else "")
    lines = [(f"== {head}t = {snap['time_s']:.2f} s - {where} Mode {snap['mode']} "
              f"({snap['mode_title']}){aim} =="),
             f"  {snap['reason']}"]
    sw = snap["switches"]
    names = list(sw)
    lines.append("  Switch bank   " + " ".join(f"{n:>3}" for n in names))
    lines.append("                " + " ".join(f"{'X' if sw[n] else '.':>3}" for n in names))
    shut = [n for n in names if sw[n]]
    lines.append(f"  closed: {' '.join(shut) if shut else 'none'}; "
                 f"S7/S8 on the {snap['selector_s7_s8']} contact")
    lines.append(_row("", AXES, "") .rstrip())
    lines.append(_row("counters 14/16/18 [pulse]", snap["counters_pulses"].values(), "+d"))
    lines.append(_row("  as angle [arcsec]", snap["counters_arcsec"].values(), "+.1f"))
    lines.append(_row("drift counters 13/15/17 [pulse]",
                      snap["drift_counters_pulses"].values(), "+d"))
    lines.append(_row("drift DACs 7/9/11 [deg/h]", snap["drift_dacs_deg_h"].values(), "+.4f"))
    lines.append(_row("registers 25/26/27 [LSB]", snap["registers_lsb"].values(), "+d"))
    lines.append(_row("DACs 28/29/30 [arcsec]", snap["dacs_arcsec"].values(), "+.2f"))
    lines.append(_row("computed errors [arcsec]", snap["computed_errors_arcsec"].values(),
                      "+.1f"))
    lines.append(_row("body rates [deg/s]", snap["body_rates_deg_s"].values(), "+.5f"))
    sun, trk = snap["sun_sensor"], snap["star_tracker"]
    lines.append(f"  sun sensor    pitch {sun['pitch_arcsec']:+10.1f}\"  yaw "
                 f"{sun['yaw_arcsec']:+10.1f}\"  {'Sun present' if sun['present'] else 'NO SUN'}")
    lines.append(f"  star tracker  yaw   {trk['yaw_arcsec']:+10.1f}\"  pitch "
                 f"{trk['pitch_arcsec']:+8.1f}\"  "
                 f"{'star present' if trk['present'] else 'NO STAR'}")
    r23 = snap["register23"]
    cc = r23["cross_coupling"]
    lines.append(f"  register 23   scale factor roll {r23['scale_factor']['roll']:.7f}  "
                 f"yaw {r23['scale_factor']['yaw']:.7f}")
    lines.append("                cross-coupling [arcsec] " + "  ".join(
        f"{k.replace('_into_', '->')} {v * units.RAD2ARCSEC:+.1f}" for k, v in cc.items()))
    r24 = snap["register24_deg"]
    lines.append(f"  register 24   programmed roll {r24['roll']:+.4f} deg  "
                 f"yaw {r24['yaw']:+.4f} deg")
    lines.append(f"  propellant    {snap['propellant_kg']:.3f} kg left "
                 f"({snap['propellant_used_kg']:.3f} kg used)")
    happened = [e for e in snap.get("events", ()) if worth_a_line(e)]
    if happened:
        lines.append(f"  since the last stop ({len(happened)} journal entries):")
        lines += [f"    {e['t_s']:9.2f} s  {event_text(e)}" for e in happened]
    if snap.get("saved_state"):
        lines.append(f"  state saved   {snap['saved_state']} (resume: allsky step --from ...)")
    return "\n".join(lines)


def step_mission(m, on_stop, every_s=None, until=None, save_dir=None) -> list:
    """Fly ``m`` to its end, calling ``on_stop(snapshot)`` at every stop.

    Parameters
    ----------
    m : allsky.sim.mission.Mission
    on_stop : callable
        Receives each stop's :func:`snapshot`, with ``events``: the journal's
        entries since the stop before; raising :class:`StopStepping` ends the
        session with the mission where it is.
    every_s : float, optional
        Also stop every this many simulated seconds inside modes [s].
    until : str, optional
        Show no stop before this mode (inside it only the ``every_s`` stops)
        and end the session at its end.
    save_dir : path, optional
        Save the mission at every mode boundary, as ``after_mode_<MODE>.npz``
        (from the second target of a sequence on, ``after_target<N>_mode_<MODE>.npz``).

    Returns
    -------
    list of dict
        The snapshots shown.
    """
    from allsky.apps import states
    from allsky.sim.mission import Hooks

    shown = []

    def show(snap):
        shown.append(snap)
        on_stop(snap)

    if until is not None and until not in m.plan[m.next_mode:]:
        raise ValueError(f"--until {until}: not a mode still to fly "
                         f"(remaining: {', '.join(m.plan[m.next_mode:]) or 'none'})")
    read = [len(m.journal)]  # journal entries shown at the stops before

    def since_last(snap):
        snap["events"] = [dict(e) for e in m.journal.events[read[0]:]]
        read[0] = len(m.journal)
        return snap

    def pause(mm, what):
        if until is None or mm.current_mode == until:
            show(since_last(snapshot(mm, "every", f"waiting for: {what}")))

    hooks = Hooks(pause_every_s=every_s, on_pause=pause if every_s else None)
    try:
        while not m.finished:
            rec = m.run_mode(hooks)
            saved = (states.save(m, Path(save_dir) / state_file_name(m, rec.mode)) if save_dir
                     else None)
            if until is None or rec.mode == until or m.finished:
                snap = since_last(snapshot(m, "mode end", rec.exit))
                if saved:
                    snap["saved_state"] = str(saved)
                show(snap)
            if rec.mode == until:
                break
    except StopStepping:
        pass
    return shown


def state_file_name(m, mode) -> str:
    """File name for the state saved after ``mode`` (and target, from the second on).

    ``m`` is the mission (its target being flown).
    """
    target = f"target{m.target_index + 1}_" if m.target_index else ""
    return f"after_{target}mode_{mode}.npz"


def _interactive_stop(out, ask):
    count = [0]

    def on_stop(snap):
        count[0] += 1
        print(format_stop(snap, count[0]), file=out, flush=True)
        if snap["status"] != "running":
            return
        answer = ask()
        if answer is None or answer.strip().lower().startswith("q"):
            raise StopStepping()

    return on_stop


def _ask():
    try:
        return input("[Enter] next stop, q + Enter to stop here > ")
    except EOFError:
        return None


#: The finest ``--every``: stops closer than this in mission time [s] or in frames
#: show nothing new and make a session of millions of stops.
EVERY_MIN_S = 0.1
EVERY_MIN_FRAMES = 10


def run_from_cli(cfg, args) -> int:
    """``allsky step``: the interactive (or ``--no-pause``) stop-by-stop mission.

    ``q`` at a prompt, Ctrl-C or SIGTERM end the session; the report,
    ``--json`` and ``--telemetry`` of the flight so far are written either
    way (after Ctrl-C, :class:`~allsky.apps.output.Interrupted` says so).

    ``cfg`` is the scenario the command line loaded (``--scenario``, ``--set``)
    and ``args`` the parsed command line (:mod:`allsky.apps.cli`); returns the
    exit status.
    """
    from allsky.apps import report, states, telemetry_files
    from allsky.apps.output import TELEMETRY_SUFFIXES, Interrupted, check_output, write_atomic
    from allsky.config import ConfigError
    from allsky.sim.mission import Mission

    want_tlm = bool(args.telemetry)
    check_output("--json", args.json)
    check_output("--telemetry", args.telemetry, suffixes=TELEMETRY_SUFFIXES)
    if want_tlm:
        telemetry_files.file_format(args.telemetry)  # refuse a bad suffix before flying
    check_output("--save-dir", args.save_dir, directory=True)
    if args.from_state:
        if args.scenario or args.overrides or args.plan != "legacy":
            raise ConfigError(None, rule="--from resumes a saved mission with its own "
                              "scenario and plan; drop SCENARIO, --set and --plan")
        try:
            m = states.load(args.from_state, telemetry=want_tlm)
        except (ValueError, KeyError, zipfile.BadZipFile) as e:
            raise ConfigError(None, rule=f"--from {args.from_state}: not a saved allsky "
                              f"mission state ({e})") from None
        if m.finished:
            raise ConfigError(None, rule=f"--from {args.from_state}: the saved mission is "
                              f"already {m.status}")
    else:
        m = Mission(cfg, telemetry=want_tlm,
                    plan=PLANS[args.plan])
    if args.until is not None and args.until not in m.plan[m.next_mode:]:
        remaining = " ".join(m.plan[m.next_mode:])
        raise ConfigError(None, rule=f"--until {args.until}: not a mode still to fly "
                          f"(remaining: {remaining})")
    floor_s = max(EVERY_MIN_S, EVERY_MIN_FRAMES * float(m.params.frame_s))
    if args.every is not None and args.every < floor_s * (1 - 1e-12):
        raise ConfigError(None, rule=f"--every {args.every:g}: stops must be at least "
                          f"{EVERY_MIN_S:g} s and {EVERY_MIN_FRAMES} frames apart "
                          f"(here {floor_s:g} s)")
    to_stdout = args.json == "-"  # the JSON alone on stdout; the stops go to stderr
    out = sys.stderr if to_stdout else sys.stdout
    pause = not args.no_pause and sys.stdin.isatty()
    ask = _ask if pause else (lambda: "")
    save_dir = Path(args.save_dir) if args.save_dir else None
    if save_dir:
        save_dir.mkdir(parents=True, exist_ok=True)
    stops = []
    show = _interactive_stop(out, ask)

    def on_stop(snap):
        stops.append(snap)
        show(snap)

    interrupted = False
    try:
        step_mission(m, on_stop, every_s=args.every, until=args.until, save_dir=save_dir)
    except KeyboardInterrupt:
        interrupted = True
    summary = m.summary()
    print(file=out)
    if not m.finished:
        inside = m.current_mode is not None and (not m.timeline
                                                 or m.timeline[-1].mode != m.current_mode)
        where = (f"inside Mode {m.current_mode}" if inside
                 else f"before Mode {m.plan[m.next_mode]}")
        print(f"Stepping ended at t = {m.now_s():.2f} s, {where}; "
              f"the report covers the flight so far.", file=out)
    about = None
    if getattr(args, "from_state", None) is None:
        from allsky.apps.replay import describe_scenario

        about = describe_scenario(getattr(args, "scenario", None), getattr(args, "overrides", ()))
    print(report.format_report(summary, report.tracker_star(m.cfg), scenario=about,
                               width=report.report_width(out)), file=out)
    outputs = []
    body = json.dumps({"stops": stops, "summary": summary}, indent=2) + "\n"
    if to_stdout:
        sys.stdout.write(body)
    elif args.json:
        outputs.append((f"stops and summary {args.json}",
                        lambda: write_atomic(args.json, body, option="--json")))
    if want_tlm:
        outputs.append((f"telemetry {args.telemetry}", lambda: telemetry_files.write(
            args.telemetry, m.telemetry(), option="--telemetry")))
    written, failed = report.write_outputs(outputs)
    for what in written:
        print(f"wrote {what}", file=out)
    if interrupted:
        saved = ", ".join(["the report"] + written)
        raise Interrupted(f"stepping stopped at {report.where_stopped(m)}; written: {saved}"
                          + "".join(f"; {e}" for e in failed))
    if failed:
        for e in failed:
            print(f"allsky: error: {e}", file=sys.stderr)
        return 2
    return 1 if summary["status"] == "aborted" else 0
