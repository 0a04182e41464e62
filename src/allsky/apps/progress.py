"""A live progress line for a mission flown from the command line.

The line (tqdm, on stderr) counts modes and shows the mode under way and the
mission time; it is refreshed every ``PROGRESS_EVERY_S`` of mission time by
pausing the frame loop, which does not change the flight (legs resume
exactly), and after each slice of the frame loop
(:data:`allsky.sim.mission.SLICE_FRAMES`), so that it moves even when a
frame is very short. It is silent when asked to be, or when stderr is not a
terminal. The first line says the frame loop is being compiled only when it
is (:func:`frame_loop_needs_compiling`).
"""

import sys

from tqdm import tqdm

from allsky.sequencer.modes import MODE_TITLE

PROGRESS_EVERY_S = 20.0  #: [s] of mission time between refreshes


def frame_loop_needs_compiling(params=None) -> bool:
    """Whether the first leg flown in this process will compile the frame loop.

    ``params`` picks the loop (:func:`allsky.sim.frame_loop.leg_entry`); by
    default the patent's vehicle without faults.

    False when the loop is already compiled in this process, runs as plain
    Python (``NUMBA_DISABLE_JIT=1``), or numba's on-disk cache holds an entry
    for the current source (its index file, read the way numba reads it:
    an index of another source or numba version counts as empty).
    """
    from allsky.sim import frame_loop

    run_leg = frame_loop._run_leg_jets if params is None else frame_loop.leg_entry(params)
    if not hasattr(run_leg, "signatures") or run_leg.signatures:
        return False
    try:
        return not run_leg._cache._cache_file._load_index()
    except Exception:  # noqa: BLE001 - numba internals moved: assume a compile, say so
        return True


def fly(m, quiet=False, stream=None):
    """Fly the remaining modes of ``m`` with a progress line; return its summary."""
    stream = stream or sys.stderr
    disable = True if quiet else (None if stream is sys.stderr else False)
    with tqdm(total=len(m.plan), initial=m.next_mode, unit="mode", file=stream,
              disable=disable, leave=False, dynamic_ncols=True,
              bar_format="{desc} |{bar}| {n_fmt}/{total_fmt} modes [{elapsed}]") as bar:
        if bar.disable:
            return m.run()

        def describe(first_use=False):
            name = m.plan[m.next_mode]
            note = " (compiling the frame loop on first use)" if first_use else ""
            bar.set_description_str(f"Mode {name} {MODE_TITLE[name]}, "
                                    f"t = {m.state.time_s[0]:.0f} s{note}")

        m.pause_every_s = PROGRESS_EVERY_S
        m.on_pause = m.on_slice = lambda mm, what: describe()
        try:
            first = frame_loop_needs_compiling(m.params)
            while not m.finished:
                describe(first_use=first)
                first = False
                m.run_mode()
                bar.update(1)
        finally:
            m.pause_every_s = None
            m.on_pause = m.on_slice = None
    return m.summary()
