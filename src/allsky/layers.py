"""Package layers of allsky, top to bottom, and the import graph read from source.

A package may import only from packages below it. ``tests/test_layers.py``
holds the code to this order; ``docs/architecture.md`` draws it
(:func:`allsky.apps.architecture.layers_figure`).
"""

import ast
from pathlib import Path
from typing import NamedTuple


class Layer(NamedTuple):
    """One package of the source tree and what it holds."""

    package: str  #: folder under src/allsky ("" = the top-level foundation modules)
    title: str  #: what a reader calls it
    holds: str  #: what lives there, in words


#: Top to bottom: a layer may import the layers after it, never those before.
LAYERS = (
    Layer("apps", "front ends",
          "command line, step display, reports, figures, replay, generated docs, files"),
    Layer("studies", "studies",
          "calibration comparison, Monte Carlo campaigns, loop analysis, estimator theory"),
    Layer("sim", "simulation",
          "compiled frame loop in stages, mission state, mission driver, telemetry schema and "
          "recorder, the journal"),
    Layer("sequencer", "master sequencer 20",
          "mode table and rules, the watch, the leg vocabulary, the plans (legacy, dither), "
          "the host protocol"),
    Layer("computer", "computer 111",
          "CPU 22, word registers 23/24, computer sequencer 21, register 24's ground program"),
    Layer("hardware", "numbered blocks",
          "gyros 1-3 ... jets 39-41, sensors 104/105, switch bank and wiring table S1-S19"),
    Layer("config", "configuration",
          "scenario rules, loading and merging, dispersions"),
    Layer("vehicle", "vehicle and sky",
          "rigid body (compiled and python-control), quaternions, Sun (the DE421 ephemeris) "
          "and stars, envelopes"),
    Layer("", "foundations", "units and conversions, the vocabulary (modes, fault kinds, "
          "axes, actions, journal kinds), the exact arithmetic (the same bits on every "
          "machine), the jit decorators and their caches (the on-disk key, the functions "
          "built ahead of time, the compile lock), the noise source"),
)
#: Package -> rank (0 = bottom).
RANK = {layer.package: len(LAYERS) - 1 - i for i, layer in enumerate(LAYERS)}
#: Top-level modules that are front doors rather than foundations.
FRONT_DOORS = {"allsky.__main__": "apps"}

SRC = Path(__file__).resolve().parent


def module_name(path: Path, root: Path = SRC) -> str:
    """Dotted module name of source file ``path`` under ``root`` (the allsky folder)."""
    parts = path.relative_to(root.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def package_of(module: str, root: Path = SRC) -> str:
    """Layer package of a dotted allsky module name ("" for the foundations).

    ``module`` is the name (``allsky.sim.mission``); ``root`` the allsky
    source folder, where a layer package must be a folder.
    """
    if module in FRONT_DOORS:
        return FRONT_DOORS[module]
    parts = module.split(".")
    if len(parts) >= 2 and parts[1] in RANK and (root / parts[1]).is_dir():
        return parts[1]
    return ""


def imports_of(path: Path, root: Path = SRC) -> set:
    """Every allsky module an import statement of ``path`` names (lazy imports too).

    ``root`` is the allsky source folder: ``from allsky.x import y`` counts
    as an import of module ``allsky.x.y`` when that is a file or package there.
    """
    tree = ast.parse(path.read_text(encoding="utf-8"))
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found |= {a.name for a in node.names if a.name.split(".")[0] == "allsky"}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0 \
                and node.module.split(".")[0] == "allsky":
            for a in node.names:
                sub = f"{node.module}.{a.name}"
                found.add(sub if _is_module(sub, root) else node.module)
    return found


def _is_module(module: str, root: Path) -> bool:
    rel = Path(*module.split(".")[1:])
    return (root / rel).with_suffix(".py").exists() or (root / rel / "__init__.py").exists()


def import_graph(root: Path = SRC) -> dict:
    """Module -> set of allsky modules it imports, for each source file under ``root``."""
    return {module_name(p, root): imports_of(p, root) for p in sorted(root.rglob("*.py"))}


def package_edges(graph: dict) -> dict:
    """(importing package, imported package) -> number of module imports between them.

    ``graph`` is an import graph as :func:`import_graph` makes it.
    """
    edges = {}
    for module, deps in graph.items():
        a = package_of(module)
        for dep in deps:
            b = package_of(dep)
            if a != b:
                edges[(a, b)] = edges.get((a, b), 0) + 1
    return edges


def find_cycles(graph: dict) -> list:
    """Every import loop a depth-first search meets, as ``[a, b, ..., a]``.

    ``graph`` maps each module to the modules it imports (:func:`import_graph`).
    """
    state, stack, cycles = {}, [], []

    def visit(m):
        state[m] = "open"
        stack.append(m)
        for d in sorted(graph.get(m, ())):
            if state.get(d) == "open":
                cycles.append(stack[stack.index(d):] + [d])
            elif d not in state:
                visit(d)
        stack.pop()
        state[m] = "done"

    for m in sorted(graph):
        if m not in state:
            visit(m)
    return cycles
