"""Pulse-width pulse-frequency valve modulators 34, 35, 36.

A first-order filter driven by the input minus the fed-back output, followed
by a Schmitt trigger (Wie, *Space Vehicle Dynamics and Control*, 2nd ed.,
section 7.4)::

    tau df/dt = K (e - U_m y) - f
    y: 0 -> sign(f) when |f| >= U_on ;  +-1 -> 0 when |f| <= U_off

with ``e`` the control-amplifier output [V] and ``y`` in {-1, 0, +1} the valve
command. The filter is discretised exactly for an input held over the frame.
A valve once opened stays open for at least the jets' minimum on-time.

Static characteristic for a constant input ``e > 0`` (continuous time):

* dead zone: no firing while ``K e <= U_on`` (at equality the filter only
  approaches U_on, so ``T_off`` is infinite);
* on-time  ``T_on  = tau ln((U_on - K(e - U_m)) / (U_off - K(e - U_m)))``;
* off-time ``T_off = tau ln((K e - U_off) / (K e - U_on))``;
* saturation (valve always open) when ``K (e - U_m) >= U_off``.
"""

import math
from typing import NamedTuple

from allsky import clock, xmath
from allsky.jit import njit


class PwpfParams(NamedTuple):
    """One parameter set shared by the three modulators."""

    filter_gain: float  #: [-] K
    decay: float  #: [-] exp(-dt / tau), the filter's per-frame decay
    on_threshold_v: float  #: [V] U_on
    off_threshold_v: float  #: [V] U_off
    full_on_v: float  #: [V] U_m, fed back while the valve is open
    min_on_frames: int  #: [frames] minimum valve on-time


def make_params(filter_gain, time_constant_s, on_threshold_v, off_threshold_v, full_on_v,
                min_on_time_s, frame_s) -> PwpfParams:
    """Build :class:`PwpfParams`; the minimum on-time is rounded up to whole frames.

    Parameters
    ----------
    filter_gain : float
        [-] K, the filter's gain.
    time_constant_s : float
        [s] tau, the filter's time constant.
    on_threshold_v, off_threshold_v : float
        [V] U_on and U_off, the Schmitt trigger's thresholds (open, close).
    full_on_v : float
        [V] U_m, fed back while the valve is open.
    min_on_time_s : float
        [s] the jets' minimum on-time.
    frame_s : float
        [s] frame length (the filter is discretised over it).
    """
    return PwpfParams(float(filter_gain), xmath.exp(-frame_s / time_constant_s),
                      float(on_threshold_v), float(off_threshold_v), float(full_on_v),
                      max(1, clock.frames_for(clock.clock(frame_s), min_on_time_s)))


@njit
def pwpf_step(p, axis, input_v, filter_v, out, on_frames):
    """Advance modulator ``axis`` by one frame; returns the valve command -1, 0 or +1.

    ``filter_v``, ``out`` and ``on_frames`` are the modulators' state arrays.
    ``p`` is the modulators' :class:`PwpfParams`; ``input_v`` [V] the output of
    control amplifier 31, 32 or 33, held over the frame.
    """
    target = p.filter_gain * (input_v - p.full_on_v * out[axis])
    f = target + (filter_v[axis] - target) * p.decay
    filter_v[axis] = f
    y = out[axis]
    if y == 0:
        if f >= p.on_threshold_v:
            y = 1
        elif f <= -p.on_threshold_v:
            y = -1
        on_frames[axis] = 0
    elif on_frames[axis] >= p.min_on_frames and y * f <= p.off_threshold_v:
        y = 0
    out[axis] = y
    if y != 0:
        on_frames[axis] += 1
    return y


def static_on_off_times_s(p_gain, tau_s, u_on, u_off, u_m, e):
    """Continuous-time (T_on, T_off) [s] of the modulator for constant input ``e`` [V].

    Returns ``(0, inf)`` inside the dead zone and ``(inf, 0)`` in saturation.

    Parameters
    ----------
    p_gain : float
        [-] K, the filter's gain.
    tau_s : float
        [s] tau, the filter's time constant.
    u_on, u_off : float
        [V] the trigger's on and off thresholds.
    u_m : float
        [V] the output fed back while the valve is open.
    """
    if p_gain * e <= u_on:
        return 0.0, math.inf
    if p_gain * (e - u_m) >= u_off:
        return math.inf, 0.0
    t_on = tau_s * xmath.log((u_on - p_gain * (e - u_m)) / (u_off - p_gain * (e - u_m)))
    t_off = tau_s * xmath.log((p_gain * e - u_off) / (p_gain * e - u_on))
    return t_on, t_off
