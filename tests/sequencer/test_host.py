"""The seam between master sequencer 20 and the mission (allsky.sequencer.host).

Read from the source with ``ast``: every attribute the sequencer's steps use
on the mission (``m.<name>`` in the master sequencer and the dither mode) is
a member of :class:`~allsky.sequencer.host.Host`; the mission offers every
member; and nothing in the package writes or reads another object's private
field (``x._name`` for any ``x`` but ``self`` and ``cls``).
"""

import ast
import inspect
from pathlib import Path

from allsky.config import load_scenario
from allsky.sequencer import dither_mode, host, master_sequencer
from allsky.sim.mission import Mission

SRC = Path(__file__).resolve().parents[2] / "src" / "allsky"


def _members():
    names = set(host.Host.__annotations__)
    names |= {n for n, v in vars(host.Host).items()
              if callable(v) and not n.startswith("_")}
    return names


def _used_on_m(module):
    tree = ast.parse(inspect.getsource(module))
    used = set()
    for fn in ast.walk(tree):
        if isinstance(fn, ast.FunctionDef) and fn.args.args and fn.args.args[0].arg == "m":
            for node in ast.walk(fn):
                if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) \
                        and node.value.id in ("m", "mm"):
                    used.add(node.attr)
    return used


def test_the_sequencer_uses_only_what_the_host_declares():
    members = _members()
    for module in (master_sequencer, dither_mode):
        extra = _used_on_m(module) - members
        assert not extra, f"{module.__name__} uses {sorted(extra)}, not in Host"


def test_the_mission_is_a_host():
    m = Mission(load_scenario(), telemetry=False)
    for name in _members():
        assert hasattr(m, name), name
        if callable(getattr(host.Host, name, None)):
            assert callable(getattr(m, name)), name


#: A named tuple's own API (public, named with an underscore so as not to clash), and
#: ``os._exit`` (the documented exit without clean-up).
NAMED_TUPLE_API = {"_replace", "_asdict", "_fields", "_make", "_exit"}
#: Private fields of other libraries read where they offer no public way, each guarded:
#: argparse's list of a parser's actions and subparsers (the generated CLI reference),
#: numba's cache locators and index (allsky.jit_cache, allsky.compiles).
LIBRARY_INTERNALS = {("apps/cli.py", "_actions"), ("apps/docgen.py", "_actions"),
                     ("apps/docgen.py", "_SubParsersAction"), ("apps/warm.py", "_cache"),
                     # numba's cache file methods, wrapped to check each file's digest
                     *(("jit_cache.py", n) for n in ("_save_data", "_load_index",
                                                     "_load_data", "_allsky_heals")),
                     ("jit_cache.py", "_CacheLocator"), ("jit_cache.py", "_CacheImpl"),
                     ("jit_cache.py", "_locator_classes"), ("compiles.py", "_cache")}
#: A module's own classes working together: the scenario reads its sections' values, the
#: jit decorators make their own compiled functions.
SAME_MODULE = {("config/scenario.py", "_values"), ("jit.py", "_make"),
               ("apps/comparison.py", "_headline_result")}


def test_no_module_touches_another_object_s_private_fields():
    """``x._name`` only on ``self``, ``cls`` or ``other`` of the same class (equality)."""
    found = []
    for path in sorted(SRC.rglob("*.py")):
        where = str(path.relative_to(SRC))
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.Attribute) and node.attr.startswith("_") \
                    and not node.attr.startswith("__") and isinstance(node.value, ast.Name) \
                    and node.value.id not in ("self", "cls", "other") \
                    and node.attr not in NAMED_TUPLE_API \
                    and (where, node.attr) not in LIBRARY_INTERNALS | SAME_MODULE:
                found.append(f"{where}:{node.lineno} {node.value.id}.{node.attr}")
    assert not found, found
