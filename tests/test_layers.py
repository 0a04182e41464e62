"""The packages are layers: imports go down only, and no modules import each other in a loop.

Read from the source with ``ast`` (nothing is imported), counting imports
inside functions too: a lazy import is still a dependency. The order is
:data:`allsky.layers.LAYERS`, the one ``docs/architecture.md`` draws.
"""

import pytest

from allsky import layers
from allsky.layers import RANK, SRC, find_cycles, import_graph, imports_of, package_of

GRAPH = import_graph()


def test_every_package_has_a_layer():
    packages = {p.name for p in SRC.iterdir() if p.is_dir() and (p / "__init__.py").exists()}
    assert packages == set(RANK) - {""}
    assert sorted(RANK.values()) == list(range(len(layers.LAYERS)))


@pytest.mark.parametrize("module", sorted(GRAPH))
def test_imports_go_down(module):
    here = package_of(module)
    upward = [dep for dep in sorted(GRAPH[module])
              if package_of(dep) != here and RANK[package_of(dep)] >= RANK[here]]
    assert not upward, f"{module} ({here or 'foundation'}) imports up or sideways: {upward}"


def test_no_import_cycles():
    """Depth-first search for a loop in the module graph (package faces excluded)."""
    faces = {m for m in GRAPH if m.count(".") == 1 and (SRC / m.split(".")[1]).is_dir()}
    graph = {m: {d for d in deps if d in GRAPH and d not in faces and d != m}
             for m, deps in GRAPH.items() if m not in faces}
    cycles = find_cycles(graph)
    assert not cycles, "import cycles: " + "; ".join(" -> ".join(c) for c in cycles)


def test_the_checker_sees_lazy_and_dotted_imports(tmp_path):
    f = tmp_path / "x.py"
    f.write_text("import allsky.units\n\ndef f():\n    from allsky.apps import cli\n")
    assert imports_of(f) == {"allsky.apps.cli", "allsky.units"}
    assert package_of("allsky.hardware.gyro") == "hardware"
    assert package_of("allsky.units") == "" and package_of("allsky.__main__") == "apps"


def test_package_exports_match_the_lazy_table():
    import allsky

    assert set(allsky.__all__) == {"__version__", *allsky._EXPORTS}
    for name in allsky._EXPORTS:
        assert getattr(allsky, name) is not None


#: [lines] the most the mission's class may span: it drives the flight, the record keeps it
MISSION_LINES = 550


def test_the_mission_stays_the_driver():
    """``Mission`` (docstrings included) within MISSION_LINES; what it grows belongs elsewhere."""
    import ast

    tree = ast.parse((SRC / "sim" / "mission.py").read_text())
    cls = next(n for n in tree.body if isinstance(n, ast.ClassDef) and n.name == "Mission")
    span = cls.end_lineno - cls.lineno + 1
    assert span <= MISSION_LINES, (
        f"Mission spans {span} lines (at most {MISSION_LINES}): move the record's reading to "
        "allsky.sim.record, the commands' applying to allsky.sim.commands")
