"""numba's on-disk cache for allsky's compiled functions, keyed by their sources.

:func:`install` puts :class:`PackageCacheLocator` first among numba's cache
locators; :func:`allsky.jit.load_numba` calls it before it makes any
compiled function.
"""

import os

import numba
from numba.core import caching

from allsky.sources import PACKAGE_DIR, source_stamp


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


def install():
    """Put :class:`PackageCacheLocator` first among numba's cache locators (once)."""
    impl = getattr(caching, "CacheImpl", None) or caching._CacheImpl
    if PackageCacheLocator not in impl._locator_classes:
        impl._locator_classes.insert(0, PackageCacheLocator)
