"""Compiling the frame loop: when it is due, the machine's lock, who hears of it.

A process about to compile an entry (nothing of it in numba's cache,
:func:`needs_compiling`) compiles inside :func:`compiling`: the callbacks of
:data:`ON_COMPILE` hear it start and end (a pool's worker tells its parent,
which then knows the worker is not yet flying), and the compile holds the
machine's lock (:func:`compile_lock`), so that processes starting together
compile once and the others load the cache. Nothing here imports numba.
"""

import contextlib

#: Compile locks this process holds, by (thread, source file): a lock taken again inside
#: its own block (a warm-up's mission compiling its loop) is the one already held, since a
#: second ``flock`` of the same file from this process would wait for itself.
_held = {}
#: Called as ``f(True)`` before this process compiles a frame-loop entry (or waits for
#: another process's compile of it), ``f(False)`` after: a pool's worker tells its parent,
#: which ends a compiling worker at once on Ctrl-C (:mod:`allsky.studies.pool`).
ON_COMPILE = []


def needs_compiling(dispatchers) -> bool:
    """Whether calling ``dispatchers`` (compiled functions) will compile.

    False when each is built ahead of time (:mod:`allsky.aot`), loaded in
    this process already, runs as plain Python (``NUMBA_DISABLE_JIT=1``), or
    has entries in numba's on-disk cache index for its current source (read
    the way numba reads it: an index of another source or numba version
    counts as empty).
    """
    from allsky.jit import CompiledFunction

    for d in dispatchers:
        if isinstance(d, CompiledFunction) and d.ahead_of_time():
            continue  # built at install (allsky.aot): nothing to load or compile
        if not hasattr(d, "signatures") or d.signatures:
            continue
        try:
            if not d._cache._cache_file._load_index():
                return True
        except Exception:  # noqa: BLE001 - numba internals moved: assume a compile
            return True
    return False


@contextlib.contextmanager
def compile_lock(dispatcher):
    """Hold the machine's compile lock for ``dispatcher`` inside the block.

    The lock is an ``flock`` on the dispatcher's source file, opened for
    reading: every process on the machine that runs this installation shares
    it, whatever cache directory each one uses, and nothing is written.
    Where the platform has no ``fcntl`` (Windows) or the file cannot be
    opened, the block runs without a lock: a second process may then
    compile too, which costs time, never results. Inside a block that holds
    it already (the same thread), the lock is not taken again.
    """
    import _thread

    try:
        import fcntl
    except ImportError:
        fcntl = None
    source = getattr(getattr(dispatcher, "py_func", dispatcher), "__code__", None)
    key = (_thread.get_ident(), getattr(source, "co_filename", None))
    if key in _held:
        _held[key] += 1
        try:
            yield
        finally:
            _held[key] -= 1
        return
    handle = None
    if fcntl is not None and source is not None:
        try:
            handle = open(source.co_filename, "rb")  # noqa: SIM115 - held across the yield
            fcntl.flock(handle.fileno(), fcntl.LOCK_EX)
        except OSError:
            if handle is not None:
                handle.close()
            handle = None
    _held[key] = 1
    try:
        yield
    finally:
        del _held[key]
        if handle is not None:
            fcntl.flock(handle.fileno(), fcntl.LOCK_UN)
            handle.close()


@contextlib.contextmanager
def compiling(dispatcher):
    """Compile ``dispatcher`` inside the block: told to :data:`ON_COMPILE`, locked.

    :func:`allsky.sim.frame_loop.run_leg` flies a leg whose loop is not yet
    compiled (nor in the cache) inside it: the callbacks hear that this
    process is compiling (which may take a minute, or wait for another
    process's compile) and, after, that it is done; the compile holds the
    machine's lock (:func:`compile_lock`).
    """
    for f in ON_COMPILE:
        f(True)
    try:
        with compile_lock(dispatcher):
            yield
    finally:
        for f in ON_COMPILE:
            f(False)
