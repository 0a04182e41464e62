"""The ``allsky`` command line: parse, call one library function, present.

Commands::

    allsky run [SCENARIO] [--set KEY=VALUE ...] [--json PATH] [--telemetry PATH] [--plots DIR]
               [--html PATH] [--commands FILE] [--strict]
    allsky serve [SCENARIO] [--set KEY=VALUE ...] [--host HOST] [--port PORT] [--speed X]
                 [--no-browser] [--save-commands FILE] [--allow-remote] [--pause-when-alone]
                 [--json PATH] [--telemetry PATH] [--html PATH]
    allsky plot TELEMETRY [--out DIR] [--summary SUMMARY.json]
    allsky replay TELEMETRY [--summary JSON] --html PATH [--scenario SCENARIO] [--set KEY=VALUE]
    allsky analyze [SCENARIO] [--set KEY=VALUE ...] [--json PATH] [--plot PNG]
                   [--envelope [--wheel-torque N_M] [--wheel-momentum N_M_S] [--wheel-beta DEG]]
    allsky faults [SCENARIO] [--kinds KIND,...] [--modes MODE,...] [--json PATH] [--workers N]
    allsky scenarios [NAME] [--json PATH]
    allsky config show [SCENARIO] [--set KEY=VALUE ...]
    allsky config check FILE [--set KEY=VALUE ...]
    allsky warm-up
    allsky montecarlo [SCENARIO] --runs N [--disperse SPEC] [--workers N | --scheduler ADDRESS]
                      [--batch N] [--out DIR] [--resume] [--set KEY=VALUE ...] [--json PATH]
                      [--quiet]

Exit codes (:data:`EXIT_CODES`): 0 success; 1 a mission that ended aborted (with
``run --strict``, or whose summary has a warning);
2 a usage, input or output error, or a lost Dask cluster, reported as one
line ``allsky: error: ...`` on stderr; 3 an internal error, reported as one
line with a crash report file holding the traceback; 130 interrupted
(Ctrl-C, SIGTERM or SIGHUP), after writing what the finished work promised, in one
line ``allsky: interrupted; ...``; 141 stdout's reader went away (``| head``) after
every file asked for was written. Never a bare traceback.
"""

import _thread
import argparse
import errno
import os
import signal
import sys
import tempfile
import time
import traceback

from allsky import __version__
from allsky.apps.output import ENDING_SIGNALS

# Nothing else of allsky is imported here: `allsky --help` parses and prints without numpy,
# numba or matplotlib, and each command imports its own module when it runs (_run). The
# signals that end a command as Ctrl-C does (EXIT_INTERRUPTED) are output's.

#: The exit codes of every command.
EXIT_CODES = {
    0: "success",
    1: "a mission ended aborted (with run --strict: or with any warning)",
    2: "usage, input or output error (one line 'allsky: error: ...'), or the Dask cluster lost",
    3: "internal error (one line, the traceback in a crash report file), or a case of "
       "allsky faults that raised (the matrix still written)",
    130: "interrupted by Ctrl-C, SIGTERM or SIGHUP (a closed terminal): what finished is "
         "written, partial files removed; one line says what",
    141: "stdout's reader went away (allsky ... | head): every file asked for was still "
         "written (a closed or full stdout: exit 2 and one line)",
}
EXIT_ABORTED, EXIT_USAGE, EXIT_INTERNAL, EXIT_INTERRUPTED = 1, 2, 3, 130
#: 128 + SIGPIPE, what a shell reports for a writer whose pipe closed.
EXIT_STDOUT_GONE = 141
#: The options that mean the same on every command that has them.
COMMON_FLAGS = {
    "--json PATH": "write the result as JSON; '-' writes it to stdout and nothing else goes "
                   "there",
    "--quiet": "no progress line (progress goes to stderr, and only when it is a terminal)",
    "--workers N": "worker processes, at most one per run and per core (a larger request is "
                   "lowered, with a note on stderr)",
    "--set KEY=VALUE": "override a scenario key (dotted path, TOML value); repeatable",
    "--version": "print the version, before or after the command",
}


def exit_codes_text() -> str:
    """The exit codes and the common flags, as the help's epilog shows them."""
    lines = ["exit codes:"] + [f"  {k:<4} {v}" for k, v in EXIT_CODES.items()]
    lines += ["", "flags common to the commands:"]
    lines += [f"  {k:<16} {v}" for k, v in COMMON_FLAGS.items()]
    return "\n".join(lines)


class _Parser(argparse.ArgumentParser):
    """argparse with errors as one line ``allsky: error: ...`` and exit code 2."""

    def error(self, message):
        where = "" if self.prog == "allsky" else f"{self.prog}: "  # once "allsky: error:"
        self.exit(EXIT_USAGE, f"allsky: error: {where}{message}; usage: {self.prog} "
                              "--help\n")


def _parser() -> argparse.ArgumentParser:
    p = _Parser(
        prog="allsky", formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Emulator of the 1970s all-sky pointing attitude control system "
                    "(US patent 4,012,018).",
        epilog=exit_codes_text() + "\n\n"
               "examples:\n"
               "  allsky run                     # fly the default mission, print the report\n"
               "  allsky step                    # the same, stopping at each mode boundary\n"
               "  allsky COMMAND --help          # each command's options and examples")
    p.add_argument("--version", action="version", version=f"allsky {__version__}")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")

    def scenario_args(sp, required=False):
        if required:
            sp.add_argument("scenario", metavar="FILE", help="scenario TOML file")
        else:
            sp.add_argument("scenario", nargs="?", metavar="SCENARIO", action=_Scenario,
                            help="scenario TOML file, merged over the packaged default "
                                 "(default: the packaged default mission)")
        sp.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        dest="overrides",
                        help="override a key: dotted path, TOML value "
                             "(e.g. gyro.drift_deg_h=[1,0,0], target.star=Vega); repeatable")

    run = sub.add_parser(
        "run", help="fly Modes 1 to 6-2 and print the report",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Fly the whole mission (Modes 1 to 6-2) and print the mode timeline, "
                    "the calibration against the scenario's truth, the target angles, the "
                    "final pointing error and the propellant used.",
        epilog="examples:\n"
               "  allsky run\n"
               "  allsky run my_scenario.toml --json out.json --telemetry tlm.csv\n"
               "  allsky run --set target.star=Vega --set mission.seed=7\n"
               "  allsky run --set calibration.apply=false   # Mode 6 without the calibration\n"
               "  allsky run --json - | jq .target          # machine output on stdout")
    scenario_args(run)
    run.add_argument("--disperse", metavar="SPEC",
                     help="TOML file with a [dispersions] table, merged over the scenario's; "
                          "the values drawn for mission.seed are applied and printed")
    run.add_argument("--json", metavar="PATH",
                     help="write the mission summary as JSON (PATH '-': the JSON alone on "
                          "stdout, no report)")
    run.add_argument("--quiet", action="store_true",
                     help="no progress line (it is also off when stderr is not a terminal)")
    run.add_argument("--telemetry", metavar="PATH",
                     help="write the telemetry, CSV or Parquet by the suffix (.csv, .parquet); "
                          "columns in docs/telemetry.md")
    run.add_argument("--plots", metavar="DIR",
                     help="write the mission figures (PNG) into DIR, as allsky plot does")
    run.add_argument("--html", metavar="PATH",
                     help="write the mission replay: one self-contained HTML page, offline "
                          "(docs/replay.md)")
    run.add_argument("--strict", action="store_true",
                     help="exit 1 when the summary has any warning (a mission the sequencer "
                          "judged complete included), with the first on stderr; for scripts")
    _ground_control(sub, scenario_args, run)

    step = sub.add_parser(
        "step", help="fly the mission stop by stop, showing the hardware at each stop",
        formatter_class=_ModeListFormatter,
        description="Fly the mission and stop at each mode boundary (and, with --every, "
                    "inside modes). Each stop shows the switch bank, counters, drift "
                    "counters and DACs, storage registers, sensor outputs, body rates, "
                    "word registers 23/24 and propellant. Enter goes on; q stops (the "
                    "report and telemetry so far are still written).",
        epilog="examples:\n"
               "  allsky step                          # the default mission, Enter at each stop\n"
               "  allsky step --every 60 --until 3     # stop every 60 s, end after Mode 3\n"
               "  allsky step --no-pause --save-dir states/ > tour.txt\n"
               "  allsky step --from states/after_mode_3.npz")
    scenario_args(step)
    step.add_argument("--from", dest="from_state", metavar="STATE",
                      help="resume a mission saved at a mode boundary (.npz from --save-dir)")
    step.add_argument("--every", type=_positive_float, metavar="SECONDS",
                      help="also stop every SECONDS of mission time inside modes (at least "
                           "0.1 s and 10 frames)")
    step.add_argument("--until", metavar="MODE",
                      help="show no stop before MODE ({modes}; inside it only the --every "
                           "stops) and end the session at its end")
    step.add_argument("--plan", choices=("legacy", "dither"), default="legacy",
                      help="legacy: the patent's Modes 1-6; dither: the comparison "
                           "method in place of Modes 4 and 5")
    step.add_argument("--no-pause", action="store_true",
                      help="print the stops without waiting (implied when stdin is not "
                           "a terminal)")
    step.add_argument("--save-dir", metavar="DIR",
                      help="save the mission state at every mode boundary "
                           "(after_mode_<MODE>.npz)")
    step.add_argument("--json", metavar="PATH",
                      help="write the stops and the mission summary as JSON ('-': to stdout; "
                           "the stops are then shown on stderr)")
    step.add_argument("--telemetry", metavar="PATH",
                      help="write the telemetry so far (.csv or .parquet)")

    cmp_ = sub.add_parser(
        "compare", help="fly the legacy calibration (Modes 4-5) and the dither method on "
                        "identical vehicles; compare",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Fly the patent's 360-degree calibration turns and the dither method "
                    "on vehicles with the same gyro errors and noise; compare accuracy "
                    "(measured and predicted spread), time, largest excursion, propellant "
                    "and final pointing.",
        epilog="examples:\n"
               "  allsky compare\n"
               "  allsky compare --runs 200 --json cmp.json --plot cmp.png\n"
               "  allsky compare --set dither.detector=\"lsq\" --runs 50\n"
               "  allsky compare --sweep amplitude_urad=100,1000,10000 --sweep record_s=204.8,819.2"
               " --runs 20\n"
               "  allsky compare --vehicle wheels --runs 20\n"
               "  allsky compare --methods legacy,dither,kalman --runs 200")
    scenario_args(cmp_)
    cmp_.add_argument("--runs", type=_runs, default=1, metavar="N",
                      help="repeat over N seeds (from mission.seed on) and give statistics "
                           "(at most 10^7)")
    cmp_.add_argument("--workers", type=_positive_int, metavar="N",
                      help="worker processes for --runs (default: one per core; at most "
                           "one per run and per core)")
    cmp_.add_argument("--json", metavar="PATH",
                      help="write the comparison as JSON ('-': to stdout, instead of the table)")
    cmp_.add_argument("--plot", metavar="PNG",
                      help="write scale-factor error against calibration time (PNG; with "
                           "--sweep, the trade study's figure)")
    cmp_.add_argument("--sweep", action="append", type=_sweep_axis, metavar="NAME=V1,V2,...",
                      help="trade study of the dither instead of the comparison: NAME is "
                           "amplitude_urad (on each dithered axis) or record_s; give one or "
                           "both; --runs seeds per point, the legacy turns as reference "
                           "(docs/comparison.md)")
    cmp_.add_argument("--vehicle", choices=("jets", "wheels"),
                      help="fly both methods on the jets (PWPF modulators, jets 39-41) or on "
                           "the reaction wheels unloaded by the jets (default: the scenario's "
                           "actuators.kind, jets unless set)")
    cmp_.add_argument("--methods", type=_methods, metavar="M1,M2,...",
                      help="methods to compare: legacy,dither (default), adding kalman (the "
                           "three-axis Kalman filter through the legacy turns and through the "
                           "dither hold, docs/kalman.md) and/or smoother (the fixed-interval "
                           "smoother over Modes 3-5, docs/comparison.md); not with --sweep")

    replay = sub.add_parser(
        "replay", help="write the replay page (HTML) of a flown mission from its telemetry file",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Write one self-contained HTML page that plays a flown mission in any "
                    "browser, offline: the block diagram with its switches and live values, "
                    "the vehicle in 3-D, the sky map with the tracker's slit, the traces and "
                    "the event log, on one mission clock (docs/replay.md). The scenario "
                    "(SCENARIO, --set) gives the date, the stars and the tracker's slit; "
                    "--summary gives the mode exits, registers 23 and 24 and the target.",
        epilog="examples:\n"
               "  allsky run --telemetry tlm.parquet --json summary.json\n"
               "  allsky replay tlm.parquet --summary summary.json --html mission.html\n"
               "  allsky run --html mission.html       # the same in one step")
    replay.add_argument("telemetry", metavar="TELEMETRY",
                        help="telemetry file written by allsky run --telemetry (.csv or "
                             ".parquet)")
    replay.add_argument("--summary", metavar="JSON",
                        help="mission summary (allsky run --json): mode exits, registers 23 "
                             "and 24, the target and the star locked")
    replay.add_argument("--html", metavar="PATH", required=True,
                        help="the page to write (.html)")
    replay.add_argument("--scenario", metavar="SCENARIO", dest="scenario",
                        help="the scenario flown, merged over the packaged default "
                             "(default: the packaged default mission)")
    replay.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        dest="overrides",
                        help="override a key of the scenario flown (dotted path, TOML "
                             "value); repeatable")

    plot = sub.add_parser(
        "plot", help="draw the figures of a flown mission from its telemetry file",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Write PNG figures from a telemetry file (allsky run --telemetry): "
                    "attitude errors with the modes shaded, the switch timing diagram "
                    "S1-S19, the counters, the jet valves and propellant, and, with "
                    "--summary, the stored calibration against the truth.",
        epilog="examples:\n"
               "  allsky run --telemetry tlm.parquet --json summary.json\n"
               "  allsky plot tlm.parquet --summary summary.json --out figures/\n"
               "  allsky plot tlm.csv                  # figures into the current directory")
    plot.add_argument("telemetry", metavar="TELEMETRY",
                      help="telemetry file written by allsky run --telemetry (.csv or .parquet)")
    plot.add_argument("--out", metavar="DIR", default=".",
                      help="directory for the PNG files (created if needed; default: .)")
    plot.add_argument("--summary", metavar="SUMMARY.json",
                      help="mission summary (allsky run --json) for the calibration figure")

    analyze = sub.add_parser(
        "analyze", help="loop margins per axis and the PWPF modulator's static characteristic; "
                        "wheel and jet envelopes",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Linear gain and phase margins of each axis's position and rate loops, "
                    "and the PWPF modulators' duty cycle against a constant input: the "
                    "analytic curve beside the simulated modulator.\n\n"
                    "With --envelope instead: the torque and momentum envelopes of the "
                    "scenario's reaction-wheel array ([wheels]: any number of wheels, axes "
                    "and per-wheel limits), with its worst single failure, beside the torque "
                    "box of the scenario's jets 39-41, and the dither document's example "
                    "(its own 16000 kg m^2 vehicle, not the emulated one; 100 urad, 51.2 s) "
                    "checked in each (docs/envelopes.md). The --wheel-* options replace "
                    "parts of the array.",
        epilog="examples:\n"
               "  allsky analyze\n"
               "  allsky analyze --set pwpf.time_constant_s=0.05 --plot loops.png\n"
               "  allsky analyze my_scenario.toml --json analysis.json\n"
               "  allsky analyze --envelope --plot envelope.png\n"
               "  allsky analyze --envelope --wheel-torque 0.05 --wheel-beta 60 --json -\n"
               "  allsky analyze --envelope --set 'wheels.max_torque_n_m=[0.2, 0.2, 0.1, 0.1]'")
    scenario_args(analyze)
    analyze.add_argument("--json", metavar="PATH",
                         help="write the margins and the PWPF characteristic (with --envelope: "
                              "the envelopes and the dither check) as JSON ('-': to stdout, "
                              "instead of the tables)")
    analyze.add_argument("--plot", metavar="PNG",
                         help="write Bode plots with the margins and the static curve (with "
                              "--envelope: the torque envelopes in 3-D) (PNG)")
    analyze.add_argument("--envelope", action="store_true",
                         help="show the wheel and jet torque/momentum envelopes instead")
    analyze.add_argument("--wheel-torque", type=_positive_float, metavar="N_M",
                         help="with --envelope: torque limit of each wheel [N m], instead of "
                              "the scenario's wheels.max_torque_n_m")
    analyze.add_argument("--wheel-momentum", type=_positive_float, metavar="N_M_S",
                         help="with --envelope: momentum limit of each wheel [N m s], instead "
                              "of the scenario's wheels.max_momentum_n_m_s")
    analyze.add_argument("--wheel-beta", type=_pyramid_angle, metavar="DEG",
                         help="with --envelope: a four-wheel pyramid about +x (roll), each "
                              "spin axis at this angle from +x [deg], instead of the "
                              "scenario's wheels.axes (whose limits carry over when one "
                              "number or four; atan(sqrt 2) = 54.74 puts all twelve facets "
                              "equally far)")

    mc = sub.add_parser(
        "montecarlo", help="fly a campaign over seeds and dispersions; statistics and histograms",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Fly N missions. Run i uses mission.seed = base + i (base: the scenario's\n"
                    "seed) and the scenario's [dispersions] drawn for that seed, so any run is\n"
                    "reproduced alone by 'allsky run --set mission.seed=S'. Runs go to local\n"
                    "worker processes or to a Dask cluster; with --out each finished run is\n"
                    "saved at once, and --resume continues an interrupted campaign.\n"
                    "Dispersion syntax and seeding: docs/montecarlo.md.",
        epilog="examples:\n"
               "  allsky montecarlo --runs 1000 --out mc/                 # all cores\n"
               "  allsky montecarlo --runs 1000 --out mc/ --resume        # after a Ctrl-C\n"
               "  allsky montecarlo my.toml --disperse gyro_errors.toml --runs 200 --workers 1\n"
               "  allsky montecarlo --runs 5000 --scheduler tcp://10.0.0.5:8786 --out mc/\n"
               "  allsky montecarlo --runs 100 --set target.star=Vega --json - --quiet")
    scenario_args(mc)
    mc.add_argument("--runs", type=_runs, metavar="N",
                    help="number of runs, at most 10^7 (needed for a new campaign; with "
                         "--resume, a larger N extends it)")
    mc.add_argument("--disperse", metavar="SPEC",
                    help="TOML file with a [dispersions] table, merged over the scenario's")
    where = mc.add_mutually_exclusive_group()
    where.add_argument("--workers", type=_positive_int, metavar="N",
                       help="local worker processes (default: one per core; 1: in this process)")
    where.add_argument("--scheduler", metavar="ADDRESS",
                       help="fly on an existing Dask distributed cluster (tcp://HOST:PORT)")
    mc.add_argument("--batch", type=_positive_int, metavar="N",
                    help="with --scheduler: runs per Dask task (default: chosen from the task "
                         "overhead and the mission time measured, docs/montecarlo.md)")
    mc.add_argument("--out", metavar="DIR",
                    help="campaign directory: campaign.json, runs.csv (one row per run, saved "
                         "as it finishes), summary.txt/.json, histograms.png")
    mc.add_argument("--resume", action="store_true",
                    help="continue the campaign in --out DIR (the same scenario and dispersions)")
    mc.add_argument("--json", metavar="PATH",
                    help="write the summary as JSON ('-': to stdout, instead of the table)")
    mc.add_argument("--quiet", action="store_true", help="no progress bar")

    cfg = sub.add_parser("config", help="show or check a scenario")
    cfg.add_argument("--version", action="version", version=f"allsky {__version__}")
    csub = cfg.add_subparsers(dest="config_command", required=True, metavar="ACTION")
    show = csub.add_parser(
        "show", help="print the fully resolved configuration as TOML",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n"
               "  allsky config show > my_scenario.toml   # a complete file to edit\n"
               "  allsky config show --set mission.seed=3")
    scenario_args(show)
    check = csub.add_parser(
        "check", help="validate a scenario file",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n"
               "  allsky config check my_scenario.toml     # 'ok: ...' or one error line, exit 2")
    scenario_args(check)

    stars = sub.add_parser(
        "stars", help="the star catalog and the moving bodies, and what the tracker's "
                      "magnitude window passes",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="List the catalog stars, the Moon and the planets Mercury to Saturn with "
                    "their magnitudes and J2000 positions on the mission date (the bodies "
                    "with their phases), marking those inside star_tracker.magnitude_window "
                    "and the planned reference star (star_tracker.reference_star); the "
                    "tracker locks the first star of the window its slit meets, a body too "
                    "where star_tracker.moving_bodies flies them.",
        epilog="examples:\n"
               "  allsky stars\n"
               "  allsky stars --window                       # only the stars in the window\n"
               "  allsky stars --date 2030-06-01T00:00:00Z --json -")
    scenario_args(stars)
    stars.add_argument("--window", action="store_true",
                       help="list only the stars and bodies inside the tracker's magnitude "
                            "window")
    stars.add_argument("--date", metavar="UTC",
                       help="the date (TOML datetime, e.g. 2026-03-20T12:00:00Z; default: "
                            "mission.date_utc)")
    stars.add_argument("--json", metavar="PATH",
                       help="write the list as JSON ('-': to stdout, instead of the table)")

    faults = sub.add_parser(
        "faults", help="fly every fault kind starting in every mode; the matrix of outcomes",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Fly the mission once without a fault and once per fault kind and "
                    "mode, the fault starting at the start of that mode, on all cores. "
                    "Print the matrix: the final pointing error of each complete mission, "
                    "or the reason it aborted (mode, symptom, fault). Faults and their "
                    "fields: docs/faults.md.",
        epilog="examples:\n"
               "  allsky faults\n"
               "  allsky faults --kinds gyro_dead,tracker_dropout --modes 4,5\n"
               "  allsky faults mariner4-star-hopping --kinds gyro_dead --modes 6-2\n"
               "  allsky faults --set sequencer.recovery=true --json matrix.json")
    scenario_args(faults)
    # Checked by the command against allsky.config.faults (a bad name exits 2 and lists the
    # known ones), so that parsing imports no more of allsky than --help needs.
    # Comma lists, as --methods and --sweep take; several words still work (--kinds a b), and a
    # scenario given after the list is recognised as one, not taken for a name.
    faults.add_argument("--kinds", nargs="+", action=_NameList, metavar="KIND,...",
                        help="fault kinds, comma-separated (rows; default: all, as in "
                             "docs/faults.md)")
    faults.add_argument("--modes", nargs="+", action=_NameList, metavar="MODE,...",
                        help="modes the fault starts in, comma-separated (columns; default: "
                             "1,2,3,4,5,6-1,6-2; only modes the mission flies)")
    faults.add_argument("--workers", type=_positive_int, metavar="N",
                        help="worker processes (default: one per core)")
    faults.add_argument("--json", metavar="PATH",
                        help="write the matrix as JSON ('-': to stdout, instead of the table)")

    win = sub.add_parser(
        "window", help="when to eject: the mission from each ejection time over one orbit",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Fly the mission from each candidate ejection time, every --every "
                    "seconds over one orbital period, on all cores: the date and the "
                    "vehicle's place in its orbit move on together. Print a table: the "
                    "start, the outcome (complete, or the abort's reason), the sunlit "
                    "margin at the end (to the next orbit sunset), whether the Earth hid the "
                    "reference star or the target in flight, the pointing error and the "
                    "propellant (docs/orbit.md).",
        epilog="examples:\n"
               "  allsky window shuttle-free-flyer\n"
               "  allsky window --orbit 300,28.5 --every 120 --json window.json\n"
               "  allsky window shuttle-free-flyer --figure window.png")
    scenario_args(win)
    win.add_argument("--orbit", metavar="ALT_KM,INC_DEG[,RAAN_DEG[,U_DEG]]",
                     help="fly this circular orbit (altitude, inclination, node, argument of "
                          "latitude at the scenario's date) in place of the scenario's")
    win.add_argument("--every", type=float, default=60.0, metavar="S",
                     help="seconds between candidate ejection times (default 60)")
    win.add_argument("--workers", type=_positive_int, metavar="N",
                     help="worker processes (default: one per core)")
    win.add_argument("--json", metavar="PATH",
                     help="write the rows as JSON ('-': to stdout, instead of the table)")
    win.add_argument("--figure", metavar="PATH",
                     help="write the figure (PNG, SVG or PDF by the suffix)")

    scen = sub.add_parser(
        "scenarios", help="list the packaged scenarios (allsky run NAME flies one)",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="The scenarios packaged with allsky, among them the historical "
                    "anomalies of docs/faults.md; 'allsky run NAME' flies one, 'allsky "
                    "scenarios NAME' prints its card (what happened, the sources, what the "
                    "scenario flies and what it leaves out).",
        epilog="examples:\n"
               "  allsky scenarios\n"
               "  allsky scenarios voyager1-wrong-star\n"
               "  allsky run mariner4-star-hopping")
    scen.add_argument("name", nargs="?", metavar="NAME",
                      help="a packaged scenario: print its card instead of the list")
    scen.add_argument("--json", metavar="PATH",
                      help="write the list (with NAME: the card) as JSON ('-': to stdout, "
                           "instead of the table)")
    warm = sub.add_parser(
        "warm-up", help="compile the frame loop once, so that no later command waits for it",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Compile the frame loop, both its forms (the patent's vehicle without "
                    "faults; wheels and faults), into numba's cache (about 25 s, once per "
                    "install and machine; every later command loads it). 'pip install' does "
                    "this already when it builds allsky; this command is for editable "
                    "installs, a cache under NUMBA_CACHE_DIR, or a wheel built on another "
                    "machine. A Dask worker does the same with --preload allsky.apps.warm.",
        epilog="examples:\n"
               "  allsky warm-up                 # after pip install -e, or on a node\n"
               "  allsky warm-up --check         # what is compiled and cached; does it load\n"
               "  dask worker tcp://10.0.0.5:8786 --preload allsky.apps.warm   # the same, "
               "per worker")
    warm.add_argument("--check", action="store_true",
                      help="compile nothing: say what is installed, built ahead of time, "
                           "compiled and cached, and whether each loads (exit 1 if anything "
                           "is damaged; a plain warm-up sets damaged cache files aside and "
                           "rebuilds them)")

    # The same flags on every command (EXIT_CODES and COMMON_FLAGS in the epilog).
    leaves = [sp for name, sp in sub.choices.items() if name != "config"]
    leaves += list(csub.choices.values())
    for sp in leaves:
        sp.add_argument("--version", action="version", version=f"allsky {__version__}")
        if not any("--quiet" in a.option_strings for a in sp._actions):
            sp.add_argument("--quiet", action="store_true",
                            help="no progress line (it is also off when stderr is not a "
                                 "terminal)")
    return p


def _ground_control(sub, scenario_args, run):
    """``allsky serve`` and ``allsky run --commands`` (docs/ground_control.md)."""
    run.add_argument("--commands", metavar="FILE",
                     help="fly a saved session again, exactly: the command log of allsky serve "
                          "--save-commands (its scenario, unless SCENARIO is given; --set "
                          "applies over it)")
    serve = sub.add_parser(
        "serve", help="fly the mission live in the browser and command it (ground control)",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Fly the mission live, paced to the wall clock, and show it in the "
                    "browser as the replay does: the diagram, traces, sky map, 3-D view and "
                    "event log as they happen. From the page (or window.allsky.command) "
                    "pause, resume and change the speed; inject any fault kind and clear it; "
                    "upload a new target; command the sequencer to hold, proceed, reacquire "
                    "or recycle; set the tracker's magnitude window or its bright gate. "
                    "Every command is a journal entry at the frame boundary it acted at. "
                    "Prints one line, 'allsky: serving http://HOST:PORT/?token=TOKEN'; "
                    "ending the session (the page's end button, Ctrl-C) writes what allsky run "
                    "writes, and --save-commands the command log, which 'allsky run --commands "
                    "FILE' flies again exactly (docs/ground_control.md).",
        epilog="examples:\n"
               "  allsky serve                                   # the default mission\n"
               "  allsky serve voyager1-wrong-star --speed 50    # a scenario, faster\n"
               "  allsky serve --save-commands class.toml --json class.json\n"
               "  allsky run --commands class.toml              # the same flight again\n"
               "  allsky serve --host 0.0.0.0 --allow-remote --pause-when-alone  # a classroom")
    scenario_args(serve)
    serve.add_argument("--host", default="127.0.0.1",
                       help="address to listen on (default 127.0.0.1: this machine only; any "
                            "other needs --allow-remote)")
    serve.add_argument("--port", type=int, default=0,
                       help="port to listen on (default 0: any free port)")
    serve.add_argument("--speed", type=_positive_float, default=20.0, metavar="X",
                       help="fly at X times real time (default 20); the page changes it")
    serve.add_argument("--no-browser", action="store_true",
                       help="do not open the page; the printed URL opens it")
    serve.add_argument("--save-commands", metavar="FILE",
                       help="at the end, write the command log (TOML) for allsky run --commands")
    serve.add_argument("--allow-remote", action="store_true",
                       help="allow a --host beyond this machine (anyone who reaches it with the "
                            "link can command the mission; the page says so)")
    serve.add_argument("--pause-when-alone", action="store_true",
                       help="stop the clock while no page watches (default: fly on)")
    serve.add_argument("--json", metavar="PATH", help="at the end, write the summary as JSON")
    serve.add_argument("--telemetry", metavar="PATH",
                       help="at the end, write the telemetry (.csv or .parquet), every row")
    serve.add_argument("--html", metavar="PATH",
                       help="at the end, write the replay page of the session (.html)")


class _ModeListFormatter(argparse.RawDescriptionHelpFormatter):
    """Help whose ``{modes}`` lists the mode table's names, read when help is shown."""

    def _get_help_string(self, action):
        text = action.help or ""
        if "{modes}" in text:  # imported here: parsing alone needs no mode table
            from allsky.sequencer.modes import MODE_TABLE

            text = text.replace("{modes}", " ".join(m.name for m in MODE_TABLE))
        return text


def _looks_like_scenario(word) -> bool:
    """Whether a word after --kinds/--modes names a scenario file or a packaged scenario."""
    from pathlib import Path

    packaged = Path(__file__).resolve().parent.parent / "scenarios" / f"{word}.toml"
    return word.endswith(".toml") or os.sep in word or Path(word).is_file() or (
        packaged.is_file())


class _Scenario(argparse.Action):
    """The optional SCENARIO; one already found among a list option's words is kept."""

    def __call__(self, parser, namespace, values, option_string=None):
        if values is not None or getattr(namespace, self.dest, None) is None:
            setattr(namespace, self.dest, values)


class _NameList(argparse.Action):
    """A list option: comma-separated (``a,b``) or several words (``a b``), extended.

    A scenario (a ``.toml`` file or a packaged scenario's name) among the words
    is the positional SCENARIO, not a name.
    """

    def __call__(self, parser, namespace, values, option_string=None):
        names = list(getattr(namespace, self.dest, None) or [])
        for word in values:
            if _looks_like_scenario(word):
                if getattr(namespace, "scenario", None) not in (None, word):
                    parser.error(f"{option_string}: {word!r} is a scenario, and "
                                 f"{namespace.scenario!r} was given already")
                namespace.scenario = word
                continue
            given = [n.strip() for n in word.split(",") if n.strip()]
            if not given:  # "," or "": nothing named, not "all"
                parser.error(f"{option_string}: {word!r} names nothing; give names separated "
                             "by commas, or leave the option out for all")
            names += given
        setattr(namespace, self.dest, names)


def _positive_float(text):
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not v > 0 or v == float("inf"):
        raise argparse.ArgumentTypeError(f"{v} must be a positive, finite number")
    return v


def _pyramid_angle(text):
    v = _positive_float(text)
    if not v < 90.0:
        raise argparse.ArgumentTypeError(f"{v} must be below 90 deg (90: all wheels in the "
                                         "y-z plane, no roll torque)")
    return v


def _sweep_axis(text):
    from allsky.apps.dither_sweep import sweep_axis

    return sweep_axis(text)


def _methods(text):
    from allsky.studies.compare import METHODS

    names = tuple(n.strip() for n in text.split(","))
    unknown = [n for n in names if n not in METHODS]
    if unknown:
        raise argparse.ArgumentTypeError(f"unknown method {unknown[0]!r} (known: "
                                         f"{', '.join(METHODS)})")
    if not {"legacy", "dither"} <= set(names):
        raise argparse.ArgumentTypeError("legacy and dither are always compared: give "
                                         "legacy,dither or legacy,dither,kalman")
    return names


def _positive_int(text):
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"{v} must be >= 1")
    return v


def _runs(text):
    """A number of runs: 1 to :data:`allsky.config.rules.RUNS_MAX`."""
    from allsky.config.rules import RUNS_MAX

    v = _positive_int(text)
    if v > RUNS_MAX:
        raise argparse.ArgumentTypeError(f"{v} is more than {RUNS_MAX} runs (a campaign keeps "
                                         "each finished run's row in memory, about 3 kB)")
    return v


#: Options of ``allsky compare`` that the trade study (--sweep) has no use for.
SWEEP_IGNORES = ("methods",)


def _run(cfg, args) -> int:
    # Imported here so that `allsky config` never pays for compiling the simulator.
    if args.command == "compare" and args.sweep:
        given = [f"--{k}" for k in SWEEP_IGNORES if getattr(args, k) is not None]
        if given:
            from allsky.config.rules import ConfigError

            raise ConfigError(None, rule=f"{given[0]} does not apply to --sweep (the trade "
                                         "study flies the dither against the legacy turns); "
                                         "drop one of them")
        from allsky.apps.dither_sweep import run_from_cli
    elif args.command == "compare":
        from allsky.apps.compare import run_from_cli
    elif args.command == "step":
        from allsky.apps.step import run_from_cli
    elif args.command == "montecarlo":
        from allsky.apps.campaign import run_from_cli
    elif args.command == "plot":
        from allsky.apps.plots import run_from_cli
    elif args.command == "analyze":
        from allsky.apps.analyze import run_from_cli
    elif args.command == "stars":
        from allsky.apps.stars import run_from_cli
    elif args.command == "replay":
        from allsky.apps.replay import run_from_cli
    elif args.command == "faults":
        from allsky.apps.faults import run_from_cli
    elif args.command == "scenarios":
        from allsky.apps.faults import scenarios_from_cli as run_from_cli
    elif args.command == "window":
        from allsky.apps.window import run_from_cli
    elif args.command == "warm-up":
        from allsky.apps.warm import run_from_cli
    elif args.command == "serve":
        from allsky.apps.serve import run_from_cli
    else:
        from allsky.apps.report import run_from_cli

    return run_from_cli(cfg, args)


def _usage_errors() -> tuple:
    """The exceptions reported as one line ``allsky: error: ...`` with exit code 2.

    Evaluated only when an exception reaches :func:`main`: a telemetry file
    error can come only from the module that defines it, already imported then.
    """
    from allsky.apps.output import OutputError
    from allsky.config.rules import ConfigError

    telemetry_files = sys.modules.get("allsky.apps.telemetry_files")
    found = (telemetry_files.TelemetryError,) if telemetry_files is not None else ()
    return (ConfigError, OutputError, *found)


def _interrupted() -> type:
    from allsky.apps.output import Interrupted

    return Interrupted


def _config(cfg, args) -> int:
    if args.config_command == "show":
        print(cfg.to_toml(annotate=True), end="")
    else:
        from allsky.sim.braking import handover_warning

        what = args.scenario or "the packaged default"
        sets = f" with {len(args.overrides)} --set" if args.overrides else ""
        print(f"ok: {what}{sets}")
        braking = handover_warning(cfg)
        if braking is not None:
            print(f"warning: {braking}")
    return 0


#: Signals the command received (Ctrl-C, SIGTERM), in order; empty while none came.
_signalled = []
#: Whether a command is under way in this process (main is running).
_running = []
#: [s] How soon a signal that arrived during an import is raised again.
IMPORT_RETRY_S = 0.05


def _in_import(frame) -> bool:
    while frame is not None:
        if frame.f_code.co_filename.startswith("<frozen importlib"):
            return True
        frame = frame.f_back
    return False


def _resend(signum):
    time.sleep(IMPORT_RETRY_S)
    if _running:
        os.kill(os.getpid(), signum)


def _deliver_again(signum=None):
    """Send the last signal again shortly (one swallowed, or caught inside an import).

    It runs inside a signal handler, perhaps in the middle of an import, so it
    imports nothing and waits for nothing: Python 3.11's import locks are not
    re-entrant, and an import here (``threading`` itself may be the module half
    imported) would break the import under way (a ``KeyError`` in importlib, or
    a partially initialised module). A bare thread of ``_thread``, a built-in
    module, sleeps and sends the signal.
    """
    signum = signum or (_signalled[-1] if _signalled else signal.SIGINT)
    _thread.start_new_thread(_resend, (signum,))


def _interrupt(signum, frame):
    """Ctrl-C and SIGTERM during a command: KeyboardInterrupt, but never inside an import.

    A compiled extension being imported (numba's) turns a KeyboardInterrupt
    raised under it into an ImportError and prints it; so a signal that
    arrives during an import is sent again a moment later, until the import
    is done, and raised there. Once the command is over (its exit code
    decided, :data:`_running` empty) a signal changes nothing: one sent
    again, or the second of two, that arrives while ``main`` restores the
    handlers is dropped here rather than raised out of ``main``.
    """
    if not _running:
        return
    _signalled.append(signum)
    if _in_import(frame):
        _deliver_again(signum)
        return
    raise KeyboardInterrupt


def crash_report(exc) -> str:
    """Write the traceback of an unexpected exception to a file; return its path.

    ``exc`` is the exception; the file, in the temporary directory, also
    holds the version, the command line and Python's version.
    """
    stamp = time.strftime("%Y%m%d-%H%M%S")
    path = os.path.join(tempfile.gettempdir(), f"allsky-crash-{stamp}-{os.getpid()}.txt")
    text = (f"allsky {__version__}\nargv: {sys.argv}\npython: {sys.version}\n\n"
            + "".join(traceback.format_exception(exc)))
    try:
        with open(path, "w", encoding="utf-8") as f:
            f.write(text)
    except OSError:
        return "(no crash report: the temporary directory cannot be written)"
    return path


#: Every command's files, in one table: per command, (dest, option, role, kind) for each
#: option that names a file. ``role`` is "in" (read) or "out" (written); ``kind`` is "file"
#: or, for a directory output, the names it writes into its directory. The clash check
#: (:func:`check_paths`) is derived from it for every command: no output may name an input
#: or another output.
FILES = {
    "run": (("scenario", "SCENARIO", "in", "file"), ("disperse", "--disperse", "in", "file"),
            ("commands", "--commands", "in", "file"), ("json", "--json", "out", "file"),
            ("telemetry", "--telemetry", "out", "file"), ("plots", "--plots", "out", "plots"),
            ("html", "--html", "out", "file")),
    "serve": (("scenario", "SCENARIO", "in", "file"),
              ("save_commands", "--save-commands", "out", "file"),
              ("json", "--json", "out", "file"), ("telemetry", "--telemetry", "out", "file"),
              ("html", "--html", "out", "file")),
    "step": (("scenario", "SCENARIO", "in", "file"), ("from_state", "--from", "in", "file"),
             ("json", "--json", "out", "file"), ("telemetry", "--telemetry", "out", "file"),
             ("save_dir", "--save-dir", "out", "states")),
    "compare": (("scenario", "SCENARIO", "in", "file"), ("json", "--json", "out", "file"),
                ("plot", "--plot", "out", "file")),
    "replay": (("telemetry", "TELEMETRY", "in", "file"), ("summary", "--summary", "in", "file"),
               ("scenario", "--scenario", "in", "file"), ("html", "--html", "out", "file")),
    "plot": (("telemetry", "TELEMETRY", "in", "file"), ("summary", "--summary", "in", "file"),
             ("out", "--out", "out", "plots")),
    "analyze": (("scenario", "SCENARIO", "in", "file"), ("json", "--json", "out", "file"),
                ("plot", "--plot", "out", "file")),
    "montecarlo": (("scenario", "SCENARIO", "in", "file"),
                   ("disperse", "--disperse", "in", "file"), ("json", "--json", "out", "file"),
                   ("out", "--out", "out", "campaign")),
    "stars": (("scenario", "SCENARIO", "in", "file"), ("json", "--json", "out", "file")),
    "faults": (("scenario", "SCENARIO", "in", "file"), ("json", "--json", "out", "file")),
    "window": (("scenario", "SCENARIO", "in", "file"), ("json", "--json", "out", "file"),
               ("figure", "--figure", "out", "file")),
    "scenarios": (("json", "--json", "out", "file"),),
    "config": (("scenario", "SCENARIO", "in", "file"),),
    "warm-up": (),
}
#: Per command, the options that name files it writes: (dest, option, kind) (from FILES).
OUTPUTS = {c: tuple((d, o, k) for d, o, r, k in rows if r == "out") for c, rows in FILES.items()}
#: Per command, the options that name files it reads: (dest, option) (from FILES).
INPUTS = {c: tuple((d, o) for d, o, r, _ in rows if r == "in") for c, rows in FILES.items()}


def _directory_names(kind) -> tuple:
    """The file names a directory output of ``kind`` writes (imported only when given)."""
    if kind == "plots":
        from allsky.apps.plots import CALIBRATION_FILE, HOLD_FILE, TELEMETRY_FIGURES

        return (*(name for name, _ in TELEMETRY_FIGURES.values()), CALIBRATION_FILE,
                HOLD_FILE)
    if kind == "campaign":
        from allsky.apps.campaign import FILES

        return FILES
    if kind == "states":
        from allsky.sequencer.modes import MODE_TABLE

        return tuple(f"after_mode_{m.name}.npz" for m in MODE_TABLE)
    return None


def check_paths(args):
    """Refuse, before any work, outputs that cannot be written or that are one file.

    Every output option of the command is checked (:func:`allsky.apps.output.check_output`),
    then no two outputs, and no output and input, may be the same file
    (:func:`allsky.apps.output.check_distinct`). ``args`` is the parsed command
    line (its ``command`` and the options :data:`FILES` lists for it).
    """
    from allsky.apps.output import check_distinct, check_output

    outputs = []
    for dest, option, kind in OUTPUTS[args.command]:
        path = getattr(args, dest, None)
        if path is None:
            continue
        check_output(option, path, directory=kind != "file")
        outputs.append((option, path, _directory_names(kind)))
    inputs = [(option, getattr(args, dest, None)) for dest, option in INPUTS[args.command]]
    check_distinct(outputs, [(o, p) for o, p in inputs if p is not None])


#: Commands that fly missions (and so load the compiled loop).
FLYING = ("run", "step", "compare", "montecarlo", "faults", "window", "warm-up")


def build_note_once():
    """Say once, on stderr, what the install did not compile (:func:`aot.build_note`).

    ``pip install`` shows the build's own lines only with ``-v``; the first
    command that flies says it where the user sees it. A marker beside the
    note (or, where the package cannot be written, in the user's cache
    directory) keeps it to once.
    """
    import hashlib

    from allsky import aot

    note = aot.build_note()
    if note is None:
        return
    key = hashlib.sha256(repr(sorted(note.items())).encode()).hexdigest()[:16]
    cache = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"),
                                                              ".cache")
    markers = [aot.NOTE.replace(".json", ".shown"),
               os.path.join(cache, "allsky", f"build-note-{key}.shown")]
    if any(os.path.exists(m) for m in markers):
        return
    effect = note.get("effect") or "commands use numba instead"
    print(f"allsky: note: this install has no {note['missing']} ({note['reason']}): "
          f"{effect}; to build it, {note['hint']}", file=sys.stderr)
    for marker in markers:
        try:
            os.makedirs(os.path.dirname(marker), exist_ok=True)
            with open(marker, "w", encoding="utf-8") as f:
                f.write(key + "\n")
            return
        except OSError:
            continue


def _take_signals() -> bool:
    """Ctrl-C, SIGTERM and SIGHUP raise KeyboardInterrupt from here on; False where not.

    Outside the main thread signals cannot be set, and nothing changes.
    """
    try:
        for sig in ENDING_SIGNALS:
            signal.signal(sig, _interrupt)
    except ValueError:
        return False
    return True


def main(argv=None) -> int:
    """Run the command line on ``argv`` (default ``sys.argv[1:]``); return exit code.

    See :data:`EXIT_CODES`. In the ``allsky`` command (not when called from
    Python), a signal after the command is over changes nothing: the process
    exits with the command's code.
    """
    import allsky
    from allsky.apps.console import guarded

    old = {sig: signal.getsignal(sig) for sig in ENDING_SIGNALS}
    code, took = None, False
    _signalled.clear()
    if "allsky.apps.output" in sys.modules:  # a command before this one in this process
        sys.modules["allsky.apps.output"].forget_written()
    _running.append(True)
    try:
        took = _take_signals()
        with guarded(on_lost_interrupt=_deliver_again) as (out, _):
            code = _main(argv)
            code = _stdout_verdict(code, out)
    except KeyboardInterrupt:  # in the instants around the command itself
        _hold_signals()
        if code is None:
            try:
                os.write(2, (_interrupted_line() + "\n").encode())
            except OSError:
                pass
            code = EXIT_INTERRUPTED
    finally:
        _running.clear()
        if took:
            # In the allsky command the code is decided: a signal from here to the exit
            # changes nothing (ignored; Python's shutdown leaves an ignored signal ignored,
            # where it would give a handled one its default action, death).
            for sig, handler in old.items():
                signal.signal(sig, signal.SIG_IGN if allsky.RUNNING_AS_COMMAND else handler)
    if allsky.RUNNING_AS_COMMAND and code == EXIT_INTERRUPTED:
        _exit_now(code)
    return code


def _exit_now(code):
    """End the allsky command with ``code`` now, everything written and flushed.

    After a Ctrl-C that reached code run by ``PyRun_*`` (as some extension
    modules' imports do), CPython 3.11 keeps a flag that makes the interpreter,
    at its very end, reset SIGINT and kill itself with it: the command would
    die by SIGINT after saying it exited 130. Every file is closed by now and
    the workers are ended; only the console's buffers remain to flush.
    """
    from allsky.apps.output import flush_console

    flush_console()
    os._exit(code)


def _hold_signals():
    """Ignore further ending signals: the command is ending, its line being said."""
    try:
        for sig in ENDING_SIGNALS:
            signal.signal(sig, signal.SIG_IGN)
    except ValueError:  # not the main thread
        pass


def _stdout_verdict(code, out) -> int:
    """The exit code once stdout is known lost or not (:data:`EXIT_STDOUT_GONE`)."""
    if not out.dropped:
        return code
    if out.lost == errno.EPIPE:  # | head: the reader had what it wanted
        return EXIT_STDOUT_GONE if code in (0, EXIT_ABORTED) else code
    from allsky.apps.output import write_reason

    why = ("it is closed" if out.lost == errno.EBADF else
           write_reason(OSError(out.lost, os.strerror(out.lost))))
    files = ("; what was meant for it is lost, every file asked for is written"
             if code in (0, EXIT_ABORTED) else "")
    print(f"allsky: error: stdout: cannot write: {why}{files}", file=sys.stderr)
    return EXIT_USAGE if code in (0, EXIT_ABORTED) else code


def _interrupted_line() -> str:
    from allsky.apps.output import torn_writes, written_files

    torn, done = torn_writes(), written_files()
    whole = f"; written whole: {printable(', '.join(done))}" if done else ""
    if torn:
        return (f"allsky: interrupted; {printable(', '.join(torn))} cut short (written in "
                f"place, not a regular file); every regular file is whole or untouched{whole}")
    return ("allsky: interrupted; nothing half-written (files are written whole or not at "
            f"all){whole or '; nothing written'}")


def _main(argv) -> int:
    try:
        parser = _parser()
        args = parser.parse_args(argv)
        if args.command == "config" and args.config_command == "check" and not (
                args.scenario or args.overrides):
            parser.error("config check: give a scenario FILE, --set KEY=VALUE, or both")
    except SystemExit as e:  # --help, --version, or a usage error (printed as one line)
        return 0 if e.code is None else e.code if isinstance(e.code, int) else EXIT_USAGE
    except KeyboardInterrupt:
        _hold_signals()
        print(_interrupted_line(), file=sys.stderr)
        return EXIT_INTERRUPTED
    try:
        if args.command in FLYING:
            build_note_once()
        check_paths(args)
        # `allsky plot` reads a telemetry file, `allsky scenarios` lists files,
        # `allsky warm-up` compiles: no scenario.
        if args.command in ("plot", "scenarios", "warm-up"):
            cfg = None
        else:
            from allsky.config import load_scenario

            cfg = load_scenario(args.scenario, args.overrides, getattr(args, "disperse", None))
        if args.command == "config":
            return _config(cfg, args)
        return _run(cfg, args)
    except KeyboardInterrupt:
        _hold_signals()
        print(_interrupted_line(), file=sys.stderr)
        return EXIT_INTERRUPTED
    except Exception as e:  # noqa: BLE001 - sorted below; never a traceback
        return _report(e)


def printable(text) -> str:
    """``text`` with its control characters escaped (``\\x1b``): a path or a value in a
    message cannot move the cursor, clear the screen or split the line."""
    return "".join(c if c.isprintable() or c == " " else repr(c)[1:-1] for c in str(text))


def _report(e) -> int:
    """One line for an exception that ended the command; its exit code."""
    try:
        if isinstance(e, _usage_errors()):
            print(f"allsky: error: {printable(e)}", file=sys.stderr)
            return EXIT_USAGE
        if isinstance(e, _interrupted()):
            _hold_signals()
            print(f"allsky: interrupted; {e}", file=sys.stderr)
            return EXIT_INTERRUPTED
        if _signalled:  # what failed after a Ctrl-C or SIGTERM failed because of it
            _hold_signals()
            print(_interrupted_line(), file=sys.stderr)
            return EXIT_INTERRUPTED
        if isinstance(e, OSError):  # a file that the command's own checks did not name
            name = f"{e.filename}: " if e.filename else ""
            print(f"allsky: error: {printable(name)}{(e.strerror or str(e)).lower()}",
                  file=sys.stderr)
            return EXIT_USAGE
        print(f"allsky: internal error: {type(e).__name__}: {printable(e)} (details in "
              f"{crash_report(e)})", file=sys.stderr)
        return EXIT_INTERNAL
    except KeyboardInterrupt:  # a second Ctrl-C while the line was being made
        _hold_signals()
        print(_interrupted_line(), file=sys.stderr)
        return EXIT_INTERRUPTED
