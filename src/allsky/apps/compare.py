"""``allsky compare``: the comparison's table, its figure and the command.

The missions are flown and the figures computed by
:func:`allsky.studies.compare.compare`; this module presents them.
"""

import json
from pathlib import Path

import numpy as np

from allsky.studies.compare import (
    AXES,
    CC_KEYS,
    DEFAULT_METHODS,
    compare,
    flights_per_seed,
    label_percentiles,
)
from allsky.units import FRACTION2PPM
from allsky.vocabulary import AXES as BODY_AXES


def _fmt(v, spec=".1f"):
    if isinstance(v, dict):
        return f"{v['mean']:{spec}} ± {v['std']:{spec}} (p95 {v['p95']:{spec}})"
    return "-" if v is None else f"{v:{spec}}"


def headline(result) -> tuple:
    """The comparison's headline table, as data: ``(title, rows, notes)``.

    ``result`` is :func:`allsky.studies.compare.compare`'s. ``rows`` are
    ``(figure, legacy, dither)`` texts, ``notes`` the lines under the table;
    :func:`format_compare` prints them, :class:`allsky.apps.comparison.Comparison`
    shows them as HTML.
    """
    leg, dit = result["legacy"], result["dither"]
    pred = result["predicted_scale_factor_sigma_ppm"]
    n = result["runs"]
    on = ("the same reaction-wheel vehicle" if result.get("vehicle") == "wheels"
          else "the same vehicle")
    head = (f"Calibration methods compared on {on} ({n} run{'s' if n > 1 else ''},"
            f" seeds {result['seeds'][0]}-{result['seeds'][1]})")
    if result.get("interrupted"):
        head += f"; interrupted after {n} of {result['runs_requested']} pairs"
    rows, notes = [], []

    def line(name, a, b, spec=".1f"):
        rows.append((name, _fmt(a, spec), _fmt(b, spec)))

    for ax in AXES:
        line(f"scale-factor error {ax} [ppm]", leg.get("scale_factor_error_ppm", {}).get(ax),
             dit.get("scale_factor_error_ppm", {}).get(ax))
    for ax in AXES:
        line(f"  {ax}, legacy cross-coupling known", None,
             dit.get("scale_factor_error_same_misalignment_ppm", {}).get(ax))
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
    line("  same misalignment knowledge", leg.get("pointing_error_same_misalignment_arcsec"),
         dit.get("pointing_error_same_misalignment_arcsec"))
    line("  star-tracker architecture (slews)",
         leg.get("pointing_error_tracker_architecture_arcsec"),
         dit.get("pointing_error_tracker_architecture_arcsec"))
    if "tracking_ratio" in dit:
        for ax, v in dit["tracking_ratio"].items():
            notes.append(f"  dither tracking {ax}: optical amplitude / commanded = "
                        f"{_fmt(v, '.4f')}")
    chk = result.get("dither_torque_check")
    if chk:
        peak = ", ".join(f"{v:.2g}" for v in chk["torque_peak_n_m"])
        notes.append(f"  dither feed-forward torque, peak [N m] (roll, pitch, yaw): {peak}")
        notes.append(f"    margin in the wheels' torque envelope {chk['wheels']['margin']:.3g}, "
                    f"in the jets' {chk['jets']['margin']:.3g}")
    if n > 1:
        for method in ("legacy", "dither"):
            r = result[method]
            if r.get("complete", 0) < n:
                notes.append(f"  {method}: {n - r.get('complete', 0)} of {n} missions aborted")
    return head, rows, [n.strip() for n in notes]


def format_compare(result) -> str:
    """Side-by-side table of a comparison (:func:`headline`, as text).

    ``result`` is :func:`allsky.studies.compare.compare`'s.
    """
    head, rows, notes = headline(result)
    out = [head, "", f"  {'figure':<34}{'legacy (Modes 4-5)':>34}{'dither':>34}"]
    out += [f"  {name:<34}{a:>34}{b:>34}" for name, a, b in rows]
    indent = {"margin": "    "}
    out += [f"{indent.get(n.split()[0], '  ')}{n}" for n in notes]
    return "\n".join(out)


#: [arcsec] One full turn, the angle the legacy modes count (SPEC section 4).
FULL_TURN_ARCSEC = 1296000.0


def count_floor_ppm(pulse_weight_arcsec: float) -> float:
    """[ppm] Half a VFC pulse in the 360 deg count: the legacy method's rounding limit.

    The legacy scale factor is 360 deg over the counted angle, counted in
    pulses of ``pulse_weight_arcsec``; an error smaller than half a pulse in
    1 296 000 arcsec is a count that came out exact, not a better calibration.
    """
    return FRACTION2PPM * 0.5 * pulse_weight_arcsec / FULL_TURN_ARCSEC


def comparison_figure(result, pulse_weight_arcsec: float):
    """Scale-factor error against calibration time for both methods (log-log).

    Legacy: ``|error|`` of each complete run, roll and yaw, at its calibration
    time. Values below :func:`count_floor_ppm` (exact counts, down to 0) are
    drawn at that floor as open down-triangles and counted on the figure, so
    that the axis spans the methods' errors, not a lucky count's 1e-10 ppm.
    Dither: RMS over the runs of the error from shorter records.

    Parameters
    ----------
    result : dict
        :func:`allsky.studies.compare.compare`.
    pulse_weight_arcsec : float
        [arcsec] VFC pulse weight of the scenario (``electronics.vfc_pulse_weight_arcsec``).

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib.figure import Figure  # imported here: the table alone needs no figures

    floor = count_floor_ppm(pulse_weight_arcsec)
    fig = Figure(figsize=(7.5, 4.8), layout="constrained")
    ax = fig.subplots()
    rows = [r for r in result["rows"] if r["legacy"]["status"] == "complete"]
    clipped = 0
    for a, mk in (("roll", "o"), ("yaw", "s")):
        t = np.array([r["legacy"]["time_s"] for r in rows])
        e = np.array([abs(r["legacy"]["scale_factor_error_ppm"][a]) for r in rows])
        low = e < floor
        clipped += int(np.count_nonzero(low))
        dots = ax.scatter(t[~low], e[~low], marker=mk, s=14, alpha=0.5,
                          label=f"legacy |error| {a}")
        if np.any(low):
            ax.scatter(t[low], np.full(np.count_nonzero(low), floor), marker="v", s=30,
                       facecolors="none", edgecolors=dots.get_facecolor()[0],
                       label=f"legacy |error| {a} below the floor, drawn at it")
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
    ax.axhline(floor, color="0.4", lw=0.8, ls=":")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_ylim(bottom=floor / 2.0)
    ax.set_xlabel("calibration time [s]")
    ax.set_ylabel("scale-factor error [ppm]")
    ax.set_title("Gyro scale-factor calibration: 360° turns vs dither")
    note = (f"floor {floor:.3g} ppm: half a {pulse_weight_arcsec:g}″ pulse in the 360° count"
            f"\n{clipped} legacy value{'s' if clipped != 1 else ''} below it drawn at it (▽)")
    ax.text(0.01, 0.02, note, transform=ax.transAxes, ha="left", va="bottom", fontsize=8,
            color="0.25", bbox={"facecolor": "white", "alpha": 0.8, "lw": 0})
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8, loc="center left")
    return fig


def plot(result, path, pulse_weight_arcsec: float) -> Path:
    """PNG of :func:`comparison_figure` at ``path``; returns the path.

    ``result`` and ``pulse_weight_arcsec`` [arcsec] are passed to
    :func:`comparison_figure`.
    """
    path = Path(path)
    comparison_figure(result, pulse_weight_arcsec).savefig(path, dpi=120)
    return path


def run_from_cli(cfg, args) -> int:
    """``allsky compare``: fly the pairs, print the table, write --json and the plot.

    Ctrl-C or SIGTERM after some pairs finished: the table, ``--json`` (marked
    ``interrupted``) and the plot of those pairs are written, and
    :class:`~allsky.apps.output.Interrupted` says so.

    ``cfg`` is the scenario the command line loaded (``--scenario``, ``--set``)
    and ``args`` the parsed command line (:mod:`allsky.apps.cli`); returns the
    exit status.
    """
    import sys

    from tqdm import tqdm

    from allsky.apps.output import (
        FIGURE_SUFFIXES,
        Interrupted,
        cap_workers,
        check_output,
        write_atomic,
    )

    check_output("--json", args.json)
    check_output("--plot", args.plot, suffixes=FIGURE_SUFFIXES)
    runs = int(args.runs)
    to_stdout = args.json == "-"
    say = (lambda *a, **k: None) if to_stdout else print
    workers, note = cap_workers(args.workers, runs)
    if note and runs > 1:
        print(f"allsky: {note}", file=sys.stderr)
    methods = args.methods or DEFAULT_METHODS
    # One run: a step per mission of the pair (each takes seconds, the filter's longer);
    # several: a step per pair. Shown on a terminal unless --quiet.
    one = runs == 1
    total = flights_per_seed(methods) if one else runs
    bar = tqdm(total=total, desc="missions", unit="mission" if one else "pair",
               file=sys.stderr, disable=True if args.quiet else None)

    def flown(name):
        bar.set_postfix_str(name, refresh=False)
        bar.update(1)

    try:
        result = compare(cfg, runs=runs, workers=workers, vehicle=args.vehicle,
                         methods=methods, on_flight=flown if one else None,
                         on_progress=None if one else
                         lambda done, total: bar.update(done - bar.n))
    finally:
        bar.close()
    say(format_compare(result))
    if "kalman" in result or "smoother" in result:
        say(format_kalman(result))
    say(format_information(result))
    written = []
    if to_stdout:
        print(json.dumps(label_percentiles(result), indent=2))
    elif args.json:
        write_atomic(args.json, json.dumps(label_percentiles(result), indent=2) + "\n",
                     option="--json")
        written.append(args.json)
        say(f"wrote comparison {args.json}")
    if args.plot:
        pulse_weight = cfg.electronics.vfc_pulse_weight_arcsec
        draw = plot_three_way if "kalman" in result or "smoother" in result else plot
        write_atomic(args.plot, writer=lambda tmp: draw(result, tmp, pulse_weight),
                     option="--plot")
        written.append(args.plot)
        say(f"plot: {args.plot}")
    if result.get("interrupted"):
        files = f"; written: {', '.join(written)}" if written else ""
        raise Interrupted(f"after {result['runs']} of {result['runs_requested']} pairs (the "
                          f"table and JSON cover those, marked interrupted){files}")
    return 0


# -- the information limit and where the pointing error comes from ---------------------

#: Rows of the information table: (label, group of the bound, key, unit format).
INFORMATION_ROWS = (
    [(f"scale factor {a} [ppm]", "scale_factor_error_ppm", a, ".2f") for a in AXES]
    + [(f"{k} [arcsec]", "cross_coupling_error_arcsec", k, ".3f") for k in CC_KEYS]
    + [(f"drift {a} [deg/h]", "drift_error_deg_h", a, ".4f") for a in BODY_AXES])
#: Components of ``pointing_decomposition``, as printed.
DECOMPOSITION = (("total_arcsec", "final pointing (as flown)"),
                 ("targeting_arcsec", "  targeting (truth stored)"),
                 ("drift_arcsec", "  drift counters' part"),
                 ("scale_factor_arcsec", "  scale factors' part"),
                 ("misalignment_arcsec", "  cross-couplings' part"),
                 ("interaction_arcsec", "  not additive"))


def _spread(v):
    """(sample sigma, RMS) of a statistic, or of one run's value (sigma None)."""
    if isinstance(v, dict):
        return v["std"], float(np.hypot(v["mean"], v["std"]))
    return None, (None if v is None else abs(v))


def format_information(result) -> str:
    """Each method's measured spread beside the Cramer-Rao bound of its manoeuvres.

    Per method: the bound (RMS over the runs of each run's bound), the
    measured sample sigma and RMS of the error, and RMS / bound: 1 is
    information-limited, more leaves information on the table. Then each
    method's final pointing taken apart (:mod:`allsky.studies.pointing`).
    ``result`` is :func:`allsky.studies.compare.compare`'s.
    """
    bounds = result.get("crlb")
    if not bounds:
        return ""
    cols = [c for c in THREE_WAY if c in bounds]
    rows = ["", ("The information limit: Cramer-Rao bound of each method's manoeuvres, "
            "beside its error (bound / measured sigma / RMS, RMS over bound)"),
            f"  {'quantity':<28}" + "".join(f"{THREE_WAY[c]:>36}" for c in cols)]
    for label, group, key, spec in INFORMATION_ROWS:
        cells = []
        for c in cols:
            b = bounds[c][group].get(key)
            sig, rms = _spread(result[c].get(group, {}).get(key))
            if b is None:
                cells.append("not observable")
                continue
            ratio = "-" if rms is None else f"{rms / b:.2f}x"
            cells.append(f"{b:{spec}} / {_fmt(sig, spec)} / {_fmt(rms, spec)} {ratio}")
        rows.append(f"  {label:<28}" + "".join(f"{c:>36}" for c in cells))
    have = [c for c in THREE_WAY if c in result and result[c].get("pointing_decomposition")]
    if have:
        rows += ["", ("Final pointing taken apart (Mode 6 flown again with the truth stored, "
                 "and with the truth but one group) [arcsec]"),
                 f"  {'part':<28}" + "".join(f"{THREE_WAY[c]:>22}" for c in have)]
        for key, label in DECOMPOSITION:
            rows.append(f"  {label:<28}" + "".join(
                f"{_cell(result[c]['pointing_decomposition'][key]):>22}" for c in have))
    apriori = result.get("predicted_scale_factor_sigma_a_priori_ppm", {}).get("legacy")
    fitted = result["predicted_scale_factor_sigma_ppm"]["legacy"]
    if apriori:
        rows.append("")
        rows.append("  legacy scale-factor 1-sigma predicted a priori (ARW and the dead band's "
                    "0.3\" hold jitter) / fitted (these runs' drift spread) [ppm]: "
                    + ", ".join(f"{a} {apriori[a]:.2f} / {fitted[a]:.2f}" for a in apriori))
    return "\n".join(rows)


#: Manoeuvres of the information figure, as labelled there.
MANOEUVRE_LABELS = {"mode3_hold": "Mode 3\nhold (40 s)", "mode4_roll_turn": "Mode 4\n360° roll",
                    "mode5_yaw_turn": "Mode 5\n360° yaw", "dither_hold": "dither\nhold (881 s)",
                    "modes3_5": "Modes 3-5\ntogether"}


def information_figure(result):
    """The information limit: what each manoeuvre allows, how near each method comes.

    Left: the Cramer-Rao bound of the roll and yaw scale factors and of a
    cross-coupling factor per manoeuvre (``crlb_manoeuvres``; a quantity the
    manoeuvre does not show is marked at the top). Right: each method's RMS
    error over its bound, per quantity (1: information-limited). ``result``
    is :func:`allsky.studies.compare.compare`'s.

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib.figure import Figure

    fig = Figure(figsize=(11.5, 4.6), layout="constrained")
    ax_b, ax_r = fig.subplots(1, 2, width_ratios=(1, 1.25))
    per = result["crlb_manoeuvres"]
    names = [n for n in MANOEUVRE_LABELS if n in per]
    shown = (("scale_factor_ppm", "roll", "scale factor roll [ppm]"),
             ("scale_factor_ppm", "yaw", "scale factor yaw [ppm]"),
             ("cross_coupling_arcsec", "yaw_into_roll", "yaw into roll [arcsec]"))
    top = 1e4
    for j, (group, key, label) in enumerate(shown):
        x = np.arange(len(names)) + (j - 1) * 0.26
        v = [per[n][group][key] for n in names]
        ax_b.bar(x[[i for i, b in enumerate(v) if b is not None]],
                 [b for b in v if b is not None], width=0.24, label=label, color=f"C{j}")
        for i, b in enumerate(v):
            if b is None:
                ax_b.text(x[i], top * 0.6, "n/o", ha="center", va="top", fontsize=7,
                          color=f"C{j}", rotation=90)
    ax_b.set_yscale("log")
    ax_b.set_ylim(0.1, top)
    ax_b.set_xticks(range(len(names)), [MANOEUVRE_LABELS[n] for n in names], fontsize=8)
    ax_b.set_ylabel("Cramér-Rao bound, 1 sigma")
    ax_b.set_title("What each manoeuvre allows (n/o: not observable)")
    ax_b.legend(fontsize=7, loc="upper right")
    ax_b.grid(True, which="major", axis="y", alpha=0.3)
    cols = [c for c in THREE_WAY if c in result.get("crlb", {})]
    quantities = [(g, k) for _, g, k, _ in INFORMATION_ROWS]
    for i, c in enumerate(cols):
        ratio = []
        for g, k in quantities:
            b = result["crlb"][c][g].get(k)
            _, rms = _spread(result[c].get(g, {}).get(k))
            ratio.append(np.nan if b is None or rms is None else rms / b)
        ax_r.plot(np.arange(len(quantities)) + (i - len(cols) / 2) * 0.08, ratio, "o",
                  label=THREE_WAY[c], color=f"C{i}", ms=5)
    ax_r.axhline(1.0, color="k", lw=0.8, ls="--")
    ax_r.set_yscale("log")
    ax_r.set_xticks(range(len(quantities)),
                    [f"{'sf' if g.startswith('scale') else 'drift' if g.startswith('drift') else ''}"
                     f" {k.replace('_into_', '→')}".strip() for g, k in quantities],
                    fontsize=7, rotation=35)
    ax_r.set_ylabel("RMS error / bound of its manoeuvres")
    ax_r.set_title(f"How near each method comes ({result['runs']} runs; 1: information-limited)")
    ax_r.legend(fontsize=7)
    ax_r.grid(True, which="both", axis="y", alpha=0.3)
    return fig


# -- three methods: the Kalman filter beside the legacy turns and the dither -----------

#: Columns of the three-way table and figure: result section -> heading.
THREE_WAY = {"legacy": "legacy (Modes 4-5)", "dither": "dither",
             "kalman": "Kalman, Modes 3-5", "kalman_dither": "Kalman, dither hold",
             "smoother": "smoother, Modes 3-5"}


def _cell(v, spec=".2f"):
    if isinstance(v, dict) and "mean" in v:
        return f"{v['mean']:{spec}} ± {v['std']:{spec}}"
    return "-" if v is None else f"{v:{spec}}"


def format_kalman(result) -> str:
    """Legacy, dither and the Kalman filter's two flights, side by side.

    Cells are one run's value or mean ± standard deviation over the runs;
    "predicted" is each method's analytic 1-sigma (for the filter, the RMS
    of its own sigma over the runs), "measured" the spread of the errors.
    ``result`` is :func:`allsky.studies.compare.compare`'s, flown with the
    ``"kalman"`` method.
    """
    cols = [c for c in THREE_WAY if c in result]
    pred = result["predicted_scale_factor_sigma_ppm"]
    n = result["runs"]
    rows = ["", ("The three-axis Kalman filter and smoother (counters 14/16/18, sun sensor "
                 "104, star tracker 105) beside the others"),
            f"  {'figure':<32}" + "".join(f"{THREE_WAY[c]:>22}" for c in cols)]

    def line(name, values, spec=".2f"):
        rows.append(f"  {name:<32}" + "".join(f"{_cell(v, spec):>22}" for v in values))

    def get(c, key, sub=None):
        v = result[c].get(key)
        return v.get(sub) if isinstance(v, dict) and sub is not None else v

    for ax in AXES:
        line(f"scale-factor error {ax} [ppm]", [get(c, "scale_factor_error_ppm", ax)
                                                for c in cols])
        line(f"  predicted 1-sigma {ax} [ppm]", [pred.get(c, {}).get(ax) for c in cols])
        if n > 1:
            line(f"  measured 1-sigma {ax} [ppm]",
                 [(get(c, "scale_factor_error_ppm", ax) or {}).get("std") for c in cols])
    for k in CC_KEYS:
        line(f"{k} error [arcsec]", [get(c, "cross_coupling_error_arcsec", k) for c in cols])
    for ax in BODY_AXES:
        line(f"drift error {ax} [deg/h]", [get(c, "drift_error_deg_h", ax) for c in cols],
             ".4f")
    line("calibration time [s]", [get(c, "time_s") for c in cols], ".1f")
    line("largest excursion [arcsec]", [get(c, "max_excursion_arcsec") for c in cols], ".0f")
    line("calibration propellant [kg]", [get(c, "propellant_kg") for c in cols], ".3f")
    line("final pointing error [arcsec]", [get(c, "pointing_error_arcsec") for c in cols])
    for c in ("kalman", "kalman_dither", "smoother"):
        if c not in result:
            continue
        v = result[c].get("nees")
        if isinstance(v, dict):
            rows.append(f"  {THREE_WAY[c]}: mean NEES {v['mean']:.2f} over "
                        f"{result[c]['complete']} runs ({v['states']} states; the scenario's "
                        "fixed gyro errors, not a chi-square test: docs/kalman.md, "
                        "Consistency)")
        elif v is not None:
            rows.append(f"  {THREE_WAY[c]}: NEES {v:.2f} (15 states)")
    return "\n".join(rows)


def three_way_figure(result):
    """Scale-factor errors and final pointing of the three methods (log scale).

    Left: ``|scale-factor error|`` of every complete run, roll and yaw, per
    method, with each method's predicted 1-sigma as a bar. Right: the final
    pointing error of every run (Mode 6 flown with each method's register 23).
    ``result`` is :func:`allsky.studies.compare.compare`'s, flown with the
    ``"kalman"`` method.

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9.5, 4.6), layout="constrained")
    ax_sf, ax_pt = fig.subplots(1, 2, width_ratios=(3, 2))
    cols = [c for c in THREE_WAY if c in result]
    pred = result["predicted_scale_factor_sigma_ppm"]
    rng = np.random.default_rng(0)  # horizontal jitter of the dots only
    for i, c in enumerate(cols):
        ok = [r[c] for r in result["rows"] if r[c]["status"] == "complete"
              and "scale_factor_error_ppm" in r[c]]
        for j, (a, mk) in enumerate((("roll", "o"), ("yaw", "s"))):
            x = 3 * i + j + rng.uniform(-0.25, 0.25, len(ok))
            e = np.array([abs(r["scale_factor_error_ppm"][a]) for r in ok])
            ax_sf.scatter(x, np.maximum(e, 1e-4), marker=mk, s=8, alpha=0.45,
                          color=f"C{j}", label=a if i == 0 else None)
            if a in pred.get(c, {}):
                ax_sf.hlines(pred[c][a], 3 * i + j - 0.4, 3 * i + j + 0.4, color="k", lw=1.5,
                             label="predicted 1-sigma" if i == 0 and j == 0 else None)
        pts = [r[c]["pointing_error_arcsec"] for r in result["rows"]
               if r[c]["status"] == "complete"]
        ax_pt.scatter(i + rng.uniform(-0.25, 0.25, len(pts)), pts, s=8, alpha=0.45, color="C2")
    ax_sf.set_xticks([3 * i + 0.5 for i in range(len(cols))],
                     [THREE_WAY[c] for c in cols], fontsize=8, rotation=20)
    ax_sf.set_yscale("log")
    ax_sf.set_ylabel("|scale-factor error| [ppm]")
    ax_sf.set_title("Gyro scale factor: each method")
    ax_sf.legend(fontsize=8)
    ax_sf.grid(True, which="both", axis="y", alpha=0.3)
    ax_pt.set_xticks(range(len(cols)), [THREE_WAY[c] for c in cols], fontsize=8,
                     rotation=20)
    ax_pt.set_yscale("log")
    ax_pt.set_ylabel("final pointing error [arcsec]")
    ax_pt.set_title("Mode 6 with each calibration")
    ax_pt.grid(True, which="both", axis="y", alpha=0.3)
    return fig


def plot_three_way(result, path, pulse_weight_arcsec: float | None = None) -> Path:
    """PNG of :func:`three_way_figure` at ``path``; returns the path.

    ``result`` is passed to it; ``pulse_weight_arcsec`` is unused (the
    signature of :func:`plot`).
    """
    path = Path(path)
    three_way_figure(result).savefig(path, dpi=120)
    return path
