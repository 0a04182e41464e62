"""The compiled frame loop: compiled once per machine, then loaded from the cache.

The first mission on a machine compiles the frame loop (about 15-18 s of CPU
on two cores); every later process loads it from numba's on-disk cache
(``cache=True``, :mod:`allsky.jit`): next to the sources, or under
``NUMBA_CACHE_DIR`` when that is set. :func:`needs_compiling` tells, before
anything runs, whether the next mission of this process will compile;
:func:`warm_up` compiles (or loads) everything a mission calls, holding a
lock (:func:`allsky.compiles.compile_lock`) while it compiles, so that processes starting
together on one machine (local workers, Dask workers sharing a cache
directory) compile once and the others load the result.
"""

from allsky import compiles

#: [s] How long compiling takes on the project's 2-core machine, measured with an empty
#: cache (CPU time of one process, which is its wall time on an idle machine;
#: docs/design.md): the plain loop on first use, both loops in ``allsky warm-up``, and the
#: build's step (the two loops side by side, one a core, the plain one then built ahead of
#: time). Every message and page that gives a compile time says these (a test checks).
COMPILE_S = {"first use": 12, "warm-up": 25, "build": 20}


def entry_points(params=None) -> tuple:
    """The compiled functions a mission calls from Python (the loop, the pointing).

    ``params`` picks the loop (:func:`allsky.sim.frame_loop.leg_entry`); by
    default the patent's vehicle without faults, the one a default mission flies.
    """
    from allsky.sim import frame_loop
    from allsky.vehicle import quaternion

    loop = frame_loop.entries()["plain"] if params is None else frame_loop.leg_entry(params)
    return loop, quaternion.dcm_body_from_inertial


def needs_compiling(dispatchers=None) -> bool:
    """Whether calling ``dispatchers`` (default :func:`entry_points`) will compile.

    See :func:`allsky.compiles.needs_compiling`.
    """
    return compiles.needs_compiling(entry_points() if dispatchers is None else dispatchers)


def compile_once(fly, dispatchers=None) -> bool:
    """Call ``fly()``, which calls ``dispatchers``: they compile once per machine.

    When something needs compiling, ``fly`` runs under :func:`allsky.compiles.compile_lock`;
    a process that waited for the lock then finds the cache written and loads
    it. Returns whether this process compiled (numba's cache misses).
    """
    ds = entry_points() if dispatchers is None else tuple(dispatchers)
    misses = _misses(ds)
    if needs_compiling(ds):
        with compiles.compile_lock(ds[0]):
            fly()
    else:
        fly()
    return _misses(ds) > misses


def _misses(dispatchers) -> int:
    return sum(sum(getattr(d, "stats", None).cache_misses.values())
               for d in dispatchers if getattr(d, "stats", None) is not None)


#: The loops :func:`warm_up` can compile: the patent's vehicle without faults (every
#: default command), and the general one (reaction wheels, faults, the historical
#: scenarios).
LOOPS = ("plain", "any")


def loop_entries(loops=LOOPS) -> tuple:
    """The compiled entries of ``loops`` (names of :data:`LOOPS`)."""
    from allsky.sim import frame_loop

    entries = frame_loop.entries()
    return tuple(entries[loop] for loop in loops)


def _mission_for(loop: str):
    from allsky.config.scenario import load_scenario
    from allsky.sim.mission import Mission

    if loop == "plain":
        return Mission(load_scenario(), telemetry=True)
    if loop == "any":
        return Mission(load_scenario(overrides=['actuators.kind="wheels"']), telemetry=True)
    raise ValueError(f"unknown loop {loop!r}: one of {', '.join(LOOPS)}")


def warm_up(loops=("plain",), lock=True) -> bool:
    """Compile, or load from the cache, what a mission needs; True if it compiled.

    Flies one short mission per loop of ``loops`` (:data:`LOOPS`; about 0.1 s
    each once compiled). The plain loop has one compiled form for every plan
    and scenario on the jets without faults, so it covers ``allsky run``,
    ``step``, ``compare`` and ``montecarlo``; ``"any"`` adds the wheels and the
    faults. With ``lock`` a loop that needs compiling compiles under the
    machine's lock (:func:`compile_once`); ``lock=False`` compiles without it
    (a build compiling the loops side by side).
    """
    from allsky.jit import load_numba
    from allsky.sim import frame_loop

    load_numba()  # the just-in-time loops, even where the install built them ahead of time
    compiled = False
    for loop in loops:
        m = _mission_for(loop)
        entry = frame_loop.leg_entry(m.params)
        ds = (entry,) + entry_points()[1:]

        def fly(m=m):
            m.run()
            m.summary()

        if lock:
            compiled |= compile_once(fly, ds)
        else:
            misses = _misses(ds)
            fly()
            compiled |= _misses(ds) > misses
    return compiled
