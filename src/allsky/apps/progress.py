"""A live progress line for a mission flown from the command line.

The line (tqdm, on stderr) counts modes and shows the mode under way and the
mission time; it is refreshed every ``PROGRESS_EVERY_S`` of mission time by
pausing the frame loop, which does not change the flight (legs resume
exactly). It is silent when asked to be, or when stderr is not a terminal.
"""

import sys

from tqdm import tqdm

PROGRESS_EVERY_S = 20.0  #: [s] of mission time between refreshes


def fly(m, quiet=False, stream=None):
    """Fly the remaining modes of mission ``m`` with a progress line; return its summary."""
    from allsky.sim.mission import MODE_TITLE

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
        m.on_pause = lambda mm, what: describe()
        try:
            first = True
            while not m.finished:
                describe(first_use=first)
                first = False
                m.run_mode()
                bar.update(1)
        finally:
            m.pause_every_s = None
            m.on_pause = None
    return m.summary()
