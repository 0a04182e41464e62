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
                       see them, modes shaded; the true final pointing error
                       (with the summary); a dither hold on a linear scale
switches.png           switch timing diagram S1-S19 (S7/S8: share of samples on
                       each axis)
counters.png           up/down counters 14/16/18 and drift counters 13/15/17
                       [pulses]
jets.png               valve commands of modulators 34-36 (jets 39-41) and
                       propellant remaining [kg]
calibration.png        stored calibration against the truth, with the errors
                       (needs the summary)
hold.png               each hold on target: the attitude's drift per body axis
                       [arcsec] since the hold began, with its least-squares
                       rate [arcsec/min] (only when the telemetry holds a hold)
=====================  ==========================================================
"""

import math
from pathlib import Path
from typing import NamedTuple

import numpy as np
from matplotlib.figure import Figure

from allsky.apps.events import runs, switch_edges
from allsky.apps.telemetry_files import TelemetryError, read
from allsky.hardware import switch_bank, wiring
from allsky.sequencer.modes import MODE_CODE, cpu_modes
from allsky.sim.telemetry import INDEX, switch_closed
from allsky.vehicle import quaternion
from allsky.vocabulary import AXES

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
    """Mode name (``"6-1"``) of telemetry mode code ``code`` (6.1); ``"?"`` if unknown."""
    for name, c in MODE_CODE.items():
        if abs(code - c) < 1e-6:
            return name
    return "?"


def mode_spans(table: np.ndarray, summary=None) -> list:
    """Each mode's time span in order: ``[(name, t_start_s, t_end_s), ...]``.

    From the summary's timeline (``modes``, exact frame times) when a
    ``summary`` is given; else the telemetry's runs of equal mode code
    (:func:`allsky.apps.events.runs`), whose edges are those of its rows.
    ``table`` is the telemetry, in :data:`allsky.sim.telemetry.COLUMNS` order.
    """
    if summary and summary.get("modes"):
        return [(r["mode"], float(r["start_s"]), float(r["end_s"])) for r in summary["modes"]]
    if len(table) == 0:
        return []
    t = table[:, INDEX["time"]]
    starts = [i for i, _ in runs(table[:, INDEX["mode"]])]
    ends = [*starts[1:], len(t) - 1]
    return [(mode_name(table[a, INDEX["mode"]]), float(t[a]), float(t[b]))
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


def _cpu_modes(code):
    """True where CPU 22 computes attitude errors (:func:`allsky.sequencer.modes.cpu_modes`)."""
    return np.isin(np.round(code, 6), [MODE_CODE[m] for m in cpu_modes()])


def _sensor_signals(table):
    """Per axis: [(label, telemetry column, where it is drawn, colour)] of the attitude figure."""
    sun = _col(table, "sun_present") > 0.5
    star = _col(table, "star_present") > 0.5
    cpu = _cpu_modes(_col(table, "mode"))
    return {
        "roll": [("star tracker yaw 105", "tracker_yaw", star, "tab:purple"),
                 ("CPU 22 roll error", "error_roll", cpu, "black")],
        "pitch": [("sun sensor pitch 104", "sun_pitch", sun, "tab:red"),
                  ("star tracker pitch 105", "tracker_pitch", star, "tab:purple"),
                  ("CPU 22 pitch error", "error_pitch", cpu, "black")],
        "yaw": [("sun sensor yaw 104", "sun_yaw", sun, "tab:red"),
                ("CPU 22 yaw error", "error_yaw", cpu, "black")],
    }


#: The signals of the linear dither panel: (axis, label, telemetry column). The tracker's
#: yaw output moves with roll (the star crosses the slit), as in the roll panel above.
DITHER_SIGNALS = (("roll", "roll: star tracker yaw 105", "tracker_yaw"),
                  ("pitch", "pitch: sun sensor pitch 104 (not dithered)", "sun_pitch"),
                  ("yaw", "yaw: sun sensor yaw 104", "sun_yaw"))


def dither_span(table: np.ndarray):
    """``(t_start_s, t_end_s)`` of the dither hold (mode ``"dither"``), or None.

    ``table`` is the telemetry, in :data:`allsky.sim.telemetry.COLUMNS` order.
    """
    holds = [(t0, t1) for name, t0, t1 in mode_spans(table) if name == "dither"]
    return (holds[0][0], holds[-1][1]) if holds else None


def final_pointing_error_arcsec(summary):
    """The true final pointing error [arcsec] of mission ``summary``, or None.

    It is the angle between the body roll axis and the target flown last at
    the end of the mission (the summary's ``end``), computed by the
    simulator from the true attitude; the sensors and CPU 22 see only their
    own errors.
    """
    if summary is None:
        return None
    if summary.get("end"):
        return summary["end"]["true_pointing_error_arcsec"]
    return (summary.get("target") or {}).get("pointing_error_arcsec")


def _true_error_recorded(table) -> bool:
    """Whether the telemetry holds the true error (a file of format 2 or later)."""
    return not np.isnan(_col(table, "true_error")).any()


def attitude_errors(table: np.ndarray, summary=None) -> Figure:
    """Roll, pitch and yaw errors against time, as the sensors and CPU 22 report them.

    Roll: star tracker yaw output (a roll moves the star across the slit) and
    CPU 22's roll error; pitch: sun sensor pitch, tracker pitch, CPU pitch
    error; yaw: sun sensor yaw and CPU yaw error. Sensor outputs are drawn
    only while the Sun or star is present, CPU errors only in Modes 6-1/6-2.
    Symmetric-log scale: linear within +-10 arcsec.

    A row "Pointing error" draws, in Mode 6 and the hold, CPU 22's own
    estimate sqrt(pitch^2 + yaw^2) beside the true error to the target
    (the telemetry's ``true_error``), and with a ``summary`` marks the truth
    at the end of the flight. When the telemetry
    holds a dither hold, a last row shows the hold on a linear scale, where
    the sinusoids keep their shape (symlog bends them at +-10 arcsec).

    ``table`` is the telemetry, in :data:`allsky.sim.telemetry.COLUMNS` order.
    """
    t = _col(table, "time")
    signals = _sensor_signals(table)
    pointing_arcsec = final_pointing_error_arcsec(summary)
    truth = _true_error_recorded(table)
    pointing = pointing_arcsec is not None or truth
    span = dither_span(table)
    rows = 3 + pointing + (span is not None)
    ratios = [1.0, 1.0, 1.0] + [0.8] * pointing + [1.1] * (span is not None)
    fig = Figure(figsize=(FIGSIZE_IN[0], FIGSIZE_IN[1] + 1.9 * (rows - 3)), layout="constrained")
    grid = fig.add_gridspec(rows, 1, height_ratios=ratios)
    fig.suptitle("Attitude errors by axis (modes shaded)", fontsize=12)
    spans = mode_spans(table, summary)
    timeline = []  # the rows that share the mission-time axis
    for i, axis in enumerate(AXES):
        ax = fig.add_subplot(grid[i, 0], sharex=timeline[0] if timeline else None)
        timeline.append(ax)
        _shade_modes(ax, spans, label=i == 0)
        for label, name, keep, colour in signals[axis]:
            ax.plot(t, _masked(_col(table, name), keep), lw=0.8, color=colour, label=label)
        ax.set_yscale("symlog", linthresh=SYMLOG_LINTHRESH_ARCSEC)
        ax.set_ylabel(f"{axis} error [arcsec]")
        ax.set_title(f"{axis.capitalize()} error", fontsize=10, loc="left",
                     pad=TITLE_PAD_PT if i == 0 else None)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.0, 1.0))
    if pointing:
        ax = fig.add_subplot(grid[3, 0], sharex=timeline[0])
        timeline.append(ax)
        _pointing_panel(ax, table, spans, pointing_arcsec, truth)
    for ax in timeline[:-1]:
        ax.tick_params(labelbottom=False)
    timeline[-1].set_xlabel("mission time [s]")
    if span is not None:
        _dither_panel(fig.add_subplot(grid[rows - 1, 0]), table, span)
    return fig


def _pointing_panel(ax, table, spans, pointing_arcsec, truth):
    """CPU 22's pitch/yaw error magnitude in Mode 6 beside the true error, and the end."""
    t = _col(table, "time")
    _shade_modes(ax, spans, label=False)
    cpu = _cpu_modes(_col(table, "mode"))
    believed = np.hypot(_col(table, "error_pitch"), _col(table, "error_yaw"))
    ax.plot(t, _masked(believed, cpu & (believed > 0.0)), lw=0.8, color="black",
            label="CPU 22 √(pitch² + yaw²) error")
    if truth:
        true_error = _col(table, "true_error")
        ax.plot(t, _masked(true_error, cpu & (true_error > 0.0)), lw=1.0, color="tab:red",
                label="true error, roll axis to target")
    if pointing_arcsec is not None:
        ax.plot([t[-1]], [pointing_arcsec], marker="*", ms=13, ls="none", color="tab:red",
                mec="black", mew=0.5, zorder=5,
                label="true final pointing error\n(roll axis to target, summary)")
        ax.annotate(f"true final pointing error {pointing_arcsec:.1f}″",
                    (t[-1], pointing_arcsec), xytext=(-8, 8), textcoords="offset points",
                    ha="right", va="bottom", fontsize=9, color="tab:red", fontweight="bold")
    ax.set_yscale("log")
    ax.set_ylabel("pointing error [arcsec]")
    ax.set_title("Pointing error: CPU 22's estimate beside the truth", fontsize=10,
                 loc="left")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.0, 1.0))


def _dither_panel(ax, table, span):
    """The optics through the dither hold on a linear scale."""
    t0, t1 = span
    t = _col(table, "time")
    keep = (t >= t0) & (t <= t1)
    for axis, label, name in DITHER_SIGNALS:
        ax.plot(t[keep], _col(table, name)[keep], lw=0.7, color=AXIS_COLOURS[axis], label=label)
    ax.set_xlim(t0, t1)
    ax.set_yscale("linear")
    ax.set_ylabel("optical error [arcsec]")
    ax.set_xlabel("mission time [s]")
    ax.set_title(f"Dither hold, {t0:.0f}-{t1:.0f} s, linear scale (sinusoids undistorted)",
                 fontsize=10, loc="left")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.0, 1.0))


#: Colour of the on/off switch traces: neutral, so that the S7/S8 row's axis colours stand out.
SWITCH_COLOUR = "0.3"
#: Windows the S7/S8 trace is cut into: the share of samples on each contact is drawn
#: per window, since a single sample per telemetry interval cannot show a selector that
#: steps every frame or few.
SELECTOR_WINDOWS = 300


def selector_shares(table: np.ndarray, windows=SELECTOR_WINDOWS):
    """Share of telemetry samples on each S7/S8 contact, per window of samples.

    Returns ``(edges_s, shares)``: window edges [s] (``n + 1``; each sample
    stands for the interval up to the next, the last for one interval) and an
    ``(n, 3)`` array of the fraction of the window's samples with S7/S8 on
    roll, pitch, yaw (each row sums to 1). A window is a whole multiple of
    three samples, so that a selector stepping once per sample is counted
    evenly; its length is the record over ``windows``.

    ``table`` is the telemetry, in :data:`allsky.sim.telemetry.COLUMNS` order.
    """
    t = _col(table, "time")
    axis = np.rint(_col(table, "s7_s8")).astype(int)
    per = 3 * max(1, len(t) // (3 * windows))
    starts = np.arange(0, len(t), per)
    counts = np.stack([np.add.reduceat((axis == k).astype(float), starts) for k in range(3)],
                      axis=1)
    shares = counts / counts.sum(axis=1, keepdims=True)
    # The last sample stands for one more telemetry interval.
    edges = np.r_[t[starts], t[-1] + (t[-1] - t[-2] if len(t) > 1 else 0.0)]
    return edges, shares


def switch_timing(table: np.ndarray, summary=None) -> Figure:
    """Switch timing diagram: S1-S19 as logic-analyser traces, high when closed.

    S7/S8 are the coupled selectors of computer sequencer 21. In Mode 6 they
    step every frame or few, faster than the telemetry samples them, so
    their row shows per window of samples the share on each contact,
    stacked roll (bottom), pitch, yaw (top) (:func:`selector_shares`).

    With a ``summary``, the modes and the on/off switches' edges are the
    journal's, at their exact frames (:func:`allsky.apps.events.switch_edges`);
    without, the telemetry's rows.

    ``table`` is the telemetry, in :data:`allsky.sim.telemetry.COLUMNS` order.
    """
    t = _col(table, "time")
    events = (summary or {}).get("events")
    labels = _switch_labels()
    fig = Figure(figsize=(FIGSIZE_IN[0], 8.0), layout="constrained")
    ax = fig.subplots()
    fig.suptitle("Switch timing diagram S1–S19 (high = closed)", fontsize=12)
    _shade_modes(ax, mode_spans(table, summary))
    ticks, ticklabels = [], []
    height = 0.7
    rows = [k for k in range(1, switch_bank.N_SWITCHES + 1) if k != 8]  # S8 moves with S7
    for row, k in enumerate(rows):
        base = len(rows) - 1 - row  # S1 at the top
        if k in switch_bank.SELECTORS:
            edges, shares = selector_shares(table)
            window_s = float(np.median(np.diff(edges)))
            bottom = np.zeros(len(shares))
            for i, axis in enumerate(AXES):
                ax.stairs(base + (bottom + shares[:, i]) * height, edges,
                          baseline=base + bottom * height, fill=True, lw=0,
                          color=AXIS_COLOURS[axis], alpha=0.8, label=f"S7/S8 on {axis}")
                bottom = bottom + shares[:, i]
            ticklabels.append(f"S7/S8 selected axis,\nshare per {window_s:.2g} s")
        else:
            if events is not None:
                edges = switch_edges(events, k)
                tk = np.array([t[0], *(te for te, _ in edges), t[-1]])
                closed = np.array([0.0, *(float(c) for _, c in edges), edges[-1][1] if edges
                                   else 0.0])
            else:
                tk, closed = t, switch_closed(table, k).astype(float)
            ax.fill_between(tk, base, base + closed * height, step="post", color=SWITCH_COLOUR,
                            alpha=0.45, lw=0)
            ax.step(tk, base + closed * height, where="post", lw=0.8, color=SWITCH_COLOUR)
            ticklabels.append(f"S{k}  {labels.get(k, '')}")
        ticks.append(base + 0.5 * height)
    ax.set_yticks(ticks, ticklabels, fontsize=8)
    ax.set_ylim(-0.3, len(rows))
    ax.set_xlabel("mission time [s]")
    ax.grid(True, axis="x", alpha=0.3)
    fig.legend(*ax.get_legend_handles_labels(), loc="outside lower center", ncol=3, fontsize=8,
               title="S7/S8 row: share of telemetry samples on each contact "
                     "(stacked roll, pitch, yaw)", title_fontsize=8)
    return fig


def counters(table: np.ndarray, summary=None) -> Figure:
    """Up/down counters 14/16/18 and drift counters 13/15/17 [pulses] against time.

    ``table`` is the telemetry, in :data:`allsky.sim.telemetry.COLUMNS` order;
    with a ``summary`` the modes are shaded from its timeline (:func:`mode_spans`).
    """
    t = _col(table, "time")
    spans = mode_spans(table, summary)
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


def jets(table: np.ndarray, summary=None) -> Figure:
    """Valve commands of modulators 34-36 (jets 39-41) per axis, and propellant [kg].

    Valve commands are telemetry samples (one every telemetry interval), so
    pulses shorter than the interval may not show; the propellant curve
    counts every pulse.

    ``table`` is the telemetry, in :data:`allsky.sim.telemetry.COLUMNS` order;
    with a ``summary`` the modes are shaded from its timeline (:func:`mode_spans`).
    """
    t = _col(table, "time")
    spans = mode_spans(table, summary)
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
    """Stored calibration against the truth, with the errors.

    Drift, scale factor and cross-coupling, one panel each.

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


#: Bode curve looks per axis, so that the three axes stay visible where their curves
#: coincide (pitch and yaw differ by hundredths of a dB): yaw a wide pale band at the
#: bottom, roll and pitch thin lines above it with their own markers, pitch on top.
BODE_LOOKS = {
    "roll": {"lw": 1.3, "marker": "o", "ms": 4, "mfc": "none", "markevery": (0.0, 0.12),
             "zorder": 3},
    "pitch": {"lw": 1.0, "marker": "^", "ms": 4, "markevery": (0.04, 0.12), "zorder": 4},
    "yaw": {"lw": 4.0, "alpha": 0.45, "marker": "s", "ms": 4, "markevery": (0.08, 0.12),
            "zorder": 2},
}
UNSTABLE_COLOUR = "red"


def unstable_loops(margins: dict) -> list:
    """The loops to flag, ``[(loop name, margins), ...]``.

    A loop is flagged when its closed loop is unstable (``stable`` false) or
    its gain or phase margin is negative. ``margins`` are
    :func:`allsky.studies.analysis.loop_margins`'.
    """
    out = []
    for kind in ("position", "rate"):
        for axis, m in margins.get(kind, {}).items():
            if (m.get("stable") is False or m["gain_margin_db"] < 0.0
                    or m["phase_margin_deg"] < 0.0):
                out.append((f"{kind} {axis}", m))
    return out


def _flag_unstable(fig, mag, phase, margins):
    """Red "UNSTABLE" with the margins, and red crosses at the phase crossovers."""
    flagged = unstable_loops(margins)
    if not flagged:
        return
    lines = []
    for name, m in flagged:
        verdict = "NEGATIVE MARGIN (closed loop stable)" if m.get("stable") is True \
            else "UNSTABLE"
        lines.append(f"{verdict} {name}: GM {m['gain_margin_db']:.1f} dB, "
                     f"PM {m['phase_margin_deg']:.1f}°")
        w_pc = m.get("phase_crossover_rad_s", math.nan)
        if math.isfinite(w_pc) and math.isfinite(m["gain_margin_db"]):
            # |L| at the phase crossover is -GM dB: above 0 dB when the margin is negative.
            mag.plot([w_pc], [-m["gain_margin_db"]], "X", color=UNSTABLE_COLOUR, ms=10,
                     mec="black", mew=0.5, zorder=6)
            phase.plot([w_pc], [-180.0], "X", color=UNSTABLE_COLOUR, ms=10, mec="black",
                       mew=0.5, zorder=6)
    mag.text(0.98, 0.97, "\n".join(lines), transform=mag.transAxes, ha="right", va="top",
             fontsize=9, fontweight="bold", color=UNSTABLE_COLOUR,
             bbox={"facecolor": "white", "edgecolor": UNSTABLE_COLOUR, "alpha": 0.9})
    fig.suptitle(fig.get_suptitle() + " — UNSTABLE LOOP", fontsize=12,
                 color=UNSTABLE_COLOUR)


def analysis(result: dict, frequency_responses: dict) -> Figure:
    """``allsky analyze``: Bode plots with margins, and the PWPF static characteristic.

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
        look = dict(ls=styles[kind], color=AXIS_COLOURS[axis], label=name, **BODE_LOOKS[axis])
        mag.semilogx(w, 20.0 * np.log10(m), **look)
        phase.semilogx(w, ph, **look)
        mm = result["margins"][kind][axis]
        phase.plot(mm["crossover_rad_s"], -180.0 + mm["phase_margin_deg"], "o",
                   color=AXIS_COLOURS[axis], ms=4, zorder=5)
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
    _flag_unstable(fig, mag, phase, result["margins"])
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


def hold_spans(table: np.ndarray) -> list:
    """``[(t_start_s, t_end_s), ...]`` of every hold on target in the telemetry.

    ``table`` is the telemetry, in :data:`allsky.sim.telemetry.COLUMNS` order.
    """
    return [(t0, t1) for name, t0, t1 in mode_spans(table) if name == "hold"]


def hold_drift_arcsec(table: np.ndarray, span):
    """Minutes into the hold ``span`` and the attitude's turn per body axis [arcsec].

    The turn is ``2 q_vec`` of ``q_0^-1 (x) q`` from the first sample of the
    hold, as the summary measures the drift
    (:func:`allsky.sequencer.master_sequencer.measure_hold`); each row is the
    rotation about roll, pitch or yaw.

    ``table`` is the telemetry, in :data:`allsky.sim.telemetry.COLUMNS` order.
    """
    t = _col(table, "time")
    rows = (t >= span[0]) & (t <= span[1]) & np.isclose(_col(table, "mode"), MODE_CODE["hold"])
    q = table[rows][:, [INDEX[c] for c in ("q_w", "q_x", "q_y", "q_z")]]
    conj = q[0] * np.array([1.0, -1.0, -1.0, -1.0])
    turn = np.array([quaternion.multiply(conj, qk) for qk in q])
    turn[turn[:, 0] < 0] *= -1.0  # the short way round
    return (t[rows] - t[rows][0]) / 60.0, 2.0 * turn[:, 1:4].T * RAD2ARCSEC


def _summary_holds(summary) -> list:
    """The hold measurements of a summary, one per target (None where none)."""
    if summary is None:
        return []
    if summary.get("targets"):
        return [t.get("hold") for t in summary["targets"]]
    return [summary.get("hold")]


def hold_drift(table: np.ndarray, summary=None) -> Figure:
    """Each hold on target: the attitude's drift per body axis and its fitted rate.

    On the gyros alone the vehicle turns at the rate its drift store errs
    (docs/theory_of_operation.md); pitch and yaw are the roll axis walking
    off the target. A least-squares line gives each axis's rate
    [arcsec/min]; with the ``summary``, its end-to-end figure is shown too.

    ``table`` is the telemetry, in :data:`allsky.sim.telemetry.COLUMNS` order.
    """
    spans = hold_spans(table)
    if not spans:
        raise ValueError("the telemetry holds no hold on target")
    measured = _summary_holds(summary)
    fig, axes = _new_figure(3, "Hold on target on the gyros alone: attitude drift since the "
                               "hold began")
    styles = ("-", "--", ":", "-.")
    for k, span in enumerate(spans):
        minutes, turn = hold_drift_arcsec(table, span)
        hold = measured[k] if k < len(measured) else None
        for axis, ax, values in zip(AXES, axes, turn):
            rate, offset = np.polyfit(minutes, values, 1) if len(minutes) > 1 else (0.0, 0.0)
            label = f"hold {k + 1}: fit {rate:+.3f}″/min"
            if hold is not None:
                label += f" (summary {hold['drift_arcsec_per_min'][axis]:+.3f})"
            ax.plot(minutes, values, lw=0.9, ls=styles[k % len(styles)],
                    color=AXIS_COLOURS[axis], alpha=0.9 if k == 0 else 0.6, label=label)
            ax.plot(minutes, offset + rate * minutes, lw=1.4, color="black",
                    ls=styles[k % len(styles)], alpha=0.7)
    for axis, ax in zip(AXES, axes):
        ax.set_ylabel(f"{axis} [arcsec]")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.0, 1.0))
    axes[0].set_title("turn about each body axis since the hold's start; black: "
                      "least-squares line", fontsize=10, loc="left")
    axes[-1].set_xlabel("minutes into the hold")
    return fig


#: Figure name -> (file name, function of the telemetry table).
TELEMETRY_FIGURES = {
    "attitude_errors": ("attitude_errors.png", attitude_errors),
    "switches": ("switches.png", switch_timing),
    "counters": ("counters.png", counters),
    "jets": ("jets.png", jets),
}
#: Telemetry figures that also draw from the mission summary when it is given.
USES_SUMMARY = (attitude_errors, switch_timing, counters, jets)
CALIBRATION_FILE = "calibration.png"
HOLD_FILE = "hold.png"


class PlotSet(NamedTuple):
    """What :func:`write_plots` did."""

    files: list  #: paths of the PNG files written
    skipped: dict  #: file name -> why it was not drawn


def save(fig: Figure, path, option=None) -> Path:
    """Write figure ``fig`` to ``path`` at :data:`DPI`; ``option`` names it in errors.

    The file is written whole or not at all; returns its path.
    """
    from allsky.apps.output import write_atomic  # whole or not at all

    return write_atomic(path, writer=lambda tmp: fig.savefig(tmp, dpi=DPI), option=option)


def write_plots(table: np.ndarray, out_dir, summary=None, progress=False,
                option="--plots") -> PlotSet:
    """Write the mission figures as PNG files into ``out_dir`` (created if needed).

    Parameters
    ----------
    table : numpy.ndarray
        Telemetry, :data:`allsky.sim.telemetry.COLUMNS` order.
    out_dir : path
        Directory for the files.
    summary : dict, optional
        The mission summary; without it (or without a stored calibration) the
        calibration figure is skipped, and the attitude figure lacks the true
        final pointing error.
    progress : bool
        Show a progress line on stderr while drawing (when it is a terminal).
    option : str
        The command-line option that named ``out_dir``, for a file that cannot
        be written (:class:`~allsky.apps.output.OutputError`).

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
    jobs = [(name, lambda draw=draw: draw(table, summary) if draw in USES_SUMMARY
             else draw(table)) for name, draw in TELEMETRY_FIGURES.values()]
    if summary is None:
        skipped[CALIBRATION_FILE] = "no mission summary (give --summary SUMMARY.json)"
    elif summary.get("calibration") is None:
        skipped[CALIBRATION_FILE] = "the mission stored no calibration"
    else:
        jobs.append((CALIBRATION_FILE, lambda: calibration(summary)))
    if hold_spans(table):  # drawn only for a mission that held a target
        jobs.append((HOLD_FILE, lambda: hold_drift(table, summary)))
    with tqdm(jobs, desc="figures", unit="figure", leave=False,
              disable=None if progress else True) as bar:
        for file_name, draw in bar:
            bar.set_postfix_str(file_name)
            files.append(save(draw(), out / file_name, option))
    return PlotSet(files, skipped)


def format_written(result: PlotSet) -> str:
    """One line per file written or skipped, from ``result`` (:class:`PlotSet`)."""
    lines = [f"plot: {p}" for p in result.files]
    lines += [f"plot: skipped {name}: {why}" for name, why in result.skipped.items()]
    return "\n".join(lines)


def run_from_cli(cfg, args) -> int:
    """``allsky plot TELEMETRY [--out DIR] [--summary SUMMARY.json]`` (``cfg`` unused).

    ``args`` is the parsed command line (:mod:`allsky.apps.cli`); returns the
    exit status.
    """
    table, _ = read(args.telemetry)
    if len(table) == 0:
        raise TelemetryError(f"telemetry file {args.telemetry!r} has no rows: nothing to plot")
    summary = None
    if args.summary:
        from allsky.apps.summaries import read_summary

        summary = read_summary(args.summary)
    from allsky.apps.output import OutputError, write_reason

    try:
        written = write_plots(table, args.out, summary,
                              progress=not getattr(args, "quiet", False))
    except OSError as e:  # the directory could not be made
        raise OutputError("--out", e.filename or args.out, write_reason(e)) from None
    except OutputError as e:  # a figure could not be written: named by this command's option
        raise OutputError("--out", e.path, e.reason) from None
    print(format_written(written))
    return 0
