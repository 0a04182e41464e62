"""The one place that decides how blocks are compiled.

Every per-frame block is a small function decorated with :func:`njit`.
``NUMBA_DISABLE_JIT=1`` turns them back into plain Python with identical
results, for stepping through with a debugger.

:func:`njit` compiles *without numba's reference-counted runtime*: arrays
are borrowed from the caller and nothing is allocated, so a per-frame block
that tried to allocate an array would not compile. This is also what makes
the loop fast: with the runtime on, each array handed to a block (and each
array field read from a parameter or state tuple) costs an atomic
reference-count increment and decrement, dozens a frame, which took about
40 % of the frame time (docs/design.md).

:func:`njit_stage` is :func:`njit` for the stages of the frame loop
(:mod:`allsky.sim.frame_loop`) and the helpers only they call, which numba
inlines into the loop itself. A stage is too large for LLVM to inline;
called every frame as a function of its own, with its arguments passed
word by word (seven words an array), the stages made the default mission
take 1.7 times as long (62 ms against 36 ms), and compiling each one's own
entry point added to the cold start.

:func:`njit_alloc` keeps the runtime, for the few compiled helpers that
return new arrays (outside the frame loop, or once per leg).

Compiled code is cached on disk by :class:`PackageCacheLocator`, which keys
each function by the sources of every allsky module its module reaches
through imports (numba's own locators key it by its own file only, so an
edited block in another file would leave a stale compiled loop behind).
"""

import functools
import hashlib
import os
import re

import numba
from numba.core import caching

#: The allsky package directory.
PACKAGE_DIR = os.path.dirname(os.path.abspath(__file__))
_IMPORT = re.compile(r"^[ \t]*(?:from[ \t]+(allsky(?:\.\w+)*)[ \t]+import[ \t]+(\([^)]*\)|.*)"
                     r"|import[ \t]+(allsky(?:\.\w+)*))", re.M)


@functools.lru_cache(maxsize=None)
def _module_file(name: str):
    """The source file of allsky module ``name`` (a package's ``__init__.py``), or None."""
    base = os.path.join(os.path.dirname(PACKAGE_DIR), *name.split("."))
    for path in (base + ".py", os.path.join(base, "__init__.py")):
        if os.path.isfile(path):
            return path
    return None


@functools.lru_cache(maxsize=None)
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


@functools.lru_cache(maxsize=None)
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


class PackageCacheLocator(caching._CacheLocator):
    """numba's on-disk cache for allsky's compiled functions.

    The cache lives where numba would put it: under ``NUMBA_CACHE_DIR`` when
    that is set, else in ``__pycache__`` beside the source (where an install
    ships the compiled loop), else, if that cannot be written, in the user's
    cache directory. The stamp is :func:`source_stamp`. Functions outside the
    package are left to numba's own locators.
    """

    def __init__(self, py_func, py_file, cache_path):
        self._py_file = py_file
        self._lineno = py_func.__code__.co_firstlineno
        self._cache_path = cache_path

    def get_cache_path(self):
        """The directory of this function's cache files."""
        return self._cache_path

    def get_source_stamp(self):
        """The key the cache index is valid for (:func:`source_stamp`)."""
        return source_stamp(self._py_file)

    def get_disambiguator(self):
        """The function's first line: tells apart functions of one name in a file."""
        return str(self._lineno)

    @classmethod
    def from_function(cls, py_func, py_file):
        """A locator for ``py_func`` of allsky's ``py_file``; None outside the package."""
        py_file = os.path.abspath(py_file)
        if not (py_file.startswith(PACKAGE_DIR + os.sep) and os.path.isfile(py_file)):
            return None
        sub = cls.get_suitable_cache_subpath(py_file)
        if numba.config.CACHE_DIR:
            places = [os.path.join(numba.config.CACHE_DIR, sub)]
        else:
            from numba.misc.appdirs import AppDirs

            places = [os.path.join(os.path.dirname(py_file), "__pycache__"),
                      os.path.join(AppDirs(appname="numba", appauthor=False).user_cache_dir,
                                   sub)]
        for place in places:
            self = cls(py_func, py_file, place)
            try:
                self.ensure_cache_path()
            except OSError:  # not writable: the next place
                continue
            return self
        return None


_CACHE_IMPL = getattr(caching, "CacheImpl", None) or caching._CacheImpl
if PackageCacheLocator not in _CACHE_IMPL._locator_classes:
    _CACHE_IMPL._locator_classes.insert(0, PackageCacheLocator)

# cache=True keeps compiled code between processes (Monte Carlo workers,
# repeated CLI runs); fastmath stays off so that the plain-Python path gives
# the same bits.
njit = numba.njit(cache=True, nogil=True, _nrt=False)
njit_stage = numba.njit(cache=True, nogil=True, _nrt=False, inline="always")
njit_alloc = numba.njit(cache=True, nogil=True)
