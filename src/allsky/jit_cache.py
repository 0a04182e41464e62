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

import hashlib
import inspect
import os
import pickle
import sys
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


#: Suffix of a damaged cache file set aside (kept for a look, never read again).
SET_ASIDE = ".damaged"
#: Suffix of the file beside each cache data file holding its size and sha256.
DIGEST = ".sha256"


def cache_digest(path) -> str:
    """What a cache file at ``path`` is checked by: its size and sha256, in one line."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return f"{os.path.getsize(path)} {h.hexdigest()}"


def set_aside(path, why) -> None:
    """Move the damaged cache file ``path`` aside; one line on stderr says ``why``."""
    try:
        os.replace(path, path + SET_ASIDE)
        where = f"set aside as {os.path.basename(path)}{SET_ASIDE}"
    except OSError:
        try:
            os.unlink(path)
            where = "removed"
        except OSError:
            where = "left in place (not writable), bypassed"
    for extra in (path + DIGEST,):
        try:
            os.unlink(extra)
        except OSError:
            pass
    print(f"allsky: note: numba's cache file {path} is damaged ({why}); {where}, compiling "
          "it again (the same code)", file=sys.stderr)


def _healing(cache_file_class):
    """Make numba's index/data cache files validated before use, and healed when bad.

    The index (``.nbi``) and data (``.nbc``) files are pickles; random bytes or a
    truncation made numba raise (``UnpicklingError``) on every later run. A
    data file's size and sha256 are written beside it when it is saved and
    checked when it is loaded; a file that fails either way, or does not
    unpickle, is set aside (:func:`set_aside`) and compiled again.
    """
    if getattr(cache_file_class, "_allsky_heals", False):
        return
    load_index, load_data = cache_file_class._load_index, cache_file_class._load_data
    save_data = cache_file_class._save_data

    def _load_index(self):
        try:
            return load_index(self)
        except (pickle.UnpicklingError, EOFError, ValueError, TypeError, AttributeError,
                ImportError, IndexError, KeyError, MemoryError) as e:
            set_aside(self._index_path, type(e).__name__)
            return {}

    def _load_data(self, name):
        path = self._data_path(name)
        try:
            with open(path + DIGEST, encoding="ascii") as f:
                want = f.read().strip()
        except OSError:
            want = None
        if want is not None and os.path.exists(path) and cache_digest(path) != want:
            set_aside(path, "its size or sha256 is not what was saved")
            raise OSError(f"{path}: damaged")
        try:
            return load_data(self, name)
        except OSError:
            raise
        except Exception as e:  # noqa: BLE001 - a damaged pickle fails in many ways
            set_aside(path, type(e).__name__)
            raise OSError(f"{path}: damaged") from None

    def _save_data(self, name, data):
        save_data(self, name, data)
        path = self._data_path(name)
        try:
            with open(path + DIGEST, "w", encoding="ascii") as f:
                f.write(cache_digest(path) + "\n")
        except OSError:  # not writable: the data file is still checked by unpickling
            pass

    cache_file_class._load_index = _load_index
    cache_file_class._load_data = _load_data
    cache_file_class._save_data = _save_data
    cache_file_class._allsky_heals = True


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
    cache_file = getattr(caching, "IndexDataCacheFile", None)
    if cache_file is not None and all(hasattr(cache_file, m) for m in (
            "_load_index", "_load_data", "_save_data", "_data_path")):
        _healing(cache_file)
    return True
