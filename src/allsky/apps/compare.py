"""``allsky compare``: the comparison's table, its figure and the command.

The missions are flown and the figures computed by
:func:`allsky.studies.compare.compare`; this module presents them.
"""

import json
from pathlib import Path

import numpy as np

from allsky.studies.compare import AXES, CC_KEYS, compare, label_percentiles
from allsky.units import FRACTION2PPM


def _fmt(v, spec=".1f"):
    if isinstance(v, dict):
        return f"{v['mean']:{spec}} ± {v['std']:{spec}} (p95 {v['p95']:{spec}})"
    return "-" if v is None else f"{v:{spec}}"


def format_compare(result) -> str:
    """Side-by-side table of a comparison (:func:`allsky.studies.compare.compare`)."""
    leg, dit = result["legacy"], result["dither"]
    pred = result["predicted_scale_factor_sigma_ppm"]
    n = result["runs"]
    head = (f"Calibration methods compared on the same vehicle ({n} run{'s' if n > 1 else ''},"
            f" seeds {result['seeds'][0]}-{result['seeds'][1]})")
    if result.get("interrupted"):
        head += f"; interrupted after {n} of {result['runs_requested']} pairs"
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

    Legacy: |error| of each complete run, roll and yaw, at its calibration
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
    """PNG of :func:`comparison_figure` at ``path``; returns the path."""
    path = Path(path)
    comparison_figure(result, pulse_weight_arcsec).savefig(path, dpi=120)
    return path


def run_from_cli(cfg, args) -> int:
    """``allsky compare``: fly the pairs, print the table, write --json and the plot.

    Ctrl-C or SIGTERM after some pairs finished: the table, ``--json`` (marked
    ``interrupted``) and the plot of those pairs are written, and
    :class:`~allsky.apps.output.Interrupted` says so.
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
    show = runs > 1 and not args.quiet
    bar = tqdm(total=runs, desc="missions", unit="pair", file=sys.stderr,
               disable=None if show else True)
    try:
        result = compare(cfg, runs=runs, workers=workers,
                         on_progress=lambda done, total: bar.update(done - bar.n))
    finally:
        bar.close()
    say(format_compare(result))
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
        write_atomic(args.plot, writer=lambda tmp: plot(result, tmp, pulse_weight),
                     option="--plot")
        written.append(args.plot)
        say(f"plot: {args.plot}")
    if result.get("interrupted"):
        files = f"; written: {', '.join(written)}" if written else ""
        raise Interrupted(f"after {result['runs']} of {result['runs_requested']} pairs (the "
                          f"table and JSON cover those, marked interrupted){files}")
    return 0
