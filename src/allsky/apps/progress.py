"""A live progress line for a mission flown from the command line.

The line (tqdm, on stderr) counts modes and shows the mode under way and the
mission time; it is refreshed every ``PROGRESS_EVERY_S`` of mission time by
pausing the frame loop, which does not change the flight (legs resume
exactly), and after each slice of the frame loop
(:data:`allsky.sim.mission.SLICE_FRAMES`), so that it moves even when a
frame is very short. It is silent when asked to be, or when stderr is not a
terminal. Only when the frame loop is about to be compiled
(:func:`frame_loop_needs_compiling`), and unless quiet, one note says so on
stderr: in the line itself on a terminal, as a line of its own otherwise.
A terminal that reports a size of zero (some containers and CI runners)
gets an 80-column line rather than none.
"""

import os
import sys

from allsky.sequencer.modes import MODE_TITLE

PROGRESS_EVERY_S = 20.0  #: [s] of mission time between refreshes
#: [columns, lines] the terminal size assumed where it reports zero (tqdm would hide the line)
FALLBACK_SIZE = (80, 24)
#: The note shown while the frame loop compiles.
COMPILE_NOTE = "compiling the frame loop on first use, once"


def frame_loop_needs_compiling(params=None) -> bool:
    """Whether the next mission flown in this process will compile the frame loop.

    ``params`` picks the loop (:func:`allsky.sim.frame_loop.leg_entry`); by
    default the patent's vehicle without faults. See
    :func:`allsky.sim.warm_up.needs_compiling`.
    """
    from allsky.sim.warm_up import entry_points, needs_compiling

    return needs_compiling(entry_points(params))


def _fixed_size(stream):
    """(columns, lines) to use instead of a zero the terminal reports; None: tqdm's own."""
    try:
        size = os.get_terminal_size(stream.fileno())
    except (AttributeError, ValueError, OSError):
        return None, None
    return (FALLBACK_SIZE[0] if size.columns <= 0 else None,
            FALLBACK_SIZE[1] if size.lines <= 0 else None)


def fly(m, quiet=False, stream=None, bar=None):
    """Fly the remaining modes of ``m`` with a progress line; return its summary.

    ``m`` is the :class:`~allsky.sim.mission.Mission`. With ``quiet`` no line
    and no note is shown; ``stream`` is where the terminal line goes (default
    ``sys.stderr``, which, when it is not a terminal, gets the compile note
    alone). ``bar``: a tqdm class to draw the progress with instead of the
    terminal line, shown wherever it draws (:class:`tqdm.notebook.tqdm` in
    Jupyter).
    """
    stream = stream or sys.stderr
    if quiet:
        return m.run()
    first = frame_loop_needs_compiling(m.params)
    live = bar is not None or stream is not sys.stderr or stream.isatty()
    if not live:  # no line to show it in: the note alone, once
        if first:
            print(f"allsky: {COMPILE_NOTE}", file=stream, flush=True)
        return m.run()
    from allsky.sim.mission import Hooks

    bar_format = "{desc} |{bar}| {n_fmt}/{total_fmt} modes [{elapsed}]"
    if bar is None:
        from tqdm import tqdm

        columns, lines = _fixed_size(stream)
        line = tqdm(total=len(m.plan), initial=m.next_mode, unit="mode", file=stream,
                    leave=False, dynamic_ncols=columns is None and lines is None,
                    ncols=columns, nrows=lines, bar_format=bar_format)
    else:
        line = bar(total=len(m.plan), initial=m.next_mode, unit="mode", leave=False,
                   bar_format=bar_format)
    with line:

        def describe(first_use=False):
            name = m.plan[m.next_mode]
            note = f" ({COMPILE_NOTE})" if first_use else ""
            line.set_description_str(f"Mode {name} {MODE_TITLE[name]}, "
                                     f"t = {m.now_s():.0f} s{note}")

        hooks = Hooks(pause_every_s=PROGRESS_EVERY_S, on_pause=lambda mm, what: describe(),
                      on_slice=lambda mm, what: describe())
        while not m.finished:
            describe(first_use=first)
            first = False
            m.run_mode(hooks)
            line.update(1)
    return m.summary()
