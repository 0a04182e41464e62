"""Where the frame goes: the default mission's loop with one stage removed at a time.

A benchmark-only build. The frame loop's source (:func:`allsky.sim.frame_loop._run_frames`)
is compiled again with the call of one stage taken out (the sensing stage also
one sensor at a time), and every variant flies the legs the default mission
flies, from the same states, for the same number of frames each. A stage's
cost is the baseline's time less the time without it, per frame; what no
single stage accounts for (the loop itself, the clock, the overlap of stages)
is the remainder. Removing a stage changes what the stages after it see (no
sensing leaves the gyros at rest, no plant freezes the attitude), never how
much work they do.

Run from the repository root::

    python benchmarks/loop_profile.py [RUNS]          # default 7 rounds
    python benchmarks/loop_profile.py [RUNS] --orbit  # the free flyer in its orbit

``--orbit`` flies the legs of ``shuttle-free-flyer`` through the orbit's loop
and takes out, besides the stages above, the orbit's own: its sky (the
Earth's disk and shadow over the stars and the Sun), the sun sensor in the
shadow, the environment's torques and the next frame's place and Sun. There
a removal can come out negative (measured: -30 to -50 ns for each orbit
stage, 2026-12-03): without the stage the compiler lays the loop out
otherwise, and the layout costs more than the stage did. Read its figures as
+-50 ns, and time whole missions side by side (``mission_cpu.py``) to decide.

The legs run without the watch's exit (each flies exactly its frames) and
without telemetry. Each figure is the minimum over RUNS rounds of the CPU
time (``time.process_time``) of all legs, the variants taken in turns.
Compiling the variants takes a few minutes; nothing of it is cached.
"""

import ast
import inspect
import sys
import textwrap
import time

import numpy as np

from allsky.config.scenario import load_scenario
from allsky.jit import load_numba
from allsky.sequencer.legs import CLOCK_FRAMES
from allsky.sim import frame_loop
from allsky.sim.mission import Mission
from allsky.sim.state import State

#: (row, function whose source is edited, the call taken out of it). In the loop a
#: statement that assigns a stage's result assigns a neutral value instead.
VARIANTS = (
    ("sun ephemeris", "_run_frames", "sun_inertial"),
    ("sun sensor 104", "sense", "sun_sensor"),
    ("star tracker 105", "sense", "star_tracker"),
    ("gyros 1-3", "sense", "gyro_output"),
    ("summing amps, converters, counters", "_run_frames", "sum_and_count"),
    ("CPU 22 (computer)", "_run_frames", "compute"),
    ("routing / Mode 1 controller", "_run_frames", "route"),
    ("control amplifiers 31-33", "_run_frames", "control"),
    ("modulators 34-36, jets", "_run_frames", "actuate_vehicle"),
    ("jet on-time", "_run_frames", "count_jet_time"),
    ("plant (RK4), clock", "_run_frames", "advance_vehicle"),
    ("telemetry, dither record", "_run_frames", "record_telemetry"),
    ("journal", "_run_frames", "note_frame"),
    ("watch", "_run_frames", "watch"),
)
#: The orbit's stages (``--orbit``), as VARIANTS.
ORBIT_VARIANTS = (
    ("orbit: sky (Earth's disk, shadow)", "_run_frames", "orbit_sky"),
    ("orbit: sun sensor in the shadow", "_run_frames", "orbit_shadow"),
    ("orbit: torques", "_run_frames", "orbit_torque"),
    ("orbit: next place, its Sun", "_run_frames", "orbit_next"),
)
#: The scenario ``--orbit`` flies.
ORBIT_SCENARIO = "shuttle-free-flyer"
#: Neutral values of removed stages whose result the loop uses.
NEUTRAL = {"sense": "-1", "actuate_vehicle": "True", "watch": "(0, settled, sun_gone, star_gone)",
           "star_tracker": "-1", "orbit_sky": "(orbit.tracker, k_orbit, w_orbit, 1.0)",
           "orbit_next": "(k_orbit, j_orbit, w_orbit)"}
#: Statements that go with a removed stage (the journal's other notes, the dither record).
ALSO = {"note_frame": ("note_clip",), "record_telemetry": ("record_dither",),
        "route": ("acquire_sun",)}


def _calls(node, names):
    return any(isinstance(n, ast.Call) and isinstance(n.func, ast.Name) and n.func.id in names
               for n in ast.walk(node))


class _Remove(ast.NodeTransformer):
    """Take the statements calling ``names`` out; the watch's exit out of the loop."""

    def __init__(self, names, no_exit):
        self.names = names
        self.no_exit = no_exit

    def _stmts(self, body):
        out = []
        for st in body:
            st = self.visit(st)
            if st is None:
                continue
            out.extend(st if isinstance(st, list) else [st])
        return out or [ast.Pass()]

    def generic_visit(self, node):
        for field in ("body", "orelse"):
            if isinstance(getattr(node, field, None), list):
                setattr(node, field, self._stmts(getattr(node, field)))
        return node

    def visit_If(self, node):
        if self.no_exit and isinstance(node.test, ast.Compare) \
                and isinstance(node.test.left, ast.Name) and node.test.left.id == "code":
            return None  # the watch ends no leg: every variant flies the same frames
        if isinstance(node.test, ast.Compare) and _calls(node, self.names) \
                and isinstance(node.test.left, ast.Name) and node.test.left.id == "program":
            return None  # route / acquire_sun
        return self.generic_visit(node)

    def visit_Expr(self, node):
        return None if _calls(node, self.names) else node

    def visit_Assign(self, node):
        if isinstance(node.value, ast.Call) and isinstance(node.value.func, ast.Name) \
                and node.value.func.id in self.names:
            value = ast.parse(NEUTRAL[node.value.func.id], mode="eval").body
            return ast.copy_location(ast.Assign(targets=node.targets, value=value), node)
        return node


def _compile(func, remove, env, no_exit, **options):
    """``func`` (a compiled function) built again without the calls of ``remove``."""
    numba = load_numba()
    src = textwrap.dedent(inspect.getsource(func.py_func))
    tree = ast.parse(src)
    fn = tree.body[0]
    fn.decorator_list = []
    _Remove(set(remove), no_exit).visit(fn)
    ast.fix_missing_locations(tree)
    glb = dict(func.py_func.__globals__)
    glb.update(env)
    exec(compile(tree, f"<{fn.name} variant>", "exec"), glb)  # noqa: S102 - our own source
    opts = dict(func.targetoptions)
    opts.pop("cache", None)
    opts.pop("nopython", None)
    opts.update(options)
    # The compiler too (the loop's own declares its arrays not to alias: allsky.jit).
    opts["pipeline_class"] = func._compiler.pipeline_class
    return numba.njit(**opts)(glb[fn.name])


def build(row, orbit=False):
    """The loop's entry for one variant (``row`` None: nothing removed).

    The plain loop's, or with ``orbit`` the orbit's.
    """
    load_numba()
    where, what = (None, None) if row is None else (row[1], row[2])
    env = {}
    if where == "sense":
        env["sense"] = _compile(frame_loop.sense, [what], {}, False)
    remove = [what, *ALSO.get(what, ())] if where == "_run_frames" else []
    frames = _compile(frame_loop._run_frames, remove, env, True)
    entry = frame_loop._run_leg_orbit if orbit else frame_loop._run_leg_plain
    return _compile(entry, [], {"_run_frames": frames}, False)


def copy_state(s):
    return State._make(np.copy(a) for a in s)


def capture(scenario=None):
    """A mission's legs: (params, state at the leg's start, leg, frames flown).

    ``scenario`` is a packaged scenario's name (None: the default mission).
    """
    cfg = load_scenario(scenario)
    legs = []
    orig = frame_loop.run_leg

    def spy(p, s, leg, tlm, tlm_rows, rec, rec_rows):
        start = copy_state(s)
        f0 = int(s.frame[0])
        out = orig(p, s, leg, tlm, tlm_rows, rec, rec_rows)
        n = int(s.frame[0]) - f0
        fixed = leg._replace(timeout_frames=int(start.leg_clock[CLOCK_FRAMES]) + n,
                             pause_at_frame=np.iinfo(np.int64).max)
        legs.append((p, start, fixed, n, tlm.shape, rec.shape))
        return out

    frame_loop.run_leg = spy
    try:
        Mission(cfg, telemetry=False).run()
    finally:
        frame_loop.run_leg = orig
    return legs


def fly(entry, legs):
    """CPU seconds of all legs through ``entry``."""
    total = 0.0
    for p, start, leg, _, tshape, rshape in legs:
        s = copy_state(start)
        tlm, rec = np.zeros(tshape), np.zeros(rshape)
        rows, rrows = np.zeros(1, np.int64), np.zeros(1, np.int64)
        t0 = time.process_time()
        entry(p, s, leg, tlm, rows, rec, rrows)
        total += time.process_time() - t0
    return total


def main():
    args = [a for a in sys.argv[1:] if a != "--orbit"]
    orbit = "--orbit" in sys.argv[1:]
    runs = int(args[0]) if args else 7
    legs = capture(ORBIT_SCENARIO if orbit else None)
    frames = sum(leg[3] for leg in legs)
    rows = [("(all stages)", None, None), *VARIANTS, *(ORBIT_VARIANTS if orbit else ())]
    entries = [build(None if r[1] is None else r, orbit) for r in rows]
    for e in entries:
        fly(e, legs)
    best = [np.inf] * len(rows)
    for _ in range(runs):
        for i, e in enumerate(entries):
            best[i] = min(best[i], fly(e, legs))
    base = best[0]
    print(f"{frames} frames; all stages {base * 1e3:.2f} ms, {base / frames * 1e9:.1f} ns/frame"
          f" (minimum of {runs} rounds)")
    print(f"{'stage removed':38s} {'ms':>7s} {'ns/frame':>9s}")
    covered = 0.0
    for r, t in zip(rows[1:], best[1:]):
        cost = (base - t) / frames * 1e9
        covered += cost
        print(f"{r[0]:38s} {t * 1e3:7.2f} {cost:9.1f}")
    print(f"{'remainder (loop, overlap)':38s} {'':7s} {base / frames * 1e9 - covered:9.1f}")


if __name__ == "__main__":
    main()
