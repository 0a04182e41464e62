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

:func:`njit_noalias` is :func:`njit` with every array argument declared
not to alias any other (LLVM's ``noalias``), for the frame loop itself
(:func:`allsky.sim.frame_loop._run_frames`): the compiler may then keep a
value read from one array in a register across a store to another, and
reorder them. Its callers must hand it arrays that do not overlap (except
read-only ones): the parameters, the state's arrays and the work arrays are
each allocated apart. The results are the same bits (no arithmetic is
changed); the default mission took 2 % less time.

:func:`njit_alloc` keeps the runtime, for the few compiled helpers that
return new arrays (outside the frame loop, or once per leg).

The decorators do not import numba: they return a :class:`CompiledFunction`
that imports numba, and makes every compiled function of the package, the
first time one of them is called or inspected. A command that never calls
compiled code from Python (``config``, ``--help``), or calls only what was
built ahead of time at install (:mod:`allsky.aot`: a mission on the
patent's vehicle without faults), runs without numba.

Compiled code is cached on disk by :class:`allsky.jit_cache.PackageCacheLocator`,
which keys each function by :func:`allsky.sources.source_stamp`: the sources of every allsky
module its module reaches through imports (numba's own locators key it by
its own file only, so an edited block in another file would leave a stale
compiled loop behind).
"""

import functools
import sys
import threading
import warnings

from allsky import aot

#: numba, once a compiled function has been used (None before).
_numba = None
#: Every CompiledFunction made before numba was loaded.
_waiting = []
#: Every :func:`jitable` function declared before numba was loaded.
_jitable_waiting = []
_loading = threading.RLock()


def load_numba():
    """Import numba and make every compiled function waiting for it; return numba.

    The module attributes of the package that hold a :class:`CompiledFunction`
    are replaced by its numba dispatcher, so that numba, compiling a function,
    finds dispatchers (not wrappers) among its globals.
    """
    global _numba
    if _numba is not None:
        return _numba
    with _loading:  # threads (a Dask worker's) starting together make each function once
        if _numba is None:
            import numba

            try:  # the cache's key is an optimisation: compiled calls never depend on it
                from allsky import jit_cache

                jit_cache.install()
            except Exception as e:  # noqa: BLE001 - any failure leaves numba's own cache
                warnings.warn(f"allsky: the package's cache locator failed ({type(e).__name__}"
                              f": {e}); compiled functions are cached by numba's own",
                              RuntimeWarning, stacklevel=2)
            for f in _jitable_waiting:  # before anything compiles that calls them
                _register_jitable(numba, f)
            _jitable_waiting.clear()
            for f in _waiting:
                f._make(numba)
            _waiting.clear()
            for name, module in list(sys.modules.items()):
                if module is not None and (name == "allsky" or name.startswith("allsky.")):
                    for attr, value in list(vars(module).items()):
                        if isinstance(value, CompiledFunction):
                            setattr(module, attr, value._make(numba))
            _numba = numba
    return _numba


class CompiledFunction:
    """A function numba compiles, made when first used (numba is imported then).

    Calling it, or reading any attribute of numba's dispatcher from it
    (``signatures``, ``targetoptions``, ``stats``...), loads numba
    (:func:`load_numba`); ``py_func`` is the Python function itself and
    ``options`` the keywords numba's ``njit`` gets for it (``cache``,
    ``nogil``, ``inline`` ...).
    """

    def __init__(self, py_func, options):
        self.py_func = py_func
        self._options = options
        self._dispatcher = None
        self.qualified = f"{py_func.__module__}.{py_func.__qualname__}"
        functools.update_wrapper(self, py_func)

    def _make(self, numba):
        if self._dispatcher is None:
            self._dispatcher = _njit(numba, self._options, self.py_func)
        return self._dispatcher

    @property
    def dispatcher(self):
        """numba's dispatcher of this function (numba is loaded for it)."""
        return self._make(load_numba())

    def __call__(self, *args, **kwargs):
        """Call the compiled function: built ahead of time if it can be (:mod:`allsky.aot`)."""
        if _numba is None and not kwargs:
            ahead = aot.entry(self.qualified, args)
            if ahead is not None:
                return ahead(*args)
        return self.dispatcher(*args, **kwargs)

    def ahead_of_time(self) -> bool:
        """Whether calls can go to the function built ahead of time (numba not loaded)."""
        return _numba is None and aot.available() and self.qualified in aot.EXPORTS

    def __getattr__(self, name):
        # Not for its own attributes: an instance not yet initialised (a copy being made)
        # must not recurse into self.dispatcher.
        if name.startswith("__") or name in ("_dispatcher", "_options", "py_func", "qualified"):
            raise AttributeError(name)
        return getattr(self.dispatcher, name)

    def __repr__(self):
        return f"<compiled function {self.__qualname__} (numba loads on first use)>"


def jitable(py_func=None, *, inline=False):
    """A plain Python function ``py_func`` that compiled code may call as if compiled.

    The function stays what it is: Python calls it as Python, without
    loading numba (the exact arithmetic of :mod:`allsky.xmath`, called while
    a scenario is built). Once numba is loaded it is registered with numba
    (``numba.extending.register_jitable``), so that compiled functions that
    call it compile its body into their own code, with the same arithmetic
    and therefore the same bits.

    With ``inline`` true (``@jitable(inline=True)``) numba puts the
    function's body into each caller's before LLVM sees it (numba's
    ``inline="always"``), where LLVM would keep a call: for a small function
    on the frame's critical path (:func:`allsky.xmath._atan01`, whose pair
    of results a call returns through memory). Inlining changes no
    operation, so the bits stay the same; it costs compile time at every
    call site. A function inlined so must not assign one variable on two
    paths (numba's inliner warns of it).
    """
    if py_func is None:
        return functools.partial(jitable, inline=inline)
    if inline:
        _inlined.add(py_func)
    if _numba is not None:
        _register_jitable(_numba, py_func)
    else:
        _jitable_waiting.append(py_func)
    return py_func


#: The :func:`jitable` functions numba inlines into their callers.
_inlined = set()


def _register_jitable(numba, py_func):
    from numba.extending import register_jitable

    if py_func in _inlined:
        register_jitable(inline="always")(py_func)
    else:
        register_jitable(py_func)


def _njit(numba, options, py_func):
    """numba's dispatcher of ``py_func`` compiled with ``options`` (``noalias`` among them)."""
    options = dict(options)
    if options.pop("noalias", False):
        options["pipeline_class"] = _noalias_compiler()
    return numba.njit(**options)(py_func)


@functools.cache
def _noalias_compiler():
    """numba's compiler, with every array argument of the function declared not to alias."""
    from numba.core import compiler

    class NoAliasCompiler(compiler.Compiler):
        def __init__(self, typingctx, targetctx, library, args, return_type, flags, locals):
            flags = flags.copy()
            flags.noalias = True
            super().__init__(typingctx, targetctx, library, args, return_type, flags, locals)

    return NoAliasCompiler


def _decorator(**options):
    def decorate(py_func):
        if _numba is not None:
            return _njit(_numba, options, py_func)
        f = CompiledFunction(py_func, options)
        _waiting.append(f)
        return f

    return decorate


# cache=True keeps compiled code between processes (Monte Carlo workers,
# repeated CLI runs); fastmath stays off so that the plain-Python path gives
# the same bits.
njit = _decorator(cache=True, nogil=True, _nrt=False)
njit_stage = _decorator(cache=True, nogil=True, _nrt=False, inline="always")
njit_alloc = _decorator(cache=True, nogil=True)
njit_noalias = _decorator(cache=True, nogil=True, _nrt=False, noalias=True)
