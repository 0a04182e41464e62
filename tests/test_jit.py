"""How the frame loop is compiled: no allocation, no reference counting per frame.

The per-frame blocks are compiled by :func:`allsky.jit.njit` without numba's
reference-counted runtime, and the loop's stages are inlined into it. Two
consequences are checked here: a block that allocates does not compile at
all, and a leg's heap allocations do not grow with its number of frames
(numba's own allocation statistics).
"""

import numba
import numpy as np
import pytest

from allsky import clock
from allsky.config.scenario import load_scenario
from allsky.jit import njit, njit_alloc, njit_stage
from allsky.sequencer import legs, watch
from allsky.sim import faults, frame_loop, journal, parts, recorder
from allsky.sim.mission import Mission
from allsky.vehicle import environment

needs_jit = pytest.mark.skipif(numba.config.DISABLE_JIT, reason="about compiled code")


@njit
def _allocating_block(n):
    return np.zeros(n).sum()


@njit_alloc
def _allocating_helper(n):
    return np.zeros(n).sum()


@njit_stage
def _allocating_stage(n):
    return np.zeros(n).sum()


@njit
def _loop_calling(n):
    return _allocating_stage(n)


@needs_jit
def test_a_per_frame_block_that_allocates_does_not_compile():
    with pytest.raises(numba.core.errors.TypingError):
        _allocating_block(3)
    assert _allocating_helper(3) == 0.0  # the helper decorator may allocate


@needs_jit
def test_a_stage_that_allocates_does_not_compile_alone_or_inlined():
    with pytest.raises(numba.core.errors.TypingError):
        _allocating_stage(3)
    with pytest.raises(numba.core.errors.TypingError):
        _loop_calling(3)


def _py(f):
    """The Python function behind a compiled one (itself under NUMBA_DISABLE_JIT=1)."""
    return getattr(f, "py_func", f)


#: The stages the loop calls every frame, in signal order (the optional parts' among them).
STAGES = (parts.orbit_start, parts.orbit_sky, parts.faults_tracker, frame_loop.sense,
          parts.orbit_shadow, parts.faults_sense, frame_loop.sum_and_count, frame_loop.compute,
          parts.faults_upset, parts.faults_feed, frame_loop.route, frame_loop.acquire_sun,
          frame_loop.control, frame_loop.actuate_vehicle, parts.faults_actuate,
          parts.orbit_torque, frame_loop.count_jet_time, parts.orbit_next,
          frame_loop.advance_vehicle, frame_loop.track_excursion, parts.wheels_row,
          recorder.record_telemetry, journal.note_frame, journal.note_clip, parts.wheels_note,
          parts.faults_note, recorder.record_dither, watch.watch)
#: The stages the optional parts call (allsky.sim.parts), inlined with them.
PART_STAGES = (environment.occult_stars, environment.dim_sun, environment.env_torque,
               environment.sun_at, environment.next_place, environment.held,
               environment.start_place, faults.fault_tracker, faults.fault_release,
               faults.fault_sense, faults.fault_upset, faults.fault_actuate,
               journal.note_wheels, journal.note_faults)


@needs_jit
def test_frame_loop_and_blocks_are_compiled_without_the_runtime():
    assert frame_loop._run_frames.targetoptions["_nrt"] is False
    fl = frame_loop
    for block in (fl.gyro_output, fl.sun_sensor, fl.star_tracker, fl.rk4_step, fl.pwpf_step,
                  fl.jets, fl.count, fl.vfc, fl.dac, fl.control_amp, fl.target_step,
                  fl.dither_command, fl.route_positions, fl.wire_leg, watch.watched_signals,
                  watch.leg_condition, watch.sensors_in_use):
        assert block.targetoptions["_nrt"] is False, block.py_func.__name__


@needs_jit
@pytest.mark.parametrize("stage", STAGES + PART_STAGES, ids=lambda f: _py(f).__name__)
def test_stages_are_compiled_without_the_runtime_and_inlined(stage):
    assert stage.targetoptions["_nrt"] is False
    # Inlined into the loop by numba: no call, and no argument passing, per frame.
    assert stage.targetoptions["inline"] == "always"


def test_the_loop_calls_every_stage():
    import inspect

    source = inspect.getsource(_py(frame_loop._run_frames))
    for stage in STAGES:
        assert f"{_py(stage).__name__}(" in source, _py(stage).__name__


def test_no_switch_number_is_typed_in_the_loop():
    """The loop and its stages read the bank through the wiring table's index arrays only."""
    import inspect
    import re

    for f in (frame_loop._run_frames, frame_loop.wire_leg, frame_loop.route_positions,
              watch.sensors_in_use, *STAGES):
        source = inspect.getsource(_py(f))
        assert not re.search(r"(sw|bank|switches)\[\s*\d", source), _py(f).__name__


def _leg_allocations(program, frames):
    from numba.core.runtime import rtsys

    m = Mission(load_scenario(), telemetry=False)
    leg = legs.Leg(1, 1.0, program, legs.WATCH_ELAPSED, 0, 0, 0, frames,
                   clock.NEVER)
    args = (np.empty((0, recorder.N_TLM)), np.zeros(1, dtype=np.int64),
            np.empty((0, recorder.N_REC)), np.zeros(1, dtype=np.int64))
    before = rtsys.get_allocation_stats().alloc
    code, _ = frame_loop.run_leg(m.params, m.state, leg, *args)
    assert code == legs.EXIT_DONE
    assert m.state.frame[0] == frames
    return rtsys.get_allocation_stats().alloc - before


@needs_jit
@pytest.mark.parametrize("program", [legs.PROGRAM_MODE1, legs.PROGRAM_TARGET_DITHER])
def test_a_leg_allocates_the_same_for_10_and_10000_frames(program):
    from numba.core.runtime import _nrt_python

    was_on = _nrt_python.memsys_stats_enabled()
    _nrt_python.memsys_enable_stats()
    try:
        _leg_allocations(program, 1)  # compile outside the counted window
        few, many = _leg_allocations(program, 10), _leg_allocations(program, 10_000)
    finally:
        if not was_on:
            _nrt_python.memsys_disable_stats()
    assert few == many
    assert few > 0  # the per-leg scratch: proves the counter sees this code


def test_the_patent_vehicle_without_faults_flies_its_own_loop(default_cfg):
    """No per-frame branch for faults or wheels in the default mission's loop."""
    from allsky.config.scenario import load_scenario

    assert frame_loop.leg_entry(Mission(default_cfg).params) is frame_loop._run_leg_plain
    wheels = load_scenario(overrides=["actuators.kind=wheels"])
    faulty = load_scenario(overrides=['faults=[{kind="gyro_dead", axis="roll", start_s=5.0}]'])
    for cfg in (wheels, faulty):
        assert frame_loop.leg_entry(Mission(cfg).params) is frame_loop._run_leg_any


def test_numba_loads_when_compiled_code_is_first_used():
    """Importing every module and building a mission loads no numba; flying one does."""
    import subprocess
    import sys

    code = ("import sys\n"
            "import allsky.apps.report, allsky.studies.montecarlo, allsky.sim.mission as m\n"
            "from allsky.config import load_scenario\n"
            "mission = m.Mission(load_scenario(), telemetry=False)\n"
            "print('numba' in sys.modules)\n"
            "from allsky.sim import frame_loop\n"
            "print(type(frame_loop._run_leg_plain).__name__)\n"
            "frame_loop._run_leg_plain.signatures\n"
            "print('numba' in sys.modules, type(frame_loop._run_leg_plain).__name__ != "
            "'CompiledFunction' or frame_loop._run_leg_plain is frame_loop._run_leg_plain.py_func)\n")
    env = dict(__import__("os").environ, ALLSKY_AOT="0")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, env=env).stdout.split()
    assert out == ["False", "CompiledFunction", "True", "True"], out
