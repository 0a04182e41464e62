"""``allsky analyze``: loop-margin and PWPF tables, the JSON file and the figure.

The numbers come from :func:`allsky.studies.analysis.analyze`; this module
presents them. With ``--envelope`` it shows instead the torque and momentum
envelopes of the scenario's reaction-wheel array and of its jets
(:func:`allsky.studies.envelope_check.scenario_envelopes`) and checks the
dither example in them.
"""

import json
import math
from types import MappingProxyType

import numpy as np

from allsky.studies.analysis import RATE_LOOP_AXES, analyze, frequency_responses, scenario_loops
from allsky.studies.envelope_check import (
    FROM_SCENARIO,
    SCENARIO_KEYS,
    scenario_envelopes,
)
from allsky.vehicle.envelopes import facet_polygons


def format_margins(margins: dict) -> str:
    """Loop margins as a text table.

    ``margins`` are :func:`allsky.studies.analysis.loop_margins`'.
    """
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
    """The PWPF static characteristic (analysis.pwpf_static_characteristic) as a table.

    ``result`` is :func:`allsky.studies.analysis.pwpf_static_characteristic`'s.
    """
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
    """An analysis as text: margins, then PWPF.

    ``result`` is :func:`allsky.studies.analysis.analyze`'s.
    """
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
    With ``--envelope``: :func:`run_envelope`.

    ``cfg`` is the scenario the command line loaded (``--scenario``, ``--set``)
    and ``args`` the parsed command line (:mod:`allsky.apps.cli`); returns the
    exit status.
    """
    from allsky.apps.output import FIGURE_SUFFIXES, check_output, write_atomic

    if args.envelope:
        return run_envelope(cfg, args)
    given = [f"--wheel-{k}" for k in ("beta", "torque", "momentum")
             if getattr(args, f"wheel_{k}") is not None]
    if given:
        from allsky.config import ConfigError

        raise ConfigError(None, rule=f"{given[0]}: only with --envelope")

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
        say(f"plot: {plots.save(fig, args.plot, '--plot')}")
    return 0


# ---------------------------------------------------------------------------
# --envelope: reaction-wheel and jet torque/momentum envelopes
# ---------------------------------------------------------------------------

def _reach_row(label, reach, unit) -> str:
    r, m = reach[f"min_radius_{unit}"], reach[f"max_{unit}"]
    return f"  {label:<26}{r:>10.4g}{m[0]:>12.4g}{m[1]:>12.4g}{m[2]:>12.4g}"


#: The option that replaces each part of the scenario's wheel array.
WHEEL_OPTIONS = MappingProxyType({"axes": "--wheel-beta", "torque_max_n_m": "--wheel-torque",
                                   "momentum_max_n_m_s": "--wheel-momentum"})


def _origin(arr: dict, part: str) -> str:
    """Where a part of the analysed array came from: a scenario key or an option."""
    if arr["source"][part] == FROM_SCENARIO:
        return SCENARIO_KEYS[part]
    if part == "axes":
        return (f"{WHEEL_OPTIONS[part]} {arr['beta_deg']:g} (four-wheel pyramid about +x, "
                f"each spin axis {arr['beta_deg']:g} deg from it)")
    return WHEEL_OPTIONS[part]


def format_wheel_array(arr: dict, actuators_kind=None) -> str:
    """The analysed wheel array as text: one row per wheel, and where it came from.

    ``arr`` is the ``wheel_array`` of
    :func:`allsky.studies.envelope_check.scenario_envelopes`;
    ``actuators_kind`` the scenario's ``actuators.kind``, to say whether it
    flies these wheels.
    """
    axes = np.array(arr["axes"])
    from_scenario = all(v == FROM_SCENARIO for v in arr["source"].values())
    head = (f"{len(axes)} wheels, the scenario's [wheels]" if from_scenario else
            f"{len(axes)} wheels, the scenario's [wheels] with parts replaced")
    if actuators_kind is not None and from_scenario:
        head += (f" (flown: actuators.kind = \"{actuators_kind}\")" if actuators_kind == "wheels"
                 else f" (flown with actuators.kind = \"wheels\"; this scenario flies "
                      f"\"{actuators_kind}\")")
    cols = (f"  {'wheel':<7}{'spin axis x, y, z (body)':>27}{'from +x [deg]':>15}"
            f"{'torque [N m]':>14}{'momentum [N m s]':>18}")
    lines = [f"Reaction wheels: {head}", cols, "  " + "-" * (len(cols) - 2)]
    for i, g in enumerate(axes):
        angle = math.degrees(math.acos(max(-1.0, min(1.0, float(g[0])))))
        lines.append(f"  {i:<7}{g[0]:>9.4f}{g[1]:>9.4f}{g[2]:>9.4f}{angle:>15.2f}"
                     f"{arr['torque_max_n_m'][i]:>14.4g}{arr['momentum_max_n_m_s'][i]:>18.4g}")
    lines.append(f"  axes: {_origin(arr, 'axes')}; torque limits: "
                 f"{_origin(arr, 'torque_max_n_m')}; momentum limits: "
                 f"{_origin(arr, 'momentum_max_n_m_s')}")
    return "\n".join(lines)


def format_envelopes(result: dict, actuators_kind=None) -> str:
    """A :func:`scenario_envelopes` result as text: array, reaches, dither check.

    ``result`` is that result; ``actuators_kind`` the scenario's
    ``actuators.kind`` ("jets" or "wheels"), which the array's heading names.
    """
    w, dc = result["wheels"], result["dither_check"]
    failed = w["one_failed"]["wheel"]
    head = f"  {'':<26}{'radius':>10}{'x (roll)':>12}{'y (pitch)':>12}{'z (yaw)':>12}"
    emulated = dc.get("emulated_inertia_kg_m2")
    emulated = ("not the emulated one" if emulated is None else
                "not the emulated one, whose inertia is "
                f"{', '.join(f'{j:g}' for j in emulated)} kg m^2 about x, y, z")
    lines = [format_wheel_array(result["wheel_array"], actuators_kind), "",
             ("Envelopes: inscribed radius (reached in every direction) and largest reach "
              "along each body axis"),
             head, "  " + "-" * (len(head) - 2),
             _reach_row("wheels, torque [N m]", w["torque"], "n_m"),
             _reach_row("wheels, momentum [N m s]", w["momentum"], "n_m_s"),
             _reach_row("  minimum norm, torque", w["pseudo_inverse"]["torque"], "n_m"),
             _reach_row("  minimum norm, momentum", w["pseudo_inverse"]["momentum"], "n_m_s"),
             _reach_row(f"wheel {failed} failed, torque", w["one_failed"]["torque"], "n_m"),
             _reach_row(f"wheel {failed} failed, momentum", w["one_failed"]["momentum"],
                        "n_m_s"),
             _reach_row("jets 39-41, torque [N m]", result["jets"]["torque"], "n_m"),
             (f"  (wheel {failed}: the single failure leaving the least torque in every "
              "direction)"),
             ("  (the wheels' rows are the zonotope, what an allocation to the whole envelope "
              "reaches, wheels.allocation = \"direct\"; the minimum-norm rows what the "
              "pseudo-inverse delivers before a wheel saturates"
              + (f": this scenario flies \"{w['allocation']}\")" if "allocation" in w
                 else ")")),
             "",
             f"Dither check on the dither document's example vehicle ({emulated}):",
             (f"  inertia {dc['inertia_kg_m2']:g} kg m^2 about each axis, amplitude "
              f"{dc['amplitude_rad'] * 1e6:g} urad, period {dc['period_s']:g} s; "
              f"peak torque J A w^2 = {dc['peak_torque_n_m']:.4g} N m"),
             f"  {'margin, dither about':<26}{'roll':>10}{'pitch':>12}{'yaw':>12}{'fits':>8}"]
    for key, label in (("wheels", "wheels"), ("one_failed", f"wheel {failed} failed"),
                       ("jets", "jets 39-41")):
        m = dc[key]["margin_per_axis"]
        lines.append(f"  {label:<26}{m[0]:>10.4g}{m[1]:>12.4g}{m[2]:>12.4g}"
                     f"{'yes' if dc[key]['inside'] else 'NO':>8}")
    lines.append("  (margin: available torque along the dither's axis / its peak torque; "
                 "fits when >= 1)")
    return "\n".join(lines)


def _draw_zonotope(ax, envelope, colour):
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    facets = Poly3DCollection(facet_polygons(envelope), facecolor=colour, alpha=0.35,
                              edgecolor="0.15", linewidth=0.6)
    ax.add_collection3d(facets)
    return facets


def _draw_box(ax, half_n_m, reach, colour, label):
    """Faces of the box ``|x_i| <= half_i`` inside the view cube ``|x_i| <= reach``.

    A face beyond the view is left out rather than drawn at the view's edge;
    the others are clipped to the view.
    """
    half = np.asarray(half_n_m, dtype=float)
    extent = np.minimum(half, reach)
    drawn = False
    for i in range(3):
        if half[i] > reach:
            continue
        j, k = (i + 1) % 3, (i + 2) % 3
        square = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1], [-1, -1]], dtype=float)
        for side in (-1.0, 1.0):
            ring = np.zeros((5, 3))
            ring[:, i] = side * half[i]
            ring[:, j] = square[:, 0] * extent[j]
            ring[:, k] = square[:, 1] * extent[k]
            ax.plot(*ring.T, color=colour, lw=1.0, ls="--", label=None if drawn else label)
            drawn = True


BODY_AXIS_LABELS = ("x roll [N m]", "y pitch [N m]", "z yaw [N m]")


def _array_title(arr: dict) -> str:
    """The analysed array in a few words: wheels, layout, torque limits."""
    limits = np.asarray(arr["torque_max_n_m"], dtype=float)
    each = (f"{limits[0]:g} N m each" if np.all(limits == limits[0]) else
            f"{limits.min():g} to {limits.max():g} N m per wheel")
    if arr.get("beta_deg") is not None:
        layout = f"pyramid about +x (roll), spin axes {arr['beta_deg']:.2f}° from +x"
    elif arr.get("source", {}).get("axes") == FROM_SCENARIO:
        layout = "the scenario's wheels.axes"
    else:
        layout = "given axes"
    return f"{len(limits)} wheels, {layout}, {each}"


def envelope_figure(result: dict, show_failure=True):
    """``allsky analyze --envelope``: the torque envelopes in 3-D, with the jets.

    Parameters
    ----------
    result : dict
        :func:`allsky.studies.envelope_check.scenario_envelopes` (or
        ``envelope_analysis``): any number of wheels, any axes and limits.
    show_failure : bool
        Add a second panel with the worst single failure's envelope.

    Returns
    -------
    matplotlib.figure.Figure
        One 3-D panel per envelope: the facets as translucent polygons (one
        ``Poly3DCollection`` per panel, one polygon per facet), the jets'
        torque box as a dashed wireframe, the spin axes as arrows and the
        dither's peak torque about each body axis as points.
    """
    from matplotlib.figure import Figure

    from allsky.vehicle.envelopes import make_envelope

    arr, dc = result["wheel_array"], result["dither_check"]
    axes = np.array(arr["axes"])
    full = make_envelope(axes, arr["torque_max_n_m"])
    failed = result["wheels"]["one_failed"]["wheel"]
    panels = [(f"all {len(axes)} wheels", full, "tab:blue", "wheels")]
    if show_failure:
        panels.append((f"wheel {failed} failed", full.without(failed), "tab:orange",
                       "one_failed"))
    jets = np.array(result["jets"]["torque"]["max_n_m"])
    # Equal scales on the three axes, set by the wheels: the jets' faces beyond are named
    # in the legend instead of shrinking the wheels to a dot.
    tip = 1.25 * full.max_along(axes)
    reach = 1.05 * float(np.max(tip))
    beyond = [f"|{'xyz'[i]}| <= {jets[i]:g}" for i in range(3) if jets[i] > reach]
    shown = [f"|{'xyz'[i]}| <= {jets[i]:g}" for i in range(3) if jets[i] <= reach]
    jet_label = "jets 39-41: " + "; ".join(
        ([f"{', '.join(shown)} N m"] if shown else [])
        + ([f"{', '.join(beyond)} N m off the scale"] if beyond else []))
    fig = Figure(figsize=(6.0 * len(panels), 6.6), layout="constrained")
    fig.suptitle(f"Torque envelopes [N m]: {_array_title(arr)}", fontsize=11)
    peak = dc["peak_torque_n_m"]
    for k, (title, env, colour, key) in enumerate(panels):
        ax = fig.add_subplot(1, len(panels), k + 1, projection="3d")
        _draw_zonotope(ax, env, colour)
        _draw_box(ax, jets, reach, "0.3", jet_label)
        for wheel, a in enumerate(axes):
            if key == "one_failed" and wheel == failed:
                continue
            ax.plot(*np.array([[0.0, 0.0, 0.0], a * tip[wheel]]).T, color="black", lw=0.8)
            ax.text(*(a * tip[wheel]), f" wheel {wheel}", fontsize=8)
        dots = peak * np.vstack([np.eye(3), -np.eye(3)])
        ax.scatter(*dots.T, color="tab:red", s=12, depthshade=False,
                   label=f"dither example's peak torque {peak:.3g} N m on each axis "
                         f"({dc['inertia_kg_m2']:g} kg m^2 vehicle)")
        ax.set_title(f"{title}: {len(env.normals)} facets, inscribed radius "
                     f"{env.min_radius:.3g} N m;\ndither example's margin {dc[key]['margin']:.3g} "
                     f"({dc[key]['worst_axis']})", fontsize=10)
        for set_lim in (ax.set_xlim, ax.set_ylim, ax.set_zlim):
            set_lim(-reach, reach)
        ax.set_box_aspect((1, 1, 1), zoom=0.92)
        for set_label, text in zip((ax.set_xlabel, ax.set_ylabel, ax.set_zlabel),
                                   BODY_AXIS_LABELS, strict=True):
            set_label(text, fontsize=8)
        ax.tick_params(labelsize=7)
        ax.view_init(elev=22, azim=-58)
    fig.legend(*fig.axes[0].get_legend_handles_labels(), loc="outside lower center",
               fontsize=8, ncols=2, frameon=False)
    return fig


def run_envelope(cfg, args) -> int:
    """``allsky analyze --envelope``: print the envelopes; write --json and --plot.

    The wheel array is the scenario's ``[wheels]``; ``--wheel-beta``,
    ``--wheel-torque`` and ``--wheel-momentum`` replace its axes (by a
    four-wheel pyramid) and its limits.

    ``cfg`` is the scenario the command line loaded (``--scenario``, ``--set``)
    and ``args`` the parsed command line (:mod:`allsky.apps.cli`); returns the
    exit status.
    """
    from allsky.apps.output import FIGURE_SUFFIXES, check_output, write_atomic

    check_output("--json", args.json)
    check_output("--plot", args.plot, suffixes=FIGURE_SUFFIXES)
    to_stdout = args.json == "-"
    say = (lambda *a, **k: None) if to_stdout else print
    result = scenario_envelopes(cfg, args.wheel_beta, args.wheel_torque, args.wheel_momentum)
    say(format_envelopes(result, cfg.actuators.kind))
    body = json.dumps(result, indent=2) + "\n"
    if to_stdout:
        print(body, end="")
    elif args.json:
        say(f"wrote {write_atomic(args.json, body, option='--json')}")
    if args.plot:
        from allsky.apps import plots

        say(f"plot: {plots.save(envelope_figure(result), args.plot, '--plot')}")
    return 0
