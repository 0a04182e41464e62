"""``allsky window``: the table (and figure) of when to eject.

The rows are :func:`allsky.studies.window.ejection_window`'s: the mission
flown from each candidate ejection time over one orbit.
"""

import json
import sys
import time

from allsky.config import ConfigError


def parse_orbit(text: str) -> dict:
    """``--orbit`` ``text`` (ALT_KM,INC_DEG[,RAAN_DEG[,U_DEG]]) as ``[orbit]`` keys.

    Raises
    ------
    ConfigError
        Naming ``--orbit`` when the text is not 2 to 4 numbers.
    """
    parts = [p.strip() for p in text.split(",")]
    try:
        nums = [float(p) for p in parts]
    except ValueError:
        nums = []
    if not 2 <= len(nums) <= 4:
        raise ConfigError("--orbit", text, "must be ALT_KM,INC_DEG[,RAAN_DEG[,ARG_LATITUDE_DEG]]"
                          " (a circular orbit), e.g. 300,28.5")
    keys = ("altitude_km", "inclination_deg", "raan_deg", "arg_latitude_deg")
    return {"kind": "circular", **dict(zip(keys, nums))}


def format_window(result, wall_s=None) -> str:
    """The window ``result`` as text, a line per ejection time (``wall_s`` [s] taken)."""
    rows = result["rows"]
    lines = [(f"Ejection window: {len(rows)} ejection times every {result['every_s']:g} s over "
             f"one orbit ({result['period_s']:.0f} s)"), "",
             (f"  {'start':>7}  {'UTC':<20} {'u0':>6}  {'outcome':<9} {'margin':>8}  "
             f"{'ref occ':<7} {'tgt occ':<7} {'glare':>7}  {'pointing':>9}  "
             f"{'propellant':>10}")]
    notes = {}
    for r in rows:
        if r["status"] == "complete":
            outcome = "complete"
        else:
            if r["outcome"] not in notes:
                notes[r["outcome"]] = len(notes) + 1
            outcome = f"A{notes[r['outcome']]}"
        margin = r.get("sunlit_margin_s")
        margin = "-" if margin is None else f"{margin:.0f} s"
        u0 = r.get("arg_latitude_deg")
        pe = r.get("pointing_error_arcsec")
        prop = r.get("propellant_kg")
        glare = r.get("earth_glare_s")
        glare = "-" if glare is None else f"{glare:.0f} s" + ("*" if r.get("glare_took_star")
                                                              else " ")
        lines.append(
            f"  {r['offset_s']:>6.0f}s  {(r.get('date_utc') or '-'):<20} "
            f"{'-' if u0 is None else f'{u0:.1f}':>6}  {outcome:<9} {margin:>8}  "
            f"{'yes' if r.get('reference_occulted') else 'no':<7} "
            f"{'yes' if r.get('target_occulted') else 'no':<7} {glare:>7}  "
            f"{'-' if pe is None else f'{pe:.1f}':>8}\"  "
            f"{'-' if prop is None else f'{prop:.3f} kg':>10}")
    lines += ["", ("  start: ejection after the scenario's date; u0: argument of latitude "
              "at ejection [deg];"), ("  margin: end of the flight to the next orbit sunset; "
              "occ: the Earth hid the reference star / the target in flight"),
              ("  glare: sunlit Earth in the tracker's slit, blinding it; * where it took "
               "the star the loop was closed on")]
    lines += [f"  A{n}  {text}" for text, n in notes.items()]
    done = sum(r["status"] == "complete" for r in rows)
    tail = f" in {wall_s:.0f} s" if wall_s is not None else ""
    lines.append(f"  {done} complete, {len(rows) - done} not{tail}")
    return "\n".join(lines)


def write_figure(result, path) -> None:
    """The window ``result`` as a figure (PNG, SVG or PDF by ``path``'s suffix)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = result["rows"]
    fig, ax = plt.subplots(figsize=(9, 4))
    t = [r["offset_s"] / 60.0 for r in rows]
    margin = [(r.get("sunlit_margin_s") or 0.0) / 60.0 for r in rows]
    colors = ["tab:green" if r["status"] == "complete" else "tab:red" for r in rows]
    ax.bar(t, margin, width=result["every_s"] / 60.0 * 0.8, color=colors)
    top = max([*margin, 1.0])
    for x, r in zip(t, rows):
        if r["status"] != "complete":
            ax.plot([x], [0.04 * top], marker="x", color="tab:red", ms=5)
        if r.get("reference_occulted") or r.get("target_occulted"):
            ax.plot([x], [-0.03 * top], marker="^", color="black", ms=3)
    ax.set_xlabel("ejection after the scenario's date [min]")
    ax.set_ylabel("sunlit margin at the end [min]")
    ax.set_title("When to eject: bars complete, x aborted; ^ reference star or target occulted")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def run_from_cli(cfg, args) -> int:
    """``allsky window``: fly the candidates, print the table, write JSON and figure.

    ``cfg`` is the scenario the command line loaded, ``args`` the parsed command line.
    """
    from tqdm import tqdm

    from allsky.apps.output import Interrupted, cap_workers, write_atomic
    from allsky.config.scenario import scenario_from_dict
    from allsky.studies.window import ejection_window, period_s

    if args.orbit:
        data = cfg.as_dict()
        data["orbit"] = {**data["orbit"], **parse_orbit(args.orbit)}
        cfg = scenario_from_dict(data)
    if cfg.orbit.kind == "none":
        raise ConfigError("orbit.kind", "none", "allsky window needs an orbit: give --orbit "
                          "ALT_KM,INC_DEG or a scenario in orbit (shuttle-free-flyer)")
    if not args.every > 0:
        raise ConfigError("--every", args.every, "must be > 0 [s]")
    total = max(1, int(-(-period_s(cfg) // args.every)))
    workers, note = cap_workers(args.workers, total)
    if note:
        print(f"allsky: {note}", file=sys.stderr)
    bar = tqdm(total=total, desc="ejection window", unit="mission", file=sys.stderr,
               disable=True if args.quiet else None)
    t0 = time.perf_counter()
    try:
        result = ejection_window(cfg, args.every, workers,
                                 on_progress=lambda done, n: bar.update(done - bar.n))
    finally:
        bar.close()
    wall_s = time.perf_counter() - t0
    body = json.dumps({**result, "wall_s": wall_s, "workers": workers}, indent=2) + "\n"
    if args.json == "-":
        sys.stdout.write(body)
    else:
        print(format_window(result, wall_s))
        if args.json:
            write_atomic(args.json, body, option="--json")
            print(f"wrote {args.json}")
    if args.figure:
        write_figure(result, args.figure)
        if args.json != "-":
            print(f"wrote {args.figure}")
    if result.get("interrupted"):
        raise Interrupted(f"after {len(result['rows'])} of {total} ejection times")
    return 0
