"""How the frame loop is compiled: no allocation, no reference counting per frame.

The per-frame blocks are compiled by :func:`allsky.jit.njit` without numba's
reference-counted runtime. Two consequences are checked here: a block that
allocates does not compile at all, and a leg's heap allocations do not grow
with its number of frames (numba's own allocation statistics).
"""

import numba
import numpy as np
import pytest

from allsky.sim import kernel
from allsky.config.scenario import load_scenario
from allsky.jit import njit, njit_alloc
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
    assert kernel._run_frames.targetoptions["_nrt"] is False
    for block in (kernel.gyro_output, kernel.sun_sensor, kernel.star_tracker, kernel.rk4_step,
                  kernel.pwpf_step, kernel.jets, kernel.count, kernel.vfc, kernel.dac,
                  kernel.control_amp, kernel.target_step, kernel.dither_command):
        assert block.targetoptions["_nrt"] is False, block.py_func.__name__


def _leg_allocations(program, frames):
    from numba.core.runtime import rtsys

    m = Mission(load_scenario(), telemetry=False)
    leg = kernel.Leg(1, 1.0, program, kernel.WATCH_ELAPSED, 0, 0, 0.0,
                     frames * m.params.frame_s, 1e9)
    args = (np.empty((0, kernel.N_TLM)), np.zeros(1, dtype=np.int64),
            np.empty((0, kernel.N_REC)), np.zeros(1, dtype=np.int64))
    before = rtsys.get_allocation_stats().alloc
    code, _ = kernel.run_leg(m.params, m.state, leg, *args)
    assert code == kernel.EXIT_DONE
    assert m.state.frame[0] == frames
    return rtsys.get_allocation_stats().alloc - before


@needs_jit
@pytest.mark.parametrize("program", [kernel.PROGRAM_MODE1, kernel.PROGRAM_TARGET_DITHER])
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
