"""``allsky stars``: the catalog, the moving bodies and what the window passes.

The stars come from :func:`allsky.vehicle.sky.catalog`, the Moon and the
planets from :mod:`allsky.vehicle.bodies`; this module prints them.
"""

import json
import sys


def format_stars(stars, window, date_utc, moving=(), seen=False) -> str:
    """The catalog as a table: magnitude, RA [h], Dec [deg], phase, window mark.

    ``stars`` are :func:`allsky.vehicle.sky.catalog`'s entries, ``window`` the
    tracker's (brightest, faintest) magnitudes and ``date_utc`` the UTC
    date-time of the positions; ``moving`` are the moving bodies' rows
    (:func:`moving_rows`), listed among the stars by magnitude with their
    phases, and ``seen`` whether the scenario's tracker sees them
    (``star_tracker.moving_bodies``).
    """
    lo, hi = window
    rows = sorted([*stars, *moving], key=lambda r: (r["magnitude"], r["name"]))
    inside = sum(1 for s in stars if s["in_window"])
    bodies_in = sum(1 for b in moving if b["in_window"])
    when = date_utc.isoformat().replace("+00:00", "Z")
    lines = [(f"Star tracker magnitude window {lo:+.2f} .. {hi:+.2f}: {inside} "
              f"star{'s' if inside != 1 else ''} inside (positions J2000 at {when})")]
    if moving:
        lines.append(f"Moving bodies inside: {bodies_in} ("
                     + ("the tracker sees them)" if seen else
                        "not flown: see star_tracker.moving_bodies)"))
    lines += ["",
             f"  {'star':<16}{'mag':>7}{'RA [h]':>9}{'Dec [deg]':>11}{'phase':>7}  window"]
    for s in rows:
        body = "phase" in s
        mark = ""
        if s.get("reference"):
            mark = "reference (planned)"
        elif s["in_window"]:
            mark = "in (not flown)" if body and not seen else "in"
        phase = f"{s['phase']:>7.2f}" if body else " " * 7
        lines.append(f"  {s['name']:<16}{s['magnitude']:>+7.2f}{s['ra_deg'] / 15.0:>9.3f}"
                     f"{s['dec_deg']:>+11.2f}{phase}  {mark}".rstrip())
    return "\n".join(lines)


def moving_rows(date_utc, window) -> list[dict]:
    """The moving bodies at ``date_utc`` as rows of the table and of ``--json``.

    ``name``, ``magnitude``, ``ra_deg``, ``dec_deg``, ``phase`` (the lit
    fraction of the disk), ``elongation_deg`` (from the Sun), ``distance_au``
    and ``in_window`` (inside the tracker's magnitude ``window``).
    """
    from allsky.vehicle import bodies

    lo, hi = window
    return [{"name": b.name, "magnitude": float(b.magnitude), "ra_deg": float(b.ra_deg),
             "dec_deg": float(b.dec_deg), "phase": float(b.phase),
             "elongation_deg": float(b.elongation_deg), "distance_au": float(b.distance_au),
             "in_window": bool(lo <= b.magnitude <= hi)} for b in bodies.bodies(date_utc)]


def run_from_cli(cfg, args) -> int:
    """``allsky stars [--window] [--date UTC] [--json PATH]``.

    ``cfg`` is the scenario the command line loaded (``--scenario``, ``--set``)
    and ``args`` the parsed command line (:mod:`allsky.apps.cli`); returns the
    exit status.
    """
    from allsky.apps.output import check_output, write_atomic
    from allsky.config import ConfigError, load_scenario
    from allsky.sim import sky_rows
    from allsky.vehicle import sky

    check_output("--json", args.json)
    if args.date:
        try:  # the date goes through the scenario's own rules (format, ephemeris years)
            cfg = load_scenario(args.scenario, [*args.overrides,
                                                f"mission.date_utc={args.date}"])
        except ConfigError as e:
            raise ConfigError(None, rule=f"--date {args.date}: {e}") from None
    window = tuple(cfg.star_tracker.magnitude_window)
    date = cfg.mission.date_utc
    stars = sky.catalog(date, window, cfg.star_tracker.reference_star)
    moving = moving_rows(date, window)
    seen = sky_rows.bodies_flown(cfg)
    if args.window:
        stars = [s for s in stars if s["in_window"]]
        moving = [b for b in moving if b["in_window"]]
    if args.json:
        body = json.dumps({"date_utc": date.isoformat().replace("+00:00", "Z"),
                           "magnitude_window": list(window), "stars": stars,
                           "moving_bodies": moving, "moving_bodies_seen": seen},
                          indent=2) + "\n"
        if args.json == "-":
            sys.stdout.write(body)
            return 0
        write_atomic(args.json, body, option="--json")
    print(format_stars(stars, window, date, moving, seen))
    if args.json:
        print(f"wrote {args.json}")
    return 0
