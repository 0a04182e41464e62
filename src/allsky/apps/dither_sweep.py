"""``allsky compare --sweep``: the dither trade study's table, figure and command.

The grid is flown and summarised by :func:`allsky.studies.dither_sweep.sweep`;
this module parses the ``--sweep`` option and presents the result.
"""

import argparse
import json
from pathlib import Path

#: Names ``--sweep`` accepts: the arguments of :func:`allsky.studies.dither_sweep.sweep`
#: (``amplitudes_urad``, ``records_s``) one value at a time.
SWEEP_NAMES = ("amplitude_urad", "record_s")


def sweep_axis(text):
    """Parse one ``--sweep NAME=V1,V2,...`` into ``(name, (v1, v2, ...))``.

    ``text`` is the option's value. The values are positive, finite numbers.
    """
    name, sep, values = text.partition("=")
    name = name.strip()
    if not sep or name not in SWEEP_NAMES:
        raise argparse.ArgumentTypeError(
            f"{text!r}: expected NAME=V1,V2,... with NAME one of {', '.join(SWEEP_NAMES)}")
    out = []
    for v in values.split(","):
        try:
            x = float(v)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name}: {v!r} is not a number") from None
        if not 0.0 < x < float("inf"):
            raise argparse.ArgumentTypeError(f"{name}: {x} must be a positive, finite number")
        out.append(x)
    return name, tuple(out)


#: Most grid points a trade study flies (amplitudes x record lengths).
SWEEP_POINTS_MAX = 1000


def grid_from_args(cfg, sweeps):
    """Amplitudes [µrad] and record lengths [s] from the ``--sweep`` options.

    ``sweeps`` are the ``--sweep`` values as given (text); a name not given
    keeps scenario ``cfg``'s value (the largest amplitude of the dithered
    axes; ``dither.record_s``). A name given twice raises
    :class:`allsky.config.ConfigError` naming ``--sweep``.
    """
    from allsky.config import ConfigError

    given = {}
    for name, values in sweeps:
        if name in given:
            raise ConfigError("--sweep", name, "each of amplitude_urad and record_s at most once")
        given[name] = values
    amps = given.get("amplitude_urad", (max(cfg.dither.amplitude_urad),))
    records = given.get("record_s", (float(cfg.dither.record_s),))
    amps, records = sorted(set(amps)), sorted(set(records))
    points = len(amps) * len(records)
    if points > SWEEP_POINTS_MAX:
        raise ConfigError("--sweep", f"{len(amps)} x {len(records)}",
                          f"{points} grid points, more than {SWEEP_POINTS_MAX} (each point "
                          "flies --runs missions)")
    return amps, records


def _g(v, spec):
    return "-" if v is None else f"{v:{spec}}"


def format_sweep(result) -> str:
    """The trade study as a table: one line per grid point, the legacy reference first.

    ``result`` is :func:`allsky.studies.dither_sweep.sweep`'s.
    """
    leg = result["legacy"]
    rms = leg.get("scale_factor_rms_error_ppm", {})
    axes = sorted({a for p in result["points"] for a in p.get("predicted_sigma_ppm", {})},
                  key=("roll", "yaw").index)
    rows = [(f"Dither trade study ({result['runs']} run{'s' if result['runs'] > 1 else ''} per "
             f"point, seeds {result['seeds'][0]}-{result['seeds'][1]}); RMS scale-factor "
             "error [ppm]: own register 23 / legacy cross-coupling known / predicted 1-sigma"),
            "  legacy turns: " + ", ".join(f"{a} {_g(rms.get(a), '.1f')}" for a in axes)
            + f"; {_g(leg.get('time_s'), '.0f')} s; largest excursion "
              f"{_g(leg.get('max_excursion_arcsec'), '.0f')}″",
            "",
            f"  {'A [µrad]':>9}{'T [s]':>9}" + "".join(f"{a + ' [ppm]':>28}" for a in axes)
            + f"{'time [s]':>10}{'excursion [″]':>15}"]
    for p in result["points"]:
        own = p.get("scale_factor_rms_error_ppm", {})
        known = p.get("scale_factor_rms_error_same_misalignment_ppm", {})
        pred = p.get("predicted_sigma_ppm", {})
        cells = "".join(f"{' / '.join(_g(v.get(a), '.1f') for v in (own, known, pred)):>28}"
                        for a in axes)
        rows.append(f"  {p['amplitude_urad']:>9g}{p['record_s']:>9g}{cells}"
                    f"{_g(p.get('time_s'), '.0f'):>10}{_g(p.get('max_excursion_arcsec'), '.0f'):>15}")
    rows.append("")
    for label, key in (("legacy cross-coupling known", "crossover"),
                       ("own register 23", "crossover_own_register")):
        for t, per_axis in result.get(key, {}).items():
            parts = []
            for a, c in per_axis.items():
                if c is None:
                    parts.append(f"{a} not within the grid")
                else:
                    at = "" if c["bracketed"] else "at most "
                    parts.append(f"{a} at {at}{c['amplitude_urad']:.0f} µrad ({c['time_s']:.0f} s,"
                                 f" excursion {c['max_excursion_arcsec']:.0f}″)")
            rows.append(f"  reaches the legacy accuracy ({label}), T = {t} s: " + "; ".join(parts))
    return "\n".join(rows)


def sweep_figure(result):
    """RMS scale-factor error against amplitude, one line per record length.

    The largest excursion is on the right axis.

    Solid lines: the dither with the legacy cross-coupling known; dotted:
    its own register 23; thin dashed: the analytic 1-sigma. The horizontal
    line per axis is the legacy turns' RMS error; the right axis (grey) the
    largest excursion from the attitude held. ``result`` is
    :func:`allsky.studies.dither_sweep.sweep`'s.

    Returns
    -------
    matplotlib.figure.Figure
    """
    import numpy as np
    from matplotlib.figure import Figure  # imported here: the table alone needs no figures

    pts = result["points"]
    axes_names = [a for a in ("roll", "yaw")
                  if any(a in p.get("predicted_sigma_ppm", {}) for p in pts)]
    fig = Figure(figsize=(6.2 * len(axes_names), 5.6), layout="constrained")
    subplots = np.atleast_1d(fig.subplots(1, len(axes_names), sharey=True))
    records = sorted({p["record_s"] for p in pts})
    leg_rms = result["legacy"].get("scale_factor_rms_error_ppm", {})
    for ax, a in zip(subplots, axes_names):
        for k, t in enumerate(records):
            line = sorted((p for p in pts if p["record_s"] == t),
                          key=lambda p: p["amplitude_urad"])
            amp = [p["amplitude_urad"] for p in line]
            color = f"C{k}"
            known = [p.get("scale_factor_rms_error_same_misalignment_ppm", {}).get(a)
                     for p in line]
            own = [p.get("scale_factor_rms_error_ppm", {}).get(a) for p in line]
            pred = [p.get("predicted_sigma_ppm", {}).get(a) for p in line]
            ax.plot(amp, known, "o-", color=color, label=f"T = {t:g} s, misalignment known")
            ax.plot(amp, own, "s:", color=color, ms=4, label=f"T = {t:g} s, own register 23")
            ax.plot(amp, pred, "--", color=color, lw=0.8, alpha=0.7)
        if a in leg_rms:
            ax.axhline(leg_rms[a], color="k", lw=1.2)
            ax.text(min(p["amplitude_urad"] for p in pts), leg_rms[a] * 1.15, f"legacy 360° turns: {leg_rms[a]:.1f} ppm", fontsize=8)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("dither amplitude [µrad]")
        ax.set_title(f"{a}: RMS scale-factor error over {result['runs']} runs")
        ax.grid(True, which="both", alpha=0.3)
        right = ax.twinx()
        exc = {}
        for p in pts:
            exc[p["amplitude_urad"]] = max(exc.get(p["amplitude_urad"], 0.0),
                                           p.get("max_excursion_arcsec") or 0.0)
        xs = sorted(exc)
        right.plot(xs, [exc[x] for x in xs], "^-", color="0.55", lw=1, ms=4,
                   label="largest excursion")
        right.set_yscale("log")
        right.set_ylabel("largest excursion from the attitude held [″]", color="0.4")
        right.tick_params(axis="y", colors="0.4")
    from matplotlib.lines import Line2D

    handles, _ = subplots[0].get_legend_handles_labels()
    handles += [Line2D([], [], ls="--", lw=0.8, color="0.3", label="predicted 1σ"),
                Line2D([], [], marker="^", color="0.55", lw=1, ms=4,
                       label="largest excursion (right axis)")]
    subplots[0].set_ylabel("RMS scale-factor error [ppm]")
    fig.legend(handles=handles, fontsize=8, loc="outside lower center", ncol=4)
    return fig


def run_from_cli(cfg, args) -> int:
    """``allsky compare --sweep``: fly the grid, print the table, write the files.

    ``--json`` gets :func:`allsky.studies.dither_sweep.sweep`'s result,
    ``--plot`` :func:`sweep_figure`.

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
    from allsky.config import ConfigError
    from allsky.config.rules import RUNS_MAX
    from allsky.studies.dither_sweep import sweep

    check_output("--json", args.json)
    check_output("--plot", args.plot, suffixes=FIGURE_SUFFIXES)
    if getattr(args, "vehicle", None) is not None:  # --vehicle: the sweep flies that one
        from allsky.studies.compare import on_vehicle

        cfg = on_vehicle(cfg, args.vehicle)
    amps, records = grid_from_args(cfg, args.sweep)
    runs = int(args.runs)
    to_stdout = args.json == "-"
    say = (lambda *a, **k: None) if to_stdout else print
    n_missions = runs * (1 + len(amps) * len(records))
    if n_missions > RUNS_MAX:
        raise ConfigError("--sweep", n_missions, f"missions ({runs} per grid point and for "
                          f"the reference), more than {RUNS_MAX}, as --runs is bounded")
    workers, note = cap_workers(args.workers, n_missions)
    if note:
        print(f"allsky: {note}", file=sys.stderr)
    bar = tqdm(total=n_missions, desc="missions", unit="mission", file=sys.stderr,
               disable=True if args.quiet else None)
    try:
        result = sweep(cfg, amps, records, runs=runs, workers=workers,
                       on_progress=lambda done, total: bar.update(done - bar.n))
    finally:
        bar.close()
    say(format_sweep(result))
    written = []
    if to_stdout:
        print(json.dumps(result, indent=2))
    elif args.json:
        write_atomic(args.json, json.dumps(result, indent=2) + "\n", option="--json")
        say(f"wrote trade study {args.json}")
        written.append(args.json)
    if args.plot and result["points"]:
        def draw(tmp):
            sweep_figure(result).savefig(Path(tmp), dpi=120)
        write_atomic(args.plot, writer=draw, option="--plot")
        say(f"plot: {args.plot}")
        written.append(args.plot)
    if result.get("interrupted"):
        files = f"; written: {', '.join(written)}" if written else ""
        raise Interrupted(f"after {len(result['points'])} of {len(amps) * len(records)} grid "
                          f"points (the table covers those){files}")
    return 0
