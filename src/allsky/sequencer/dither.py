"""The dither scale-factor method: generator, feed-forward, detector.

This is the comparison mode.

A small sinusoidal attitude dither ``d(t) = A sin(w t)`` (A a vector: amplitude
and axis, one frequency per axis) is added to the attitude command; a
feed-forward torque ``J_est a(t)``, ``a(t) = -A w^2 sin(w t)``, helps the loop
follow it. The gyro's response at the dither frequency, read from the
up/down counters as the hardware sees it, is compared with the commanded
amplitude (estimate 1) and with the amplitude the optical sensors see at the
same frequency (estimate 2, robust to imperfect tracking).

Scale factors follow the patent's convention (true angle / counted angle),
so they can be stored in register 23 and used by Mode 6 unchanged:
``SF = A_true / A_gyro``; a cross-coupling factor is the in-phase gyro
amplitude on another axis per unit true amplitude of the dithered axis.

Detection: with the record an integer number of dither periods and the
period a power-of-two multiple of the sample period, the dither falls on an
FFT bin (:func:`fft_amplitude`); otherwise a least-squares sinusoid fit with
a polynomial trend (:func:`lsq_amplitude`) or a Hann window removes the
leakage. Noise limit (derived in docs/comparison.md):
``sigma_SF = N sqrt(2/T) / (A w)`` for angle random walk density N and a
record of length T.
"""

import math
from typing import NamedTuple

import numpy as np

from allsky import xarrays, xmath
from allsky.jit import njit
from allsky.units import RAD2ARCSEC


class DitherParams(NamedTuple):
    """Dither generator and feed-forward, per body axis [roll, pitch, yaw]."""

    amplitude_arcsec: np.ndarray  #: [arcsec] dither amplitude per axis (0 = not dithered)
    omega_rad_s: np.ndarray  #: [rad/s] dither angular frequency per axis
    ff_inertia_kg_m2: np.ndarray  #: [kg m^2] 3x3 inertia estimate for the feed-forward
    ff_volts_per_n_m: np.ndarray  #: [V/(N m)] feed-forward torque -> modulator input, per axis


@njit
def dither_command(p, t_s, angle_arcsec, ff_volts):
    """Dither angle [arcsec] per axis and feed-forward modulator input [V] at ``t_s``.

    ``p`` is the :class:`DitherParams`, ``t_s`` the time in the leg [s]; the
    angles go into ``angle_arcsec`` and the inputs of modulators 34-36 into
    ``ff_volts``, both (3,) roll, pitch, yaw.
    """
    # a(t) = -A w^2 sin(w t) [rad/s^2], kept in ff_volts until the torque is formed
    for i in range(3):
        s = xmath.sin(p.omega_rad_s[i] * t_s)
        angle_arcsec[i] = p.amplitude_arcsec[i] * s
        ff_volts[i] = -p.amplitude_arcsec[i] * p.omega_rad_s[i] ** 2 * s / RAD2ARCSEC
    a0, a1, a2 = ff_volts[0], ff_volts[1], ff_volts[2]
    for i in range(3):
        torque = p.ff_inertia_kg_m2[i, 0] * a0 + p.ff_inertia_kg_m2[i, 1] * a1 \
            + p.ff_inertia_kg_m2[i, 2] * a2
        ff_volts[i] = torque * p.ff_volts_per_n_m[i]


def feedforward_torque_n_m(inertia_kg_m2, amplitude_rad, omega_rad_s, t_s):
    """Feed-forward torque [N m] = J_est a(t), for checking the compiled generator.

    ``inertia_kg_m2`` is the 3x3 inertia estimate J_est [kg m^2],
    ``amplitude_rad`` the (3,) dither amplitudes [rad], ``omega_rad_s`` their
    angular frequencies [rad/s] and ``t_s`` the time [s].
    """
    a = [-float(amp) * float(w) ** 2 * xmath.sin(float(w) * t_s)
         for amp, w in zip(amplitude_rad, omega_rad_s, strict=True)]
    return xmath.matmul(inertia_kg_m2, np.array(a))


# ---------------------------------------------------------------------------
# Detector
# ---------------------------------------------------------------------------
# The detectors feed register 23, so every sum, phasor and fit below is exact
# arithmetic (allsky.xmath): the same estimates, to the bit, on every machine.

def phasor(angle_rad) -> complex:
    """exp(i ``angle_rad``) [-], from the exact sine and cosine."""
    return complex(xmath.cos(angle_rad), xmath.sin(angle_rad))


def magnitude(c) -> float:
    """The modulus of ``c`` (``abs`` of one calls the C library's hypot)."""
    return xmath.hypot(float(c.real), float(c.imag))


def _weighted_sum(values) -> float:
    """The correctly rounded sum of ``values`` (``math.fsum``)."""
    return math.fsum(float(v) for v in values)


def hann(n) -> np.ndarray:
    """The ``n``-point Hann window, ``0.5 - 0.5 cos(2 pi k / (n - 1))``, k = 0 .. n-1.

    The window ``numpy.hanning`` gives, with the exact cosine."""
    if n == 1:
        return np.ones(1)
    return 0.5 - 0.5 * xarrays.cos_many(2.0 * math.pi * np.arange(n, dtype=float) / (n - 1))


def fft_amplitude(x, sample_s, freq_hz, window="rect", integrating=True):
    """Complex amplitude ``c`` of ``x`` at ``freq_hz``, from one DFT bin.

    The component is ``|c| sin(w t + arg c)``, t from the first sample.

    ``x`` holds ``n + 1`` samples spanning the record, ``sample_s`` [s] apart;
    ``freq_hz`` [Hz] is the dither frequency, ``window`` ``"rect"`` or
    ``"hann"``, and ``integrating`` true for a counter channel. For an *integrating*
    channel (a counter) the estimate works on the ``n`` sample-to-sample
    differences, the pulses per sample: the drift ramp becomes a constant
    and the random walk white noise, so neither leaks; the DFT bin is then
    divided by the differencing response ``1 - exp(-i w dt)``. For a
    *sampling* channel with white noise (the optics) differencing would
    amplify the end samples' noise by ``1/(w dt)``, so the first ``n``
    samples are used directly, less their mean. With ``window="rect"`` the
    ``n`` samples must span whole dither periods (the dither on an FFT bin);
    ``"hann"`` tolerates an off-bin frequency (corrected for the window's gain).
    ``c`` has the units of ``x``.
    """
    x = np.asarray(x, dtype=float)
    omega = 2.0 * math.pi * freq_hz
    if integrating:
        y = np.diff(x)
        first = 1
    else:
        y = x[:-1]
        first = 0
    n = y.size
    k = freq_hz * n * sample_s
    if window == "rect":
        if abs(k - round(k)) > 1e-6:
            raise ValueError(f"{freq_hz} Hz is not on an FFT bin of a {n}-sample record;"
                             " use window='hann' or lsq_amplitude")
        w = np.ones(n)
    else:
        w = hann(n)
    w_sum = _weighted_sum(w)
    y = y - _weighted_sum(w * y) / w_sum
    # the same bits as xmath.sin/cos of each angle, compiled (allsky.xarrays)
    angles = omega * (np.arange(first, n + first, dtype=float) * sample_s)
    wy = w * y
    re = _weighted_sum(wy * xarrays.cos_many(angles))
    im = -_weighted_sum(wy * xarrays.sin_many(angles))
    # For |c| sin(w t + arg c) = Im(c e^{i w t}) the single-bin DFT gives c / (2i).
    c = 2j * complex(re, im) / w_sum
    return c / (1.0 - phasor(-omega * sample_s)) if integrating else c


def lsq_amplitude(x, sample_s, freq_hz, trend_order=2):
    """Complex amplitude of ``x`` at ``freq_hz`` by least squares.

    The fit holds a sine, a cosine and a polynomial trend.

    ``x`` holds samples ``sample_s`` [s] apart, ``freq_hz`` [Hz] is the dither
    frequency and ``trend_order`` the degree of the polynomial trend. Exact
    for any record length (no leakage from the dither itself); the trend
    absorbs the drift ramp of a counter. The amplitude has the units of ``x``.
    """
    x = np.asarray(x, dtype=float)
    t = np.arange(x.size) * sample_s
    wt = 2.0 * math.pi * freq_hz * t
    tn = t / max(t[-1], 1e-12)
    cols = [xarrays.sin_many(np.asarray(wt, dtype=float)),
            xarrays.cos_many(np.asarray(wt, dtype=float)), np.ones_like(tn)]
    for _ in range(trend_order):
        cols.append(cols[-1] * tn)  # tn^k by products: NumPy's power calls the C library
    coef = xmath.lstsq(np.column_stack(cols), x)
    return complex(coef[0], coef[1])  # a sin + b cos = |.| sin(wt + atan2(b, a))


def projected(c, ref):
    """Signed component of complex amplitude ``c`` in phase with ``ref``.

    It has the units of ``c``.
    """
    return float((c * ref.conjugate()).real) / magnitude(ref)


def scale_factor_sigma(arw_arcsec_rt_s, record_s, amplitude_arcsec, omega_rad_s):
    """Predicted 1-sigma scale-factor error [-]: N sqrt(2/T) / (A w).

    ``arw_arcsec_rt_s`` is the gyro's angle random walk N [arcsec/sqrt(s)],
    ``record_s`` the record length T [s], ``amplitude_arcsec`` the dither
    amplitude A [arcsec] and ``omega_rad_s`` its angular frequency w [rad/s]
    (docs/comparison.md derives it).
    """
    return arw_arcsec_rt_s * math.sqrt(2.0 / record_s) / (amplitude_arcsec * omega_rad_s)
