"""``allsky stars``: the catalog and what the tracker's magnitude window passes.

The list comes from :func:`allsky.vehicle.sky.catalog`; this module prints it.
"""

import json
import sys


def format_stars(stars, window, date_utc) -> str:
    """The catalog as a table: magnitude, RA [h], Dec [deg], window, reference star.

    ``stars`` are :func:`allsky.vehicle.sky.catalog`'s entries, ``window`` the
    tracker's (brightest, faintest) magnitudes and ``date_utc`` the UTC
    date-time of the positions.
    """
    lo, hi = window
    inside = sum(1 for s in stars if s["in_window"])
    when = date_utc.isoformat().replace("+00:00", "Z")
    lines = [(f"Star tracker magnitude window {lo:+.2f} .. {hi:+.2f}: {inside} "
              f"star{'s' if inside != 1 else ''} inside (positions J2000 at {when})"), "",
             f"  {'star':<16}{'mag':>7}{'RA [h]':>9}{'Dec [deg]':>11}  window"]
    for s in stars:
        mark = ("reference (planned)" if s["reference"]
                else "in" if s["in_window"] else "")
        lines.append(f"  {s['name']:<16}{s['magnitude']:>+7.2f}{s['ra_deg'] / 15.0:>9.3f}"
                     f"{s['dec_deg']:>+11.2f}  {mark}".rstrip())
    return "\n".join(lines)


def run_from_cli(cfg, args) -> int:
    """``allsky stars [--window] [--date UTC] [--json PATH]``.

    ``cfg`` is the scenario the command line loaded (``--scenario``, ``--set``)
    and ``args`` the parsed command line (:mod:`allsky.apps.cli`); returns the
    exit status.
    """
    from allsky.apps.output import check_output, write_atomic
    from allsky.config import ConfigError, load_scenario
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
    if args.window:
        stars = [s for s in stars if s["in_window"]]
    if args.json:
        body = json.dumps({"date_utc": date.isoformat().replace("+00:00", "Z"),
                           "magnitude_window": list(window), "stars": stars}, indent=2) + "\n"
        if args.json == "-":
            sys.stdout.write(body)
            return 0
        write_atomic(args.json, body, option="--json")
    print(format_stars(stars, window, date))
    if args.json:
        print(f"wrote {args.json}")
    return 0
