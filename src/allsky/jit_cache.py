"""numba's on-disk cache for allsky's compiled functions, keyed by their sources.

:func:`install` puts :class:`PackageCacheLocator` first among numba's cache
locators; :func:`allsky.jit.load_numba` calls it before it makes any
compiled function.

The locator builds on two private parts of numba (``caching._CacheLocator``
and the ``_locator_classes`` table of its cache implementation), which a
numba release may rename. Where either is missing, or the locator no longer
fits numba's protocol, nothing of it is used: :func:`install` says so in one
warning and every function is cached by numba's own locators, keyed by its
own file (correct for an installed package; in a source tree, an edited block
in another file then needs ``__pycache__`` cleared). Compiled calls never
depend on it.
"""

import inspect
import os
import warnings

import numba

from allsky.sources import PACKAGE_DIR, source_stamp

try:
    from numba.core import caching

    _BASE = caching._CacheLocator
    _IMPL = getattr(caching, "CacheImpl", None) or caching._CacheImpl
    if not isinstance(_IMPL._locator_classes, list):
        raise TypeError("numba's cache locators are not a list")
    #: Why the package's locator cannot be used with this numba (None: it can).
    UNAVAILABLE = None
except (ImportError, AttributeError, TypeError) as e:
    _BASE, _IMPL = object, None
    UNAVAILABLE = f"{type(e).__name__}: {e}"


class PackageCacheLocator(_BASE):
    """numba's on-disk cache for allsky's compiled functions.

    The cache lives where numba would put it: under ``NUMBA_CACHE_DIR`` when
    that is set, else in ``__pycache__`` beside the source (where an install
    ships the compiled loop), else, if that cannot be written, in the user's
    cache directory. The stamp is :func:`source_stamp`. Functions outside the
    package are left to numba's own locators.

    Make it with :meth:`from_function`; numba does. ``py_func`` is the
    Python function compiled, ``py_file`` the absolute path of its source
    file and ``cache_path`` the directory chosen for its cache files.
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


#: What numba asks of a locator (the methods :class:`PackageCacheLocator` relies on).
PROTOCOL = ("ensure_cache_path", "get_cache_path", "get_source_stamp", "get_disambiguator",
            "from_function", "get_suitable_cache_subpath")


def unavailable_reason():
    """Why :class:`PackageCacheLocator` cannot serve this numba, or None when it can."""
    if UNAVAILABLE is not None:
        return UNAVAILABLE
    missing = [m for m in PROTOCOL if not callable(getattr(PackageCacheLocator, m, None))]
    if missing:
        return f"numba's cache locator has no {missing[0]}"
    if inspect.isabstract(PackageCacheLocator):
        return ("numba's cache locator asks for "
                f"{', '.join(sorted(PackageCacheLocator.__abstractmethods__))}")
    return None


_warned = []


def install() -> bool:
    """Put :class:`PackageCacheLocator` first among numba's cache locators (once).

    Returns whether it is in place. When this numba has no room for it
    (:func:`unavailable_reason`), one warning says so and numba's own locators
    cache every function.
    """
    why = unavailable_reason()
    if why is not None:
        if not _warned:
            _warned.append(why)
            warnings.warn(f"allsky: numba {numba.__version__} does not take allsky's cache "
                          f"locator ({why}); compiled functions are cached by numba's own, "
                          "keyed by their own file", RuntimeWarning, stacklevel=2)
        return False
    if PackageCacheLocator not in _IMPL._locator_classes:
        _IMPL._locator_classes.insert(0, PackageCacheLocator)
    return True
