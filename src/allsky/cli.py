"""The ``allsky`` command line: parse, call one library function, present.

Exit codes: 0 success; 1 a mission that ended aborted; 2 usage or
configuration error (a one-line message, never a traceback).
"""

import argparse
import sys

from allsky import __version__
from allsky.config import ConfigError, load_scenario


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="allsky",
        description="Emulator of the 1970s all-sky pointing attitude control system "
                    "(US patent 4,012,018).")
    p.add_argument("--version", action="version", version=f"allsky {__version__}")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")

    def scenario_args(sp, required=False):
        if required:
            sp.add_argument("scenario", metavar="FILE", help="scenario TOML file")
        else:
            sp.add_argument("scenario", nargs="?", metavar="SCENARIO",
                            help="scenario TOML file (default: the packaged default mission)")
        sp.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        dest="overrides", help="override a key (dotted path, TOML value)")

    run = sub.add_parser("run", help="fly Modes 1 to 6-2 and print the report")
    scenario_args(run)
    run.add_argument("--json", metavar="PATH", help="write the mission summary as JSON")
    run.add_argument("--telemetry", metavar="PATH", help="write the telemetry as CSV")

    cfg = sub.add_parser("config", help="show or check a scenario")
    csub = cfg.add_subparsers(dest="config_command", required=True, metavar="ACTION")
    show = csub.add_parser("show", help="print the fully resolved configuration (TOML)")
    scenario_args(show)
    check = csub.add_parser("check", help="validate a scenario file")
    scenario_args(check, required=True)
    return p


def main(argv=None) -> int:
    """Run the command line; returns the exit code."""
    args = _parser().parse_args(argv)
    try:
        cfg = load_scenario(args.scenario, args.overrides)
        if args.command == "config":
            if args.config_command == "show":
                print(cfg.to_toml(), end="")
            else:
                print(f"ok: {args.scenario}")
            return 0
        from allsky.report import run_from_cli

        return run_from_cli(cfg, args)
    except ConfigError as e:
        print(f"allsky: error: {e}", file=sys.stderr)
        return 2
    except OSError as e:  # an output path that cannot be written
        print(f"allsky: error: {e}", file=sys.stderr)
        return 2
