"""The configuration package's layout: one job per module, imports in one direction.

Read from the source with ``ast`` (nothing is imported), counting imports
inside functions too: a lazy import is still a dependency. The package face
(``allsky/config/__init__.py``) is part of the graph, so a module that
imports a name from ``allsky.config`` while the face imports that module is
a cycle here.
"""

import ast
from pathlib import Path

import pytest

from allsky.layers import find_cycles

PACKAGE = "allsky.config"
DIR = Path(__file__).resolve().parents[2] / "src" / "allsky" / "config"
#: Longest a module of the package may grow before its job should be split [lines].
MAX_LINES = 400


def _module(path: Path) -> str:
    return PACKAGE if path.stem == "__init__" else f"{PACKAGE}.{path.stem}"


MODULES = {_module(p): p for p in sorted(DIR.glob("*.py"))}


def _imports(path: Path, package: str = PACKAGE, modules=None) -> dict:
    """``{module of the package: names imported from it}`` for every import in ``path``.

    ``from allsky.config import scenario`` counts as an import of the module
    ``allsky.config.scenario`` (its name set empty: the module itself).
    """
    modules = MODULES if modules is None else modules
    found = {}
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            for a in node.names:
                if a.name in modules:
                    found.setdefault(a.name, set())
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:  # relative: from the package itself
                base = ".".join(filter(None, [package, base]))
            for a in node.names:
                sub = f"{base}.{a.name}"
                if sub in modules:
                    found.setdefault(sub, set())
                elif base in modules:
                    found.setdefault(base, set()).add(a.name)
    return found


GRAPH = {m: {d for d in _imports(p) if d != m} for m, p in MODULES.items()}


def test_the_package_has_the_modules_named_by_its_face():
    assert set(MODULES) == {PACKAGE, *(f"{PACKAGE}.{m}" for m in (
        "rules", "checkers", "toml_io", "schema", "cross_rules", "meanings", "dispersion_table", "faults",
        "frozen", "scenario", "dispersions"))}


def test_no_import_cycle_in_the_config_package():
    cycles = find_cycles(GRAPH)
    assert not cycles, "import cycles: " + "; ".join(" -> ".join(c) for c in cycles)


def test_scenario_loading_does_not_depend_on_drawing():
    """Dispersions are drawn over a loaded scenario, so nothing below may import them."""
    users = [m for m, deps in GRAPH.items() if f"{PACKAGE}.dispersions" in deps]
    assert users == []


def _private_uses(path: Path, modules=None) -> list:
    """Private names of sibling modules that ``path`` imports or reads (``config._thaw``)."""
    modules = MODULES if modules is None else modules
    private = [f"{dep}.{n}" for dep, names in _imports(path, modules=modules).items()
               for n in names if n.startswith("_")]
    tree = ast.parse(path.read_text(encoding="utf-8"))
    aliases = set()  # local names bound to a module of the package
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            aliases |= {a.asname for a in node.names if a.name in modules and a.asname}
        elif isinstance(node, ast.ImportFrom) and node.module:
            base = ".".join(filter(None, [PACKAGE, node.module])) if node.level else node.module
            aliases |= {a.asname or a.name for a in node.names if f"{base}.{a.name}" in modules}
    for node in ast.walk(tree):
        if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
                and node.value.id in aliases and node.attr.startswith("_")):
            private.append(f"{node.value.id}.{node.attr}")
    return private


@pytest.mark.parametrize("module", sorted(MODULES))
def test_modules_use_only_public_names_of_each_other(module):
    private = _private_uses(MODULES[module])
    assert not private, f"{module} reaches into private names: {private}"


@pytest.mark.parametrize("module", sorted(MODULES))
def test_modules_stay_small(module):
    lines = len(MODULES[module].read_text(encoding="utf-8").splitlines())
    assert lines <= MAX_LINES, f"{module} has {lines} lines: split it by job"


def test_the_checker_sees_lazy_relative_and_package_imports(tmp_path):
    fake = {f"{PACKAGE}.a": None, f"{PACKAGE}.b": None, PACKAGE: None}
    f = tmp_path / "x.py"
    f.write_text("from allsky.config import a\n"
                 "def g():\n    from .b import _hidden\n    from allsky.config import Name\n")
    assert _imports(f, modules=fake) == {f"{PACKAGE}.a": set(), f"{PACKAGE}.b": {"_hidden"},
                                         PACKAGE: {"Name"}}
    f.write_text("from allsky.config import a as cfg\nx = cfg._thaw\n"
                 "from allsky.config.b import _hidden\n")
    assert sorted(_private_uses(f, modules=fake)) == ["allsky.config.b._hidden", "cfg._thaw"]
    assert find_cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == [["a", "b", "c", "a"]]
    assert find_cycles({"a": {"b"}, "b": {"c"}, "c": set()}) == []
