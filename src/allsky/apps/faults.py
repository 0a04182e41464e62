"""``allsky faults`` (the fault matrix) and ``allsky scenarios``.

The matrix is computed by :func:`allsky.studies.faults.fault_matrix`; this
module prints it as a table (rows: fault kinds; columns: the mode the fault
starts in; a cell: the final pointing error of a complete mission, or the
number of its abort reason, listed under the table) and writes its JSON.
"""

import json
import sys
import time

from allsky.config import ConfigError
from allsky.config.faults import START_MODES

#: Blanks between two columns of the matrix [characters].
GAP = 2


def _cell(row, notes) -> str:
    if row["status"] == "complete":
        pe = row["pointing_error_arcsec"]
        return f'{pe:.0f}"' if pe >= 10 else f'{pe:.1f}"'
    mark = "E" if row["status"] == "error" else "A"
    key = (mark, row["outcome"])
    if key not in notes:  # numbered per mark: A1, A2, ... and E1, E2, ...
        notes[key] = sum(1 for m, _ in notes if m == mark) + 1
    return f"{mark}{notes[key]}"


def format_matrix(result, wall_s=None) -> str:
    """The matrix as text: a table of outcomes, the abort reasons, the counts.

    ``result`` is :func:`allsky.studies.faults.fault_matrix`'s; ``wall_s``
    [s], if given, is the time the matrix took, which the counts line names.
    """
    modes, kinds = result["modes"], result["kinds"]
    ref = result["reference"]
    notes = {}
    by = {(r["kind"], r["mode"]): r for r in result["cases"]}
    table = [[_cell(by[(k, m)], notes) if (k, m) in by else "-" for m in modes] for k in kinds]
    heads = [f"Mode {m}" for m in modes]
    # Each column as wide as its widest entry, so that no two run together.
    widths = [max(len(h), *(len(row[j]) for row in table)) + GAP for j, h in enumerate(heads)]
    first = max(len("fault"), *(len(k) for k in kinds))
    n = len(result["cases"])
    own = result.get("scenario_faults") or []
    ref_name = ("Reference (the scenario's own faults: " + "; ".join(own) + ")" if own
                else "Fault-free reference")
    lines = [(f"Fault matrix: {n} mission{'' if n == 1 else 's'}, each with one fault "
              "starting at the start of a mode"),
             f"{ref_name}: {ref['status']}"
             + (f', pointing {ref["pointing_error_arcsec"]:.1f}"'
                if ref["status"] == "complete" else f": {ref['abort_reason']}"), "",
             f"  {'fault':<{first}}" + "".join(f"{h:>{w}}" for h, w in zip(heads, widths))]
    for k, cells in zip(kinds, table):
        lines.append(f"  {k:<{first}}" + "".join(f"{c:>{w}}" for c, w in zip(cells, widths)))
    lines += ["", ('  x": complete, final pointing error [arcsec]; An: aborted (below); '
              "En: the case raised (a defect)")]
    lines += [f"  {mark}{n}  {text}" for (mark, text), n in sorted(
        notes.items(), key=lambda item: (item[0][0], item[1]))]
    lines += ["", "  faults flown: " + "; ".join(f"{k}: {result['faults'][k]}" for k in kinds)]
    c = result["counts"]["status"]
    tail = f" in {wall_s:.0f} s" if wall_s is not None else ""
    lines.append(f"  {c.get('complete', 0)} complete, {c.get('aborted', 0)} aborted, "
                 f"{c.get('error', 0)} errors{tail}")
    if result.get("interrupted"):
        lines.append("  (interrupted: the cases finished so far)")
    return "\n".join(lines)


def _names(flag, given, known):
    """``given`` if every name is in ``known``; else a ConfigError naming the first stranger."""
    for name in given or ():
        if name not in known:
            raise ConfigError(None, rule=f"{flag}: unknown name {name!r}; known: "
                                         + ", ".join(known))
    return given


def _flown(modes, cfg):
    """``modes`` if the mission flies each; else a ConfigError naming ``--modes``."""
    from allsky.sequencer.modes import LEGACY_PLAN, mission_plan

    plan = mission_plan(LEGACY_PLAN, cfg)
    for mode in modes:
        if mode not in plan:
            raise ConfigError(None, rule=f"--modes: the mission never flies mode {mode!r} "
                                         f"(it flies {', '.join(dict.fromkeys(plan))}): a "
                                         "fault starting there would never start")
    return modes


def run_from_cli(cfg, args) -> int:
    """``allsky faults``: fly the matrix, print it, write its JSON (``--json``).

    ``cfg`` is the scenario the command line loaded (``--scenario``, ``--set``)
    and ``args`` the parsed command line (:mod:`allsky.apps.cli`); returns the
    exit status.
    """
    from tqdm import tqdm

    from allsky.apps.output import Interrupted, cap_workers, check_output, write_atomic
    from allsky.studies.faults import MATRIX_FAULTS, MATRIX_MODES, fault_matrix

    check_output("--json", args.json)
    kinds = _names("--kinds", args.kinds, MATRIX_FAULTS) or list(MATRIX_FAULTS)
    modes = _flown(_names("--modes", args.modes, START_MODES) or list(MATRIX_MODES), cfg)
    total = len(kinds) * len(modes) + 1
    workers, note = cap_workers(args.workers, total)
    if note:
        print(f"allsky: {note}", file=sys.stderr)
    to_stdout = args.json == "-"
    bar = tqdm(total=total, desc="fault matrix", unit="mission", file=sys.stderr,
               disable=True if args.quiet else None)
    t0 = time.perf_counter()
    try:
        result = fault_matrix(cfg, kinds, modes, workers,
                              on_progress=lambda done, n: bar.update(done - bar.n))
    finally:
        bar.close()
    wall_s = time.perf_counter() - t0
    body = json.dumps({**result, "wall_s": wall_s, "workers": workers}, indent=2) + "\n"
    if to_stdout:
        sys.stdout.write(body)
    else:
        print(format_matrix(result, wall_s))
        if args.json:
            write_atomic(args.json, body, option="--json")
            print(f"wrote {args.json}")
    if result.get("interrupted"):
        raise Interrupted(f"after {len(result['cases'])} of {total - 1} cases (the table and "
                          "JSON cover those)")
    raised = result["counts"]["status"].get("error", 0)
    if raised:  # a case that raised is a defect of allsky, not an outcome of the mission
        print(f"allsky: internal error: {raised} case{'s' if raised != 1 else ''} of the "
              "matrix raised (En in the table); the matrix and its JSON are written",
              file=sys.stderr)
        return 3
    return 0


def format_scenarios(entries) -> str:
    """The packaged scenarios: name and the first line of each file's story.

    ``entries`` are ``{"name", "path", "title"}`` per scenario.
    """
    width = max(len(e["name"]) for e in entries)
    lines = ["Packaged scenarios (allsky run NAME; allsky scenarios NAME: its card):"]
    lines += [f"  {e['name']:<{width}}  {e['title']}" for e in entries]
    return "\n".join(lines)


#: The packaged scenarios' cards (docs/faults.md, "Historical anomalies", shows them all).
CARDS_FILE = "cards.md"


def scenario_cards() -> dict:
    """The cards of the packaged scenarios: name -> ``{"title", "text"}``.

    Each card (``src/allsky/scenarios/cards.md``) is a heading
    ``### `NAME` — title`` and paragraphs: what happened, with its sources;
    what the scenario flies; what it leaves out.
    """
    from allsky.config.schema import DEFAULT_SCENARIO_PATH

    text = (DEFAULT_SCENARIO_PATH.parent / CARDS_FILE).read_text(encoding="utf-8")
    cards = {}
    for chunk in text.split("\n### ")[1:]:
        head, _, body = chunk.partition("\n")
        name, _, title = head.partition(" \u2014 ")
        cards[name.strip("` ")] = {"title": title.strip(), "text": body.strip()}
    return cards


def format_card(name, title, text, width=100) -> str:
    """Card ``name`` as the terminal shows it, each paragraph folded to ``width``.

    ``title`` is its heading's, ``text`` its paragraphs (markdown).
    """
    import re
    import textwrap

    lines = [f"{name} \u2014 {title}" if title else name, ""]
    for para in text.split("\n\n"):
        plain = re.sub(r"\*\*(.+?)\*\*", r"\1", " ".join(para.split()))
        plain = plain.replace("`", "")
        lines += textwrap.wrap(plain, width, break_on_hyphens=False) + [""]
    return "\n".join(lines).rstrip("\n")


def scenarios_from_cli(cfg, args) -> int:
    """``allsky scenarios [NAME] [--json PATH]``: the scenarios, or one's card.

    With NAME, the scenario's card: what happened, with its sources, what the
    scenario flies and what it leaves out (a scenario without a card: the
    story of its file's comment). ``cfg`` is None (the command loads no
    scenario) and ``args`` the parsed command line (:mod:`allsky.apps.cli`);
    returns the exit status.
    """
    from allsky.apps.output import check_output, write_atomic
    from allsky.apps.report import report_width
    from allsky.config import ConfigError
    from allsky.config.faults import packaged_scenarios

    check_output("--json", args.json)
    entries = []
    for e in packaged_scenarios():  # the title: the file's first comment line
        with open(e["path"], encoding="utf-8") as f:
            entries.append({**e, "title": f.readline().lstrip("# ").strip()})
    name = getattr(args, "name", None)
    if name is not None:
        known = {e["name"]: e for e in entries}
        if name not in known:
            raise ConfigError(None, rule=f"scenario {name!r}: not a packaged scenario (one of "
                                         f"{', '.join(known)})")
        card = scenario_cards().get(name)
        if card is None:
            from allsky.apps.replay import describe_scenario

            about = describe_scenario(name)
            card = {"title": about["title"],
                    "text": about["description"] or "No historical card: not a flight's story."}
        data = {**known[name], "card_title": card["title"], "card": card["text"]}
        text = format_card(name, card["title"], card["text"], report_width())
    else:
        data, text = entries, format_scenarios(entries)
    if args.json:
        body = json.dumps(data, indent=2) + "\n"
        if args.json == "-":
            sys.stdout.write(body)
            return 0
        write_atomic(args.json, body, option="--json")
    print(text)
    return 0
