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

:func:`njit_alloc` keeps the runtime, for the few compiled helpers that
return new arrays (outside the frame loop, or once per leg).
"""

import numba

# cache=True keeps compiled code between processes (Monte Carlo workers,
# repeated CLI runs); fastmath stays off so that the plain-Python path gives
# the same bits.
njit = numba.njit(cache=True, nogil=True, _nrt=False)
njit_stage = numba.njit(cache=True, nogil=True, _nrt=False, inline="always")
njit_alloc = numba.njit(cache=True, nogil=True)
