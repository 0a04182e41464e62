"""How the frame loop is compiled: no allocation, no reference counting per frame.

The per-frame blocks are compiled by :func:`allsky.jit.njit` without numba's
reference-counted runtime. Two consequences are checked here: a block that
allocates does not compile at all, and a leg's heap allocations do not grow
with its number of frames (numba's own allocation statistics).
"""

import numba
import numpy as np
import pytest

from allsky.config.scenario import load_scenario
from allsky.jit import njit, njit_alloc
from allsky.sequencer import legs
from allsky.sim import frame_loop
from allsky.sim.mission import Mission

needs_jit = pytest.mark.skipif(numba.config.DISABLE_JIT, reason="about compiled code")


@njit
def _allocating_block(n):
    return np.zeros(n).sum()


@njit_alloc
def _allocating_helper(n):
    return np.zeros(n).sum()


@needs_jit
def test_a_per_frame_block_that_allocates_does_not_compile():
    with pytest.raises(numba.core.errors.TypingError):
        _allocating_block(3)
    assert _allocating_helper(3) == 0.0  # the helper decorator may allocate


@needs_jit
def test_frame_loop_and_blocks_are_compiled_without_the_runtime():
    assert frame_loop._run_frames.targetoptions["_nrt"] is False
    for block in (frame_loop.gyro_output, frame_loop.sun_sensor, frame_loop.star_tracker, frame_loop.rk4_step,
                  frame_loop.pwpf_step, frame_loop.jets, frame_loop.count, frame_loop.vfc, frame_loop.dac,
                  frame_loop.control_amp, frame_loop.target_step, frame_loop.dither_command):
        assert block.targetoptions["_nrt"] is False, block.py_func.__name__


def _leg_allocations(program, frames):
    from numba.core.runtime import rtsys

    m = Mission(load_scenario(), telemetry=False)
    leg = legs.Leg(1, 1.0, program, legs.WATCH_ELAPSED, 0, 0, 0.0,
                     frames * m.params.frame_s, 1e9)
    args = (np.empty((0, frame_loop.N_TLM)), np.zeros(1, dtype=np.int64),
            np.empty((0, frame_loop.N_REC)), np.zeros(1, dtype=np.int64))
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
