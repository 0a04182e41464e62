"""Voltage-to-frequency converters 8, 10, 12.

Each turns a rate [arcsec/s] into a pulse train, one pulse per
``pulse_weight_arcsec`` of angle, up or down by sign, at most
``max_rate_pps`` pulses per second (the converter saturates beyond). The
fraction of a pulse left at the end of a frame is carried into the next one
with its sign (like the charge left on the converter's integrator), so no
pulse is lost or invented: the pulses put out plus the carried residue equal
the exact integral of the (clipped) input, the count is within one pulse of
it, and equals it truncated toward zero while the input keeps one sign.

The analogue chain from the summing amplifier to the converter drifts: an
offset ``integrator_drift_arcsec_s`` per axis is added to the converter's
input (the patent's "integrator drift", which Mode 3 measures together with
the gyro drift; drift counters 13/15/17 cannot tell the two apart).
"""

from typing import NamedTuple

from allsky.jit import njit


class VfcParams(NamedTuple):
    """Converter scaling, shared by the three axes."""

    pulse_weight_arcsec: float  #: [arcsec/pulse]
    max_rate_pps: float  #: [pulses/s] saturation
    #: [arcsec/s] input offset per axis (roll, pitch, yaw); 1 arcsec/s = 1 deg/h
    integrator_drift_arcsec_s: tuple = (0.0, 0.0, 0.0)


@njit
def vfc(p, axis, rate_arcsec_s, dt_s, residue_pulses):
    """Pulses [signed int] put out over one frame.

    The remainder is carried in ``residue_pulses``.

    Parameters
    ----------
    p : VfcParams
        Converter scaling.
    axis : int
        0, 1, 2: roll (converter 8), pitch (10), yaw (12).
    rate_arcsec_s : float
        [arcsec/s] input from the summing amplifier (before the integrator
        drift is added).
    dt_s : float
        [s] frame length.
    """
    offset = p.integrator_drift_arcsec_s[axis]
    if offset != 0.0:  # only then: adding 0.0 would turn a -0.0 input into +0.0
        rate_arcsec_s = rate_arcsec_s + offset
    pps = rate_arcsec_s / p.pulse_weight_arcsec
    if pps > p.max_rate_pps:
        pps = p.max_rate_pps
    elif pps < -p.max_rate_pps:
        pps = -p.max_rate_pps
    total = residue_pulses[axis] + pps * dt_s
    n = int(total)  # toward zero
    residue_pulses[axis] = total - n
    return n
