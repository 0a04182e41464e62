"""``allsky analyze``: loop-margin and PWPF tables, the JSON file and the figure.

The numbers come from :func:`allsky.studies.analysis.analyze`; this module
presents them.
"""

import json
import math

import numpy as np

from allsky.studies.analysis import RATE_LOOP_AXES, analyze, frequency_responses, scenario_loops


def format_margins(margins: dict) -> str:
    """Loop margins (:func:`allsky.studies.analysis.loop_margins`) as a text table."""
    head = (f"{'loop':<19}{'GM [dB]':>9}{'PM [deg]':>10}{'w_gc [rad/s]':>14}"
            f"{'w_pc [rad/s]':>14}{'BW [rad/s]':>12}{'coupling':>10}")
    lines = [head, "-" * len(head)]
    for kind, label in (("position", "position"), ("rate", "rate")):
        for axis, m in margins[kind].items():
            name = f"{axis} {label}" if kind == "position" else \
                f"{axis} rate {RATE_LOOP_AXES.get(axis, '')}".rstrip()
            coupling = f"{m['coupling_ratio']:>10.2%}" if "coupling_ratio" in m else f"{'':>10}"
            lines.append(f"{name:<19}{m['gain_margin_db']:>9.2f}{m['phase_margin_deg']:>10.2f}"
                         f"{m['crossover_rad_s']:>14.3f}{m['phase_crossover_rad_s']:>14.3f}"
                         f"{m['bandwidth_rad_s']:>12.3f}{coupling}")
    return "\n".join(lines)


def format_pwpf(result: dict) -> str:
    """The PWPF static characteristic (analysis.pwpf_static_characteristic) as a table."""
    def ms(v):
        return f"{'inf':>9}" if v is None else f"{v * 1e3:>9.2f}"

    head = (f"{'e [mV]':>8}{'T_on [ms]':>11}{'T_off [ms]':>11}{'f [Hz]':>8}"
            f"{'duty':>8}{'sim fine':>10}{'sim frame':>11}")
    title = (f"PWPF modulators 34-36, static characteristic: K {result['filter_gain']:g}, "
             f"tau {result['time_constant_s']:g} s, U_on {result['on_threshold_v'] * 1e3:g} mV, "
             f"U_off {result['off_threshold_v'] * 1e3:g} mV, U_m {result['full_on_v'] * 1e3:g} mV")
    limits = (f"dead zone below {result['dead_zone_v'] * 1e3:.3f} mV, "
              f"saturation above {result['saturation_v'] * 1e3:.3f} mV")
    lines = [title, limits, head, "-" * len(head)]
    for i, e in enumerate(result["input_v"]):
        t_on, t_off = result["t_on_s"][i], result["t_off_s"][i]
        freq = 1.0 / (t_on + t_off) if t_on and t_off else 0.0
        lines.append(f"{e * 1e3:>8.3f}  {ms(t_on)}  {ms(t_off)}{freq:>8.2f}"
                     f"{result['duty_analytic'][i]:>8.4f}{result['duty_simulated_fine'][i]:>10.4f}"
                     f"{result['duty_simulated_frame'][i]:>11.4f}")
    lines.append(f"largest |simulated - analytic| duty: {result['max_error_fine']:.4f} at a "
                 f"{result['fine_step_s'] * 1e3:g} ms step, {result['max_error_frame']:.4f} at "
                 f"the {result['frame_s'] * 1e3:g} ms frame with the "
                 f"{result['min_on_time_s'] * 1e3:g} ms minimum on-time")
    return "\n".join(lines)


def format_analysis(result: dict) -> str:
    """An :func:`allsky.studies.analysis.analyze` result as text: margins, then PWPF."""
    return "\n".join(["Loop margins (linear, cut at the plant input)", "",
                      format_margins(result["margins"]), "", format_pwpf(result["pwpf"])])


def _finite_or_none(value):
    """JSON has no inf or nan: write them as null."""
    if isinstance(value, dict):
        return {k: _finite_or_none(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite_or_none(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def run_from_cli(cfg, args) -> int:
    """``allsky analyze``: print the tables; write --json and the --plot PNG.

    ``--json -`` writes the JSON alone to stdout, instead of the tables.
    """
    from allsky.apps.output import FIGURE_SUFFIXES, check_output, write_atomic

    check_output("--json", args.json)
    check_output("--plot", args.plot, suffixes=FIGURE_SUFFIXES)
    to_stdout = args.json == "-"
    say = (lambda *a, **k: None) if to_stdout else print
    result = analyze(cfg)
    say(format_analysis(result))
    body = json.dumps(_finite_or_none(result), indent=2) + "\n"
    if to_stdout:
        print(body, end="")
    elif args.json:
        say(f"wrote {write_atomic(args.json, body, option='--json')}")
    if args.plot:
        from allsky.apps import plots

        # Up to the frame's Nyquist frequency pi / frame_s: beyond it the loop is not defined.
        w = np.logspace(-2, math.log10(math.pi / cfg.mission.frame_s), 400)
        fig = plots.analysis(result, frequency_responses(scenario_loops(cfg), w))
        say(f"plot: {plots.save(fig, args.plot)}")
    return 0
