"""Figures of a flown mission from its telemetry, and ``allsky plot``.

Each figure function takes the telemetry table (:mod:`allsky.sim.telemetry`
column order) or the mission summary (:meth:`allsky.sim.mission.Mission.summary`)
and returns a :class:`matplotlib.figure.Figure`; :func:`write_plots` writes
them all as PNG. Figures are built on the object-oriented API and rendered by
Agg, so nothing needs a display and no global pyplot state is touched.

=====================  ==========================================================
file                   content
=====================  ==========================================================
attitude_errors.png    roll, pitch, yaw errors [arcsec] as the sensors and CPU 22
                       see them, modes shaded
switches.png           switch timing diagram S1-S19 (S7/S8: selected axis)
counters.png           up/down counters 14/16/18 and drift counters 13/15/17
                       [pulses]
jets.png               valve commands of modulators 34-36 (jets 39-41) and
                       propellant remaining [kg]
calibration.png        stored calibration against the truth, with the errors
                       (needs the summary)
=====================  ==========================================================
"""

import json
import math
from pathlib import Path
from typing import NamedTuple

import numpy as np
from matplotlib.figure import Figure

from allsky.config.scenario import ConfigError
from allsky.hardware import switch_bank, wiring
from allsky.sim.telemetry import INDEX, TelemetryError, read, switch_closed

AXES = ("roll", "pitch", "yaw")
AXIS_COLOURS = {"roll": "tab:blue", "pitch": "tab:orange", "yaw": "tab:green"}
#: [in] figure size at report width, and [dpi] of the PNG files.
FIGSIZE_IN = (10.0, 7.0)
DPI = 120
RAD2ARCSEC = 206264.80624709636
PPM = 1e6
#: Signals below this [arcsec] are drawn on a linear scale, above it logarithmic.
SYMLOG_LINTHRESH_ARCSEC = 10.0
#: [pt] Title padding above axes that carry the row of mode names.
TITLE_PAD_PT = 14.0
# Mode codes written in the telemetry's mode column (mission.MODE_CODE), by name.
# Kept here as data rather than imported so that plotting never imports the
# simulator; tests/test_plots.py checks they agree.
MODE_CODE = {"1": 1.0, "2": 2.0, "3": 3.0, "4": 4.0, "5": 5.0, "6-1": 6.1, "6-2": 6.2,
             "dither": 7.0}
_MODE_COLOURS = ("#4e79a7", "#f28e2b", "#59a14f", "#e15759", "#b07aa1", "#76b7b2",
                 "#edc948", "#9c755f")


def _switch_labels() -> dict:
    """Sk -> short description of what it connects, from the wiring table."""
    out = {}
    for sw in wiring.SWITCHES:
        text = sw.text
        for long, short in (("control amplifier", "amp"), ("summing amplifier", "sum amp"),
                            ("rate-command module", "rate cmd"), (" output", ""),
                            ("storage registers", "registers"), ("->", "→")):
            text = text.replace(long, short)
        out[sw.number] = text
    return out


def mode_name(code: float) -> str:
    """Mode name (``"6-1"``) of a telemetry mode code (6.1); ``"?"`` if unknown."""
    for name, c in MODE_CODE.items():
        if abs(code - c) < 1e-6:
            return name
    return "?"


def mode_spans(table: np.ndarray) -> list:
    """``[(name, t_start_s, t_end_s), ...]``: the runs of equal mode code, in time order."""
    if len(table) == 0:
        return []
    t = table[:, INDEX["time"]]
    code = table[:, INDEX["mode"]]
    cuts = np.flatnonzero(np.diff(code) != 0) + 1
    starts, ends = np.r_[0, cuts], np.r_[cuts, len(t)]
    return [(mode_name(code[a]), float(t[a]), float(t[b] if b < len(t) else t[-1]))
            for a, b in zip(starts, ends)]


def _shade_modes(ax, spans, label=True):
    """Shade each mode's time span; name the modes above the axes when ``label``."""
    names = list(MODE_CODE)
    for name, t0, t1 in spans:
        colour = _MODE_COLOURS[names.index(name) % len(_MODE_COLOURS)] if name in names \
            else "0.5"
        ax.axvspan(t0, t1, color=colour, alpha=0.12, lw=0)
        if label:
            ax.text(0.5 * (t0 + t1), 1.01, name, transform=ax.get_xaxis_transform(),
                    ha="center", va="bottom", fontsize=8, color=colour, fontweight="bold")


def _new_figure(rows, title, height_ratios=None, sharex=True):
    fig = Figure(figsize=FIGSIZE_IN, layout="constrained")
    axes = fig.subplots(rows, 1, sharex=sharex, squeeze=False,
                        gridspec_kw={"height_ratios": height_ratios} if height_ratios else None)
    fig.suptitle(title, fontsize=12)
    return fig, list(axes[:, 0])


def _col(table, name):
    return table[:, INDEX[name]]


def _masked(values, keep):
    out = np.array(values, dtype=float)
    out[~keep] = np.nan
    return out


def attitude_errors(table: np.ndarray) -> Figure:
    """Roll, pitch and yaw errors against time, as the sensors and CPU 22 report them.

    Roll: star tracker yaw output (a roll moves the star across the slit) and
    CPU 22's roll error; pitch: sun sensor pitch, tracker pitch, CPU pitch
    error; yaw: sun sensor yaw and CPU yaw error. Sensor outputs are drawn
    only while the Sun or star is present, CPU errors only in Modes 6-1/6-2.
    Symmetric-log scale: linear within +-10 arcsec.
    """
    t = _col(table, "time")
    sun = _col(table, "sun_present") > 0.5
    star = _col(table, "star_present") > 0.5
    code = _col(table, "mode")
    cpu = (np.abs(code - MODE_CODE["6-1"]) < 1e-6) | (np.abs(code - MODE_CODE["6-2"]) < 1e-6)
    signals = {
        "roll": [("star tracker yaw 105", "tracker_yaw", star, "tab:purple"),
                 ("CPU 22 roll error", "error_roll", cpu, "black")],
        "pitch": [("sun sensor pitch 104", "sun_pitch", sun, "tab:red"),
                  ("star tracker pitch 105", "tracker_pitch", star, "tab:purple"),
                  ("CPU 22 pitch error", "error_pitch", cpu, "black")],
        "yaw": [("sun sensor yaw 104", "sun_yaw", sun, "tab:red"),
                ("CPU 22 yaw error", "error_yaw", cpu, "black")],
    }
    spans = mode_spans(table)
    fig, axes = _new_figure(3, "Attitude errors by axis (modes shaded)")
    for i, (ax, axis) in enumerate(zip(axes, AXES)):
        _shade_modes(ax, spans, label=i == 0)
        for label, name, keep, colour in signals[axis]:
            ax.plot(t, _masked(_col(table, name), keep), lw=0.8, color=colour, label=label)
        ax.set_yscale("symlog", linthresh=SYMLOG_LINTHRESH_ARCSEC)
        ax.set_ylabel(f"{axis} error [arcsec]")
        ax.set_title(f"{axis.capitalize()} error", fontsize=10, loc="left",
                     pad=TITLE_PAD_PT if i == 0 else None)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.0, 1.0))
    axes[-1].set_xlabel("mission time [s]")
    return fig


def switch_timing(table: np.ndarray) -> Figure:
    """Switch timing diagram: S1-S19 as logic-analyser traces, high when closed.

    S7/S8 are the coupled selectors of computer sequencer 21; their trace
    steps between three levels, the selected axis (roll, pitch, yaw).
    """
    t = _col(table, "time")
    labels = _switch_labels()
    fig = Figure(figsize=(FIGSIZE_IN[0], 8.0), layout="constrained")
    ax = fig.subplots()
    fig.suptitle("Switch timing diagram S1–S19 (high = closed)", fontsize=12)
    _shade_modes(ax, mode_spans(table))
    ticks, ticklabels = [], []
    height = 0.7
    rows = [k for k in range(1, switch_bank.N_SWITCHES + 1) if k != 8]  # S8 moves with S7
    for row, k in enumerate(rows):
        base = len(rows) - 1 - row  # S1 at the top
        if k in switch_bank.SELECTORS:
            level = _col(table, "s7_s8") / 2.0 * height
            ax.step(t, base + level, where="post", lw=0.8, color="tab:gray")
            ticklabels.append("S7/S8 selected axis (0 roll, 1 pitch, 2 yaw)")
        else:
            closed = switch_closed(table, k).astype(float)
            ax.fill_between(t, base, base + closed * height, step="post", color="tab:blue",
                            alpha=0.6, lw=0)
            ax.step(t, base + closed * height, where="post", lw=0.8, color="tab:blue")
            ticklabels.append(f"S{k}  {labels.get(k, '')}")
        ticks.append(base + 0.5 * height)
    ax.set_yticks(ticks, ticklabels, fontsize=8)
    ax.set_ylim(-0.3, len(rows))
    ax.set_xlabel("mission time [s]")
    ax.grid(True, axis="x", alpha=0.3)
    return fig


def counters(table: np.ndarray) -> Figure:
    """Up/down counters 14/16/18 and drift counters 13/15/17 [pulses] against time."""
    t = _col(table, "time")
    spans = mode_spans(table)
    fig, axes = _new_figure(2, "Gyro pulse counters (modes shaded)")
    for ax, (title, names) in zip(axes, (
            ("Up/down counters 14, 16, 18", ("counter14", "counter16", "counter18")),
            ("Drift counters 13, 15, 17", ("drift_counter13", "drift_counter15",
                                          "drift_counter17")))):
        _shade_modes(ax, spans, label=ax is axes[0])
        for axis, name in zip(AXES, names):
            ax.step(t, _col(table, name), where="post", lw=1.0, color=AXIS_COLOURS[axis],
                    label=f"{name.replace('_', ' ')} ({axis})")
        ax.set_ylabel("count [pulses]")
        ax.set_title(title, fontsize=10, loc="left",
                     pad=TITLE_PAD_PT if ax is axes[0] else None)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8, loc="upper left")
    axes[-1].set_xlabel("mission time [s]")
    return fig


def jets(table: np.ndarray) -> Figure:
    """Valve commands of modulators 34/35/36 (jets 39/40/41) per axis, and propellant [kg].

    Valve commands are telemetry samples (one every telemetry interval), so
    pulses shorter than the interval may not show; the propellant curve
    counts every pulse.
    """
    t = _col(table, "time")
    spans = mode_spans(table)
    dt = float(np.median(np.diff(t))) if len(t) > 1 else math.nan
    fig, axes = _new_figure(4, f"Jet valve commands (sampled every {dt:.2g} s) "
                               "and propellant", height_ratios=(1, 1, 1, 1.4))
    for ax, axis, jet in zip(axes, AXES, ("34 → jets 39", "35 → jets 40", "36 → jets 41")):
        _shade_modes(ax, spans, label=axis == "roll")
        v = _col(table, f"valve_{axis}")
        ax.step(t, v, where="post", lw=0.6, color=AXIS_COLOURS[axis])
        ax.set_yticks((-1, 0, 1), ("−1", "0", "+1"))
        ax.set_ylim(-1.4, 1.4)
        ax.set_ylabel(f"{axis} valve [-]")
        on = np.count_nonzero(v)
        ax.set_title(f"{axis.capitalize()}: modulator {jet} "
                     f"(open in {on / max(len(v), 1):.1%} of samples)", fontsize=10, loc="left",
                     pad=TITLE_PAD_PT if axis == "roll" else None)
        ax.grid(True, alpha=0.3)
    ax = axes[3]
    _shade_modes(ax, spans, label=False)
    p = _col(table, "propellant")
    ax.plot(t, p, color="black", lw=1.2)
    ax.set_ylabel("propellant [kg]")
    used = float(p[0] - p[-1]) if len(p) else math.nan
    ax.set_title(f"Propellant remaining (used {used:.3f} kg over the record)", fontsize=10,
                 loc="left")
    ax.grid(True, alpha=0.3)
    ax.set_xlabel("mission time [s]")
    return fig


def calibration(summary: dict) -> Figure:
    """Stored calibration against the truth: drift, scale factor, cross-coupling, with errors.

    ``summary`` is :meth:`allsky.sim.mission.Mission.summary` (``allsky run --json``).
    Raises ``ValueError`` when the mission stored no calibration.
    """
    cal, truth = summary.get("calibration"), summary.get("truth")
    if cal is None or truth is None:
        raise ValueError("the mission stored no calibration (it ended before Mode 5)")
    fig = Figure(figsize=FIGSIZE_IN, layout="constrained")
    axes = fig.subplots(1, 3, gridspec_kw={"width_ratios": (3, 2, 4)})
    fig.suptitle(f"Gyro calibration stored in flight against the truth "
                 f"(mission {summary.get('status', '?')})", fontsize=12)
    panels = (
        ("Drift (drift DACs 7, 9, 11)", "drift [deg/h]", "drift_deg_h", 1.0,
         "{:+.4f} deg/h"),
        ("Scale factor − 1 (register 23)", "scale factor − 1 [ppm]", "scale_factor", PPM,
         "{:+.1f} ppm"),
        ("Cross-coupling (register 23)", "cross-coupling [arcsec]", "cross_coupling", RAD2ARCSEC,
         "{:+.2f}″"),
    )
    for ax, (title, ylabel, key, scale, fmt) in zip(axes, panels):
        names = list(truth[key])
        offset = 1.0 if key == "scale_factor" else 0.0
        stored = np.array([(cal[key][n] - offset) * scale for n in names])
        true = np.array([(truth[key][n] - offset) * scale for n in names])
        x = np.arange(len(names))
        ax.bar(x - 0.2, true, 0.4, color="0.6", label="truth")
        ax.bar(x + 0.2, stored, 0.4, color="tab:blue", label="stored")
        top = max(np.max(np.abs(np.r_[stored, true])), 1e-12)
        for xi, s, tr in zip(x, stored, true):
            y = max(s, tr, 0.0) + 0.04 * top
            ax.text(xi, y, "error\n" + fmt.format(s - tr), ha="center", va="bottom", fontsize=8)
        ax.set_ylim(min(0.0, np.min(np.r_[stored, true]) * 1.25) - 0.05 * top, top * 1.35)
        ax.axhline(0.0, color="black", lw=0.6)
        ax.set_xticks(x, [n.replace("_into_", " → ") for n in names], fontsize=8,
                      rotation=20 if key == "cross_coupling" else 0)
        ax.set_ylabel(ylabel)
        ax.set_title(title, fontsize=10)
        ax.grid(True, axis="y", alpha=0.3)
    axes[0].legend(fontsize=8, loc="lower left")
    return fig


def analysis(result: dict, frequency_responses: dict) -> Figure:
    """``allsky analyze``: Bode plots with the margins, and the PWPF static characteristic.

    Parameters
    ----------
    result : dict
        :func:`allsky.studies.analysis.analyze`.
    frequency_responses : dict
        ``{loop name: (omega_rad_s, magnitude, phase_deg)}``
        (:func:`allsky.studies.analysis.frequency_responses` of
        :func:`allsky.studies.analysis.scenario_loops`).
    """
    fig = Figure(figsize=(12.0, 7.0), layout="constrained")
    grid = fig.add_gridspec(2, 2, width_ratios=(1.1, 1.0))
    mag = fig.add_subplot(grid[0, 0])
    phase = fig.add_subplot(grid[1, 0], sharex=mag)
    duty = fig.add_subplot(grid[:, 1])
    fig.suptitle("Attitude loops: margins and PWPF static characteristic", fontsize=12)
    styles = {"position": "-", "rate": "--"}
    for name, (w, m, ph) in frequency_responses.items():
        kind, axis = name.split()
        colour = AXIS_COLOURS[axis]
        mag.semilogx(w, 20.0 * np.log10(m), styles[kind], color=colour, lw=1.2, label=name)
        phase.semilogx(w, ph, styles[kind], color=colour, lw=1.2, label=name)
        mm = result["margins"][kind][axis]
        phase.plot(mm["crossover_rad_s"], -180.0 + mm["phase_margin_deg"], "o", color=colour,
                   ms=4)
    mag.axhline(0.0, color="black", lw=0.6)
    phase.axhline(-180.0, color="black", lw=0.6)
    mag.set_ylabel("|L(jω)| [dB]")
    mag.set_title("Loop transfer functions L(s), cut at the plant input\n"
                  "(other axes closed; solid: position, dashed: rate)", fontsize=10, loc="left")
    mag.grid(True, which="both", alpha=0.3)
    mag.legend(fontsize=8, loc="lower left")
    phase.set_ylabel("phase [deg]")
    phase.set_xlabel("frequency ω [rad/s]")
    lines = [f"{k:<8} {a:<5}  PM {m['phase_margin_deg']:4.1f}°  GM {m['gain_margin_db']:4.1f} dB"
             for k in ("position", "rate") for a, m in result["margins"][k].items()]
    phase.text(0.01, 0.02, "\n".join(lines), transform=phase.transAxes, fontsize=7,
               va="bottom", family="monospace",
               bbox={"facecolor": "white", "alpha": 0.8, "lw": 0})
    phase.set_title("Phase (dots: gain crossover, height above −180° = phase margin)",
                    fontsize=10, loc="left")
    phase.set_ylim(-360.0, -60.0)
    phase.set_yticks(np.arange(-360.0, -59.0, 45.0))
    phase.grid(True, which="both", alpha=0.3)

    pw = result["pwpf"]
    e = np.array(pw["input_v"]) * 1e3
    duty.plot(e, pw["duty_analytic"], "-", color="black", lw=1.5,
              label="analytic (continuous time)")
    duty.plot(e, pw["duty_simulated_fine"], "o", mfc="none", color="tab:blue", ms=5,
              label=f"simulated, step {pw['fine_step_s'] * 1e3:g} ms")
    duty.plot(e, pw["duty_simulated_frame"], "x", color="tab:red", ms=5,
              label=f"simulated at the mission frame {pw['frame_s'] * 1e3:g} ms "
                    f"(min on-time {pw['min_on_time_s'] * 1e3:g} ms)")
    duty.plot(e, np.clip(np.array(pw["input_v"]) / pw["full_on_v"], 0, 1), ":", color="0.4",
              label="describing gain e / U_m")
    duty.axvline(pw["dead_zone_v"] * 1e3, color="0.5", lw=0.6)
    duty.axvline(pw["saturation_v"] * 1e3, color="0.5", lw=0.6)
    duty.text(pw["dead_zone_v"] * 1e3, 1.02, " U_on/K", fontsize=8, va="bottom")
    duty.text(pw["saturation_v"] * 1e3, 1.02, "U_m+U_off/K", fontsize=8, va="bottom",
              ha="right")
    duty.set_xlabel("constant input e [mV]")
    duty.set_ylabel("duty cycle T_on / (T_on + T_off) [-]")
    duty.set_ylim(-0.02, 1.08)
    duty.set_title(f"PWPF modulators 34-36, static characteristic\nK {pw['filter_gain']:g}, "
                   f"τ {pw['time_constant_s']:g} s, U_on {pw['on_threshold_v'] * 1e3:g} mV, "
                   f"U_off {pw['off_threshold_v'] * 1e3:g} mV, U_m {pw['full_on_v'] * 1e3:g} mV",
                   fontsize=10, loc="left")
    duty.grid(True, alpha=0.3)
    duty.legend(fontsize=8, loc="lower right")
    return fig


#: Figure name -> (file name, function of the telemetry table).
TELEMETRY_FIGURES = {
    "attitude_errors": ("attitude_errors.png", attitude_errors),
    "switches": ("switches.png", switch_timing),
    "counters": ("counters.png", counters),
    "jets": ("jets.png", jets),
}
CALIBRATION_FILE = "calibration.png"


class PlotSet(NamedTuple):
    """What :func:`write_plots` did."""

    files: list  #: paths of the PNG files written
    skipped: dict  #: file name -> why it was not drawn


def save(fig: Figure, path) -> Path:
    """Write a figure as PNG at :data:`DPI`."""
    path = Path(path)
    fig.savefig(path, dpi=DPI)
    return path


def write_plots(table: np.ndarray, out_dir, summary=None, progress=False) -> PlotSet:
    """Write the mission figures as PNG files into ``out_dir`` (created if needed).

    Parameters
    ----------
    table : numpy.ndarray
        Telemetry, :data:`allsky.sim.telemetry.COLUMNS` order.
    out_dir : path
        Directory for the files.
    summary : dict, optional
        The mission summary; without it (or without a stored calibration) the
        calibration figure is skipped.
    progress : bool
        Show a progress line on stderr while drawing (when it is a terminal).

    Returns
    -------
    PlotSet
    """
    if len(table) == 0:
        raise ValueError("the telemetry has no rows: nothing to plot")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    from tqdm import tqdm

    files, skipped = [], {}
    jobs = [(name, lambda draw=draw: draw(table)) for name, draw in TELEMETRY_FIGURES.values()]
    if summary is None:
        skipped[CALIBRATION_FILE] = "no mission summary (give --summary SUMMARY.json)"
    elif summary.get("calibration") is None:
        skipped[CALIBRATION_FILE] = "the mission stored no calibration"
    else:
        jobs.append((CALIBRATION_FILE, lambda: calibration(summary)))
    with tqdm(jobs, desc="figures", unit="figure", leave=False,
              disable=None if progress else True) as bar:
        for file_name, draw in bar:
            bar.set_postfix_str(file_name)
            files.append(save(draw(), out / file_name))
    return PlotSet(files, skipped)


def format_written(result: PlotSet) -> str:
    """One line per file written or skipped."""
    lines = [f"plot: {p}" for p in result.files]
    lines += [f"plot: skipped {name}: {why}" for name, why in result.skipped.items()]
    return "\n".join(lines)


def run_from_cli(cfg, args) -> int:
    """``allsky plot TELEMETRY [--out DIR] [--summary SUMMARY.json]`` (``cfg`` unused)."""
    table, _ = read(args.telemetry)
    if len(table) == 0:
        raise TelemetryError(f"telemetry file {args.telemetry!r} has no rows: nothing to plot")
    summary = None
    if args.summary:
        try:
            summary = json.loads(Path(args.summary).read_text())
        except json.JSONDecodeError as e:
            raise ConfigError(None, rule=f"summary {args.summary!r} is not JSON ({e})") from None
        if not isinstance(summary, dict) or not {"calibration", "truth"} <= set(summary):
            raise ConfigError(None, rule=f"summary {args.summary!r} is not an allsky mission "
                                         "summary (allsky run --json)")
    print(format_written(write_plots(table, args.out, summary, progress=True)))
    return 0
