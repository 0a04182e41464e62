"""Reference pages generated from the code, so that they cannot drift from it.

* ``docs/configuration.md``: every scenario key with its unit (from the
  key's suffix), default (the packaged default scenario), what it accepts
  (:func:`allsky.config.scenario.allowed`) and its meaning (the comment beside the key
  in ``scenarios/default.toml``).
* ``docs/cli.md``: the ``--help`` of every command.
* ``docs/blocks.md``: every patent numeral, its block, module and function
  (:data:`allsky.hardware.blocks.BLOCKS`) and every switch
  (:data:`allsky.hardware.wiring.SWITCHES`).
* In ``docs/theory_of_operation.md``, the sections between
  ``<!-- BEGIN GENERATED: name -->`` and ``<!-- END GENERATED: name -->``:
  the mode table (:data:`allsky.sequencer.modes.MODE_TABLE`) and the switch
  wiring.
* ``docs/img/block_diagram.png``: the block diagram, boxes from the block
  table, switch labels from the wiring table, positions from
  :mod:`allsky.apps.diagram_layout`.

``python -m allsky.apps.docgen [DOCS_DIR]`` rewrites them; a test checks that the
committed pages equal what this module generates.
"""

import argparse
import os
import re
import sys
from importlib import resources
from pathlib import Path

from allsky import config
from allsky.apps import architecture
from allsky.apps import diagram_layout as layout
from allsky.hardware import blocks, switch_bank, wiring
from allsky.sequencer import modes

#: Unit of a key from its name's suffix (longest suffix first).
UNIT_SUFFIXES = (
    ("_v_per_arcsec_s", "V/(arcsec/s)"), ("_v_per_arcsec", "V/arcsec"),
    ("_deg_h_rt_h", "deg/h/sqrt(h)"), ("_deg_rt_h", "deg/sqrt(h)"), ("_deg_h", "deg/h"),
    ("_deg_s", "deg/s"), ("_arcsec", "arcsec"), ("_urad", "urad"), ("_ppm", "ppm"),
    ("_kg_m2", "kg m^2"), ("_kg", "kg"), ("_deg", "deg"), ("_per_s", "1/s"), ("_pps", "pulse/s"),
    ("_frames", "frames"), ("_bits", "bit"), ("_utc", "UTC"), ("_s", "s"), ("_n", "N"),
    ("_m", "m"), ("_v", "V"),
)
SPECIAL_UNITS = {"star_tracker.magnitude_window": "mag", "target.ra_deg": "deg",
                 "sequencer.timeout_s": "s"}
#: Meanings of keys the default file leaves unset (so it carries no line for them).
UNSET_KEY_MEANINGS = {
    "target.ra_deg": "target right ascension (J2000), with dec_deg, in place of star",
    "target.dec_deg": "target declination (J2000), with ra_deg, in place of star",
}
KEY_LINE = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)\s*=")


def unit_of(key: str) -> str:
    """The unit a key's name carries ("-" for none)."""
    if key in SPECIAL_UNITS:
        return SPECIAL_UNITS[key]
    name = key.rsplit(".", 1)[1]
    for suffix, unit in UNIT_SUFFIXES:
        if name.endswith(suffix):
            return unit
    return "-"


def default_toml_text() -> str:
    return resources.files("allsky").joinpath("scenarios/default.toml").read_text()


def key_comments(text: str) -> tuple[dict, dict]:
    """Meaning of each key and intro of each section, from the default file's comments.

    A key's meaning is its trailing comment, or the comment lines right above
    it; comment lines right under a section header introduce the section.
    """
    keys, sections = {}, {}
    section, pending, in_value, after_header = None, [], False, False
    for raw in text.splitlines():
        line = raw.strip()
        if in_value:  # continuation lines of a multi-line array
            in_value = line.count("[") > line.count("]") or not line.endswith("]")
            continue
        if line.startswith("[") and line.endswith("]") and "=" not in line:
            section, pending, after_header = line.strip("[]"), [], True
            continue
        if line.startswith("#"):
            pending.append(line.lstrip("#").strip())
            continue
        if after_header and pending:  # the comment right under a header introduces it
            sections[section] = " ".join(pending)
            pending = []
        after_header = False
        if not line:
            pending = []
            continue
        m = KEY_LINE.match(line)
        if m and section:
            value, _, comment = line.partition("#")
            words = comment.strip() or " ".join(pending)
            keys[f"{section}.{m.group(1)}"] = words
            pending = []
            in_value = value.count("[") > value.count("]")
    return keys, sections


def _show_default(v) -> str:
    if hasattr(v, "isoformat"):
        return v.isoformat().replace("+00:00", "Z")
    if isinstance(v, tuple):
        return "[" + ", ".join(_show_default(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k} = {_show_default(x)}" for k, x in v.items()) + "}"
    if isinstance(v, float):
        return f"{v:g}"
    if isinstance(v, str):
        return f'"{v}"'
    if v is None:
        return "(not set)"
    return str(v).lower() if isinstance(v, bool) else str(v)


def config_reference() -> str:
    """Markdown of every scenario key."""
    cfg = config.load_scenario()
    meanings, intros = key_comments(default_toml_text())
    meanings = {**UNSET_KEY_MEANINGS, **meanings}
    out = ["# Configuration reference", "",
           ("Generated by `python -m allsky.apps.docgen` from the configuration rules and the "
           "packaged default scenario; do not edit by hand."), "",
           ("A scenario is a TOML file merged key by key over the default "
           "(`allsky config show` prints it whole). `--set KEY=VALUE` overrides one key "
           "with a TOML value, e.g. `--set gyro.drift_deg_h=[1,0,0]`. A key's unit is in "
           "its name. A value outside what the key accepts is refused with a one-line "
           "error naming the key (exit code 2)."), ""]
    section = None
    for key in config.RULES:
        sec, name = key.split(".", 1)
        if sec != section:
            section = sec
            out += ["", f"## [{sec}]", ""]
            if intros.get(sec):
                out += [intros[sec], ""]
            out += ["| key | unit | default | accepts | meaning |",
                    "|---|---|---|---|---|"]
        default = _show_default(getattr(getattr(cfg, sec), name))
        cells = [f"`{name}`", unit_of(key), f"`{default}`", config.allowed(key),
                 meanings.get(key, "")]
        out.append("| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |")
    cross = [f.__doc__.strip().splitlines()[0] for f in config.CROSS_RULES if f.__doc__]
    if cross:
        out += ["", "## Rules between keys", ""] + [f"- {c}" for c in cross]
    return "\n".join(out).replace("\n\n\n", "\n\n") + "\n"


def _subparsers(parser):
    for action in parser._actions:  # argparse offers no public walk of its tree
        if isinstance(action, argparse._SubParsersAction):
            return action.choices
    return {}


def cli_reference() -> str:
    """Markdown of ``allsky --help`` and every command's ``--help``."""
    from allsky.apps.cli import COMMON_FLAGS, EXIT_CODES, _parser

    old = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = "100"  # argparse wraps to the terminal; fix it for the page
    try:
        root = _parser()
        out = ["# Command-line reference", "",
               ("Generated by `python -m allsky.apps.docgen` from the argument parser; do not "
               "edit by hand."), "",
               "**Exit codes**", "", "| code | meaning |", "|---|---|",
               *(f"| {k} | {v} |" for k, v in EXIT_CODES.items()), "",
               "**Flags common to the commands**", "", "| flag | meaning |", "|---|---|",
               *(f"| `{k}` | {v} |" for k, v in COMMON_FLAGS.items()), "",
               "## allsky", "", "```", root.format_help().rstrip(), "```"]

        def walk(parser, path):
            for name, sub in _subparsers(parser).items():
                out.extend(["", f"## {path} {name}", "", "```",
                            sub.format_help().rstrip(), "```"])
                walk(sub, f"{path} {name}")

        walk(root, "allsky")
    finally:
        if old is None:
            del os.environ["COLUMNS"]
        else:
            os.environ["COLUMNS"] = old
    return "\n".join(out) + "\n"


# -- the mode table and the wiring -------------------------------------------------------------
def _switch_list(numbers) -> str:
    """``S10, S17+S19``: switches by number, coupled pairs joined with "+"."""
    out, done = [], set()
    for k in sorted(numbers):
        if k in done:
            continue
        mate = switch_bank.COUPLED.get(k)
        if mate in numbers:
            out.append(f"S{min(k, mate)}+S{max(k, mate)}")
            done |= {k, mate}
        else:
            out.append(f"S{k}")
            done.add(k)
    return ", ".join(out)


def _switch_range(numbers) -> str:
    """``S4-S6`` for three or more consecutive switches, else ``S12, S13``."""
    ks = sorted(numbers)
    if len(ks) >= 3 and ks == list(range(ks[0], ks[-1] + 1)):
        return f"S{ks[0]}-S{ks[-1]}"
    return ", ".join(f"S{k}" for k in ks)


def _operate_text(step) -> str:
    parts = []
    if step.open_:
        parts.append("open " + _switch_list(step.open_))
    if step.close:
        parts.append("close " + _switch_list(step.close))
    return ", ".join(parts)


def _seconds(name, cfg, mode) -> str:
    d = modes.DURATIONS[name]
    return f"{d.seconds(cfg, mode):g} s ({d.text})"


def _wait_text(step, cfg, mode) -> str:
    signals = ", ".join(step.signals)
    if step.watch == "settle":
        text = f"wait until settled: {signals}"
        if step.hold != "settle":
            text += f", held {_seconds(step.hold, cfg, mode)}"
    elif step.watch == "handover":
        text = (f"wait until {signals} is inside "
                f"{cfg.sequencer.handover_arcsec:g}\u2033 (hand-over)")
        if step.blank:
            text += f", not before {_seconds(step.blank, cfg, mode)} of blanking"
    else:
        text = f"wait {_seconds(step.hold, cfg, mode)}"
    text += f": *{step.what}*"
    if step.program != "none":
        text += f"; computer: {modes.PROGRAMS[step.program].text}"
    if step.record:
        text += f"; the samples kept as the {step.record}"
    if step.on_timeout:
        text += f"; on timeout: \u201c{step.on_timeout}\u201d"
    return text


def step_text(step, cfg, mode) -> str:
    """One step of the mode table in words (values from scenario ``cfg``)."""
    if isinstance(step, modes.Operate):
        return _operate_text(step)
    if isinstance(step, modes.Wait):
        return _wait_text(step, cfg, mode)
    return modes.action_text(step)


def mode_reference() -> str:
    """Markdown of the mode table: a switch table, then every mode step by step."""
    cfg = config.load_scenario()
    ends = {**modes.closed_after(modes.DITHER_PLAN), **modes.closed_after(modes.LEGACY_PLAN)}
    seq = cfg.sequencer
    out = [("Generated by `python -m allsky.apps.docgen` from the mode table "
            "(`allsky.sequencer.modes.MODE_TABLE`), with the values of the default scenario; "
            "do not edit by hand. *Settled* means every watched signal under "
            f"{seq.settle_threshold_arcsec:g}\u2033 (`sequencer.settle_threshold_arcsec`) "
            f"for {seq.settle_time_s:g} s (`sequencer.settle_time_s`); a lost Sun or star "
            f"(over {seq.sensor_loss_s:g} s while in use) or an empty tank aborts the "
            "mission."), "",
           "| mode | code | title | switch actions, in order | closed at the end |",
           "|---|---|---|---|---|"]
    for mode in modes.MODE_TABLE:
        actions = "; ".join(_operate_text(s) for s in mode.steps
                            if isinstance(s, modes.Operate))
        out.append(f"| {mode.name} | {mode.code:.1f} | {mode.title} | {actions or 'none'} | "
                   f"{_switch_list(ends[mode.name])} |")
    plans = ", ".join(f"{k}: {' '.join(v)}" for k, v in modes.PLANS.items())
    out += ["", (f"Plans ({plans}). Mode 6-1 opens S1-S3 when the scenario withholds the "
                 "calibration (`calibration.apply = false`).")]
    for mode in modes.MODE_TABLE:
        out += ["", f"### Mode {mode.name}: {mode.title}", "",
                (f"Telemetry code {mode.code:.1f}; time allowed "
                 f"{_seconds(mode.timeout, cfg, mode.name)}."), ""]
        out += [f"{i}. {step_text(s, cfg, mode.name)}" for i, s in enumerate(mode.steps, 1)]
        out += ["", f"Exit: \u201c{mode.exit.format(cfg=cfg)}\u201d"]
    return "\n".join(out) + "\n"


def wiring_reference() -> str:
    """Markdown of the wiring table: what each switch S1-S19 connects."""
    out = [("Generated from the wiring table (`allsky.hardware.wiring.SWITCHES`); do not edit "
            "by hand."), "",
           "| switch | connects, when closed | axis | coupled with |", "|---|---|---|---|"]
    for sw in wiring.SWITCHES:
        axis = wiring.AXES[sw.axis] if sw.axis != wiring.NONE else "selector: all three"
        mate = f"S{sw.coupled_with}" if sw.coupled_with else "-"
        out.append(f"| S{sw.number} | {sw.text} | {axis} | {mate} |")
    return "\n".join(out) + "\n"


# -- the block map page --------------------------------------------------------------------
def _code_cells(modules, functions) -> str:
    mods = ", ".join(f"`{m}`" for m in modules) or "-"
    return f"{mods} | {', '.join(f'`{f}`' for f in functions) or '-'}"


def blocks_reference() -> str:
    """Markdown of the block table and the switches: numeral -> block -> module -> function."""
    out = ["# Blocks: patent numeral \u2192 module", "",
           ("Generated by `python -m allsky.apps.docgen` from the block table "
            "(`allsky.hardware.blocks.BLOCKS`) and the wiring table "
            "(`allsky.hardware.wiring.SWITCHES`); do not edit by hand."), "",
           ("Every reference numeral of US 4,012,018 (Fig. 1, the vehicle; Fig. 2, the block "
            "diagram; SPEC.md \u00a73), every switch S1\u2013S19, and the parts the patent "
            "leaves out, with the module and function that implement them. Each module's "
            "docstring names the numerals it implements; `tests/test_block_map.py` checks "
            "that every numeral is mapped, that the modules and functions exist and that "
            "the docstrings name the numerals. Units are those at the block's boundary "
            "(arcsec and pulses in the electronics, SI in the physics; see "
            "`conventions.md`). The patent uses 128 twice: the yaw rate-command module and "
            "the yaw contact of S8.")]
    for kind, heading in blocks.KINDS.items():
        rows = [b for b in blocks.BLOCKS if b.kind == kind]
        out += ["", f"## {heading}", "",
                "| numeral | block | module | function | in \u2192 out [units] |",
                "|---|---|---|---|---|"]
        for b in rows:
            num = ", ".join(b.numerals) or "\u2014"
            out.append(f"| {num} | {b.name.replace('->', chr(0x2192))} | "
                       f"{_code_cells(b.modules, b.functions)} | "
                       f"{b.io.replace('->', chr(0x2192))} |")
        if kind == "selector":
            out += _switch_rows()
    return "\n".join(out) + "\n"


def _switch_rows() -> list:
    out = ["", "## Switches S1\u2013S19", "",
           ("Which mode operates each switch: the mode table, `allsky.sequencer.modes` "
            "(`theory_of_operation.md`)."), "",
           "| numeral | block | module | function | in \u2192 out [units] |",
           "|---|---|---|---|---|"]
    for sw in wiring.SWITCHES:
        coupled = f"; coupled with S{sw.coupled_with}" if sw.coupled_with else ""
        what = "axis 0/1/2" if sw.selector else "closed = 1, open = 0"
        fn = ("select", "SWITCHES") if sw.selector else ("operate", "SWITCHES")
        out.append(f"| S{sw.number} | {sw.text.replace('->', chr(0x2192))}{coupled} | "
                   f"{_code_cells(('allsky.hardware.switch_bank', 'allsky.hardware.wiring'), fn)}"
                   f" | {what} |")
    return out


PAGES = {"configuration.md": config_reference, "cli.md": cli_reference,
         "blocks.md": blocks_reference}
#: Generated sections inside hand-written pages: page -> {section name: generator}.
SECTIONS = {"theory_of_operation.md": {"modes": mode_reference, "wiring": wiring_reference},
            "architecture.md": {"layers": architecture.layers_table}}


def fill_sections(text: str, sections: dict) -> str:
    """``text`` with each ``<!-- BEGIN GENERATED: name -->`` section regenerated."""
    for name, make in sections.items():
        begin, end = f"<!-- BEGIN GENERATED: {name} -->\n", f"<!-- END GENERATED: {name} -->"
        if text.count(begin) != 1 or text.count(end) != 1:
            raise ValueError(f"no single generated section {name!r} in the page")
        head, rest = text.split(begin)
        _, tail = rest.split(end)
        text = head + begin + make() + end + tail
    return text


def write(docs_dir) -> list:
    """Write the generated pages and sections into ``docs_dir``; return their paths."""
    docs_dir = Path(docs_dir)
    paths = []
    for name, make in PAGES.items():
        path = docs_dir / name
        path.write_text(make())
        paths.append(path)
    for name, sections in SECTIONS.items():
        path = docs_dir / name
        path.write_text(fill_sections(path.read_text(), sections))
        paths.append(path)
    (docs_dir / "img").mkdir(exist_ok=True)
    path = docs_dir / "img" / "block_diagram.png"
    block_diagram(path)
    paths.append(path)
    path = docs_dir / "img" / "layers.png"
    architecture.layers_figure(path)
    paths.append(path)
    return paths


# -- the block diagram picture -----------------------------------------------------------------
def _block(numeral):
    """The block-table row whose first numeral is ``numeral``."""
    return next(b for b in blocks.BLOCKS if b.numerals and b.numerals[0] == numeral)


def switches_between(a: str, b: str) -> tuple:
    """Switches of the wiring table from block ``a``'s numerals to block ``b``'s."""
    src, dst = set(_block(a).numerals), set(_block(b).numerals)
    return tuple(sw for sw in wiring.SWITCHES
                 if src & set(sw.source.split("/")) and dst & set(sw.destination.split("/")))


def arrow_label(a: str, b: str) -> str:
    """What the figure writes on the line from block ``a`` to block ``b``."""
    sws = switches_between(a, b)
    if not sws:
        return ""
    label = _switch_range([s.number for s in sws])
    lines = [s.source_port.split()[-1] for s in sws if s.source_port.startswith("line")]
    return f"lines {', '.join(lines)} via {label}" if lines else label


def _box_edge(box, side):
    x, y, w, h = box
    return {"left": (x, y + h / 2), "right": (x + w, y + h / 2), "top": (x + w / 2, y + h),
            "bottom": (x + w / 2, y)}[side]


def block_diagram(path=None):
    """Draw the patent's block diagram, each block with its numerals and module.

    Boxes and their texts come from the block table, switch labels from the
    wiring table, positions from :mod:`allsky.apps.diagram_layout`. Returns
    the matplotlib Figure (written to ``path`` as PNG when given).
    """
    import textwrap

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import FancyArrowPatch, FancyBboxPatch

    boxes = layout.BOXES
    fig, ax = plt.subplots(figsize=layout.FIGSIZE_IN)
    x0, x1, y0, y1 = layout.EXTENT
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.axis("off")
    ax.set_title("All-sky pointing system (US 4,012,018): blocks, numerals and modules "
                 "(allsky.<module>)", fontsize=12)
    for numeral, (x, y, w, h) in layout.FRAMES.items():
        ax.add_patch(FancyBboxPatch((x, y), w, h, boxstyle="round,pad=0.05",
                                    fc="#f3f6fb", ec="#5577aa", ls="--", lw=1.2))
        ax.text(x + w - 0.05, y + h - 0.15, f"{_block(numeral).label} {numeral}", ha="right",
                va="top", fontsize=9, color="#335588")
    for numeral, (x, y, w, h) in boxes.items():
        b = _block(numeral)
        face = "#fff7e6" if numeral in layout.SHADED else "white"
        ax.add_patch(FancyBboxPatch((x, y), w, h, boxstyle="round,pad=0.03", fc=face,
                                    ec="black", lw=1.0))
        title = textwrap.fill(b.label, width=max(8, int(w * 8.5)))
        lines = [title, ", ".join(b.numerals)]
        ax.text(x + w / 2, y + h * 0.62, "\n".join(lines), ha="center", va="center",
                fontsize=8.5 if "\n" not in title else 7.8, fontweight="bold",
                linespacing=1.15)
        module = b.modules[0].removeprefix("allsky.")
        # Monospace at 7 pt fits about 12 characters per diagram unit with a margin; shrink to fit.
        ax.text(x + w / 2, y + 0.13, module, ha="center", va="bottom",
                fontsize=min(7.0, 7.0 * 11.5 * w / len(module)), family="monospace",
                color="#444444")

    def arrow(p, q, label="", color="black"):
        ax.add_patch(FancyArrowPatch(p, q, arrowstyle="-|>", mutation_scale=11, lw=1.1,
                                     color=color, shrinkA=0, shrinkB=0))
        if label:
            ax.text((p[0] + q[0]) / 2 + 0.05, (p[1] + q[1]) / 2 + 0.08, label, fontsize=7.5,
                    color="#aa2222", ha="left", va="bottom")

    for a, b, route in layout.ARROWS:
        A, B = boxes[a], boxes[b]
        if route == "h":
            right = A[0] < B[0]
            p, q = _box_edge(A, "right" if right else "left"), \
                _box_edge(B, "left" if right else "right")
        else:
            up = A[1] < B[1]
            p, q = _box_edge(A, "top" if up else "bottom"), _box_edge(B, "bottom" if up else "top")
        arrow(p, q, arrow_label(a, b))
    for a, b, points, at in layout.ROUTES:
        rate_lines = all(s.port == "rate_mode" for s in switches_between(a, b)) and \
            switches_between(a, b)
        color = "#555555" if rate_lines else "black"
        xs, ys = zip(*points)
        ax.plot(xs[:-1], ys[:-1], color=color, lw=1.1)
        arrow(points[-2], points[-1], color=color)
        label = arrow_label(a, b)
        if label:
            ax.text(points[at][0] + 0.08, points[at][1] + 0.06, label, fontsize=7.5,
                    color="#aa2222", ha="left", va="bottom")
    for a, b, points, text in layout.VEHICLE_LINES:
        arrow(points[0], points[1], text, color="black" if text else "#8a6d00")
    ax.text(0.05, 0.5, "Orange: sensors and the vehicle. Red labels: switches of the bank "
            "(allsky.hardware.wiring). The per-frame loop that runs the blocks in this order: "
            "allsky.sim.frame_loop.run_leg.", fontsize=8, color="#333333")
    fig.tight_layout()
    if path is not None:
        fig.savefig(path, dpi=110)
    return fig


if __name__ == "__main__":  # pragma: no cover
    for p in write(sys.argv[1] if len(sys.argv) > 1 else "docs"):
        print(p)
