"""Cross-references of the API reference, resolved by Python's own rules.

Docstrings name objects as a reader of their module would:
``:func:`njit``` inside :mod:`allsky.jit`, ``:meth:`Mission.summary```,
``:data:`allsky.sim.telemetry.COLUMNS``` (an object imported there from
:mod:`allsky.sim.recorder`). The Python domain places only the names it
documented, under their own modules. :func:`resolve` looks up each one it
could not place as Python would (import the module, follow the attributes)
and links it to where that object is documented. A reference to an object
that exists but is not in the reference (a private helper) is shown as
code, without a link; a reference to nothing -- a name that no longer
exists, a module misnamed -- stays a warning, an error under ``-W``.
"""

import importlib
import re

from docutils import nodes

#: The documented object in a docstring's source name ("...:docstring of NAME").
_SOURCE = re.compile(r"docstring of ([\w.]+)")


def _lookup(dotted):
    """The object a dotted name names, importing its module; None if nothing."""
    parts = dotted.split(".")
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ImportError:
            continue
        except Exception:  # noqa: BLE001 - a module that fails to import names nothing
            return None
        try:
            for attr in parts[i:]:
                obj = getattr(obj, attr)
        except AttributeError:
            return None
        return obj
    return None


def _same(a, b) -> bool:
    """The same object, or the same compiled function (dispatcher or wrapper)."""
    if a is b:
        return True
    func = getattr(a, "py_func", None)
    return func is not None and func is getattr(b, "py_func", b)


def _documented(domain, target, obj):
    """The documented name of ``obj`` (named ``target`` where it was referred to)."""
    last = target.rsplit(".", 1)[-1]
    found = [name for name in domain.objects
             if name.rsplit(".", 1)[-1] == last and _same(_lookup(name), obj)]
    home = getattr(obj, "__module__", None)
    canonical = [n for n in found if home and n.startswith(home + ".")]
    return (canonical or found or [None])[0]


def _contexts(node):
    """Where a reference's name is looked up: its class, its module, the object's home.

    An object documented under another name (``allsky.Mission`` for
    :class:`allsky.sim.mission.Mission`) carries that name's module as its
    context; its docstring was written in its own module, where its names are.
    """
    module, klass = node.get("py:module"), node.get("py:class")
    out = [f"{module}.{klass}"] if module and klass else []
    out += [module] if module else []
    documented = _SOURCE.search(node.source or "")
    owner = _lookup(f"{module}.{klass}") if module and klass else (
        _lookup(documented.group(1)) if documented else None)
    home = getattr(owner, "__module__", None)
    if home:
        out += ([f"{home}.{klass}"] if klass else []) + [home]
    return [*dict.fromkeys(out), ""]


def resolve(app, env, node, contnode):
    """Place a Python reference the domain could not (``missing-reference``)."""
    if node.get("refdomain") != "py":
        return None
    target = node["reftarget"].lstrip(".~")
    obj = None
    for base in _contexts(node):
        obj = _lookup(f"{base}.{target}" if base else target)
        if obj is not None:
            break
    domain = env.get_domain("py")
    if obj is None:  # as the domain's own fuzzy search: documented names ending so
        ends = [n for n in domain.objects if n.endswith("." + target)]
        objs = [_lookup(n) for n in ends]
        if ends and all(_same(o, objs[0]) for o in objs):
            obj = objs[0]
    name = _documented(domain, target, obj) if obj is not None else None
    if name is not None:
        ref = domain.resolve_xref(env, node["refdoc"], app.builder, "obj", name, node,
                                  contnode)
        if ref is not None:
            return ref
    if obj is not None:  # it exists but is not in the reference: shown as code, unlinked
        return nodes.literal(contnode.astext(), contnode.astext())
    return None


def setup(app):
    """Connect the resolver."""
    app.connect("missing-reference", resolve)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
