"""allsky's own sources: what each module imports, and a key for its compiled code.

Read at start-up (a few milliseconds, without numba): :func:`source_stamp`
keys numba's on-disk cache (:mod:`allsky.jit_cache`) and the loop compiled
ahead of time (:mod:`allsky.aot`).
"""

import functools
import hashlib
import os
import re

#: The allsky package directory.
PACKAGE_DIR = os.path.dirname(os.path.abspath(__file__))
_IMPORT = re.compile(r"^[ \t]*(?:from[ \t]+(allsky(?:\.\w+)*)[ \t]+import[ \t]+(\([^)]*\)|.*)"
                     r"|import[ \t]+(allsky(?:\.\w+)*))", re.MULTILINE)


@functools.cache
def _module_file(name: str):
    """The source file of allsky module ``name`` (a package's ``__init__.py``), or None."""
    base = os.path.join(os.path.dirname(PACKAGE_DIR), *name.split("."))
    for path in (base + ".py", os.path.join(base, "__init__.py")):
        if os.path.isfile(path):
            return path
    return None


@functools.cache
def _read_module(path: str) -> tuple:
    """(SHA-256 of the file, the allsky source files its imports run)."""
    with open(path, "rb") as f:
        data = f.read()
    deps = set()
    for package, names, module in _IMPORT.findall(data.decode("utf-8")):
        found = [module] if module else [package] + [
            f"{package}.{n}" for n in re.findall(r"\w+", names)]
        for name in found:
            # "allsky.a.b" also runs allsky/__init__.py and allsky/a/__init__.py
            parts = name.split(".")
            for k in range(1, len(parts) + 1):
                dep = _module_file(".".join(parts[:k]))
                if dep is not None:
                    deps.add(dep)
    return hashlib.sha256(data).hexdigest(), tuple(sorted(deps))


def source_closure(py_file: str) -> tuple:
    """``py_file`` and the allsky source files it reaches through imports, sorted."""
    seen, todo = set(), [os.path.abspath(py_file)]
    while todo:
        path = todo.pop()
        if path not in seen:
            seen.add(path)
            todo.extend(_read_module(path)[1])
    return tuple(sorted(seen))


@functools.cache
def source_stamp(py_file: str) -> str:
    """What a compiled function of ``py_file`` is valid for: sources, NumPy version.

    A SHA-256 over the contents of :func:`source_closure` (paths relative to
    the package, so an installed copy matches the tree it was built from) and
    NumPy's major.minor version, which decides numba's type promotion rules.
    numba's own version is checked by numba.
    """
    import numpy

    h = hashlib.sha256(".".join(numpy.__version__.split(".")[:2]).encode())
    for path in source_closure(py_file):
        rel = os.path.relpath(path, PACKAGE_DIR).replace(os.sep, "/")
        h.update(f"{rel}\0{_read_module(path)[0]}\n".encode())
    return h.hexdigest()
