"""The comparison mode: gyro calibration by attitude dither.

It is flown in place of Modes 4 and 5.

The mode's steps are in the mode table (:mod:`allsky.sequencer.modes`,
mode ``"dither"``): a record leg, a settle leg, then :func:`dither_analysis`.
It runs in the Sun-and-star hold that ends Mode 3 (S1-S3, S12, S14, S15
closed): the dither generator adds ``A sin(w t)`` to the position input of
each dithered axis's control amplifier and the feed-forward ``J_est a(t)``
to its modulator input; the record (counters 14/16/18 and the optical
attitude, every ``sample_s``) is analysed at each dither frequency.

:func:`target_hold_dither` flies the same dither while holding on the
target after Mode 6-2, to show what the method can see there.

Results go to register 23 exactly as Modes 4 and 5 would put them, so Mode 6
flies unchanged with the dither's calibration:

* scale factor (patent convention, true / counted) = optical amplitude /
  gyro amplitude (estimator "optical") or commanded amplitude / gyro
  amplitude ("command");
* cross-coupling (a step beyond the dither document, which claims scale
  factor only) = the in-phase part of the other axis's gyro response, less
  that axis's own optical motion, per unit optical amplitude of the
  dithered axis. It needs roll and yaw dithered at distinct frequencies.
  Its noise is that of the scale factor in absolute terms (about 1e-3 rad
  for the default dither), far above the misalignments it should find, so
  it is stored in register 23 only with ``dither.store_cross_coupling``;
  otherwise the cross-coupling of register 23 stays neutral (zero).
"""

import math

import numpy as np

from allsky.computer import word_registers as wr
from allsky.sequencer import dither, legs
from allsky.vocabulary import AXES


def analyse(rec, sample_s, lead_in_s, record_s, amplitude_arcsec, omega_rad_s,
            detector="fft", optics_frames=1, cross_coupling=None):
    """Estimates from a dither record (rows: t, counters x3, optical x3).

    Parameters
    ----------
    rec : numpy.ndarray, shape (n, 7)
        The record, one row per sample: leg time [s], up/down counters 14,
        16, 18 [arcsec] and the optical roll, pitch, yaw attitude [arcsec]
        (:func:`allsky.sim.recorder.record_dither`).
    sample_s : float
        [s] Interval between samples (``dither.sample_s``).
    lead_in_s : float
        [s] Leg time at which the analysed span begins (``dither.lead_in_s``).
    record_s : float
        [s] The analysed span, whole dither periods (``dither.record_s``).
    amplitude_arcsec : array_like, shape (3,)
        [arcsec] Commanded dither amplitude per axis; 0 for an axis not
        dithered (it gets no estimate).
    omega_rad_s : array_like, shape (3,)
        [rad/s] Dither angular frequency per axis.
    detector : str
        How an amplitude is measured: ``"fft"`` (on-bin, rectangular window),
        ``"hann"`` or ``"lsq"`` (sinusoid and trend), as ``dither.detector``.
    optics_frames : int
        Frames each optical sample averages (see below).
    cross_coupling : dict, optional
        Known cross-coupling words (see below).

    ``optics_frames`` is the number of frames each optical sample averages
    (:func:`allsky.sim.recorder.record_dither`); the boxcar's gain and lag
    at the dither frequency (:func:`boxcar_response`) are divided out.
    ``cross_coupling`` holds known cross-coupling words (register 23's
    ``roll_into_yaw`` ...; None or zeros: none known). The counts they
    predict from the rotation the optics see on the other axes are taken
    off each gyro channel before the scale factor is formed: in the
    Sun-and-star hold the roll loop turns a yaw dither partly into roll
    (``roll = yaw tan(pitch_out)``, about 0.18 yaw), which the yaw gyro's
    roll-into-yaw misalignment would otherwise read as yaw.

    Returns ``{axis: {...}}`` for each dithered axis: complex amplitudes of
    the gyro and optical channels, both scale-factor estimates, and the
    cross-axis responses.
    """
    t = rec[:, 0]
    # n + 1 samples span the record: n sample intervals of whole dither periods.
    # Selected by count, not by comparing float times.
    n = round(record_s / sample_s)
    first = int(np.argmax(t >= lead_in_s - 0.5 * sample_s))
    r = rec[first:first + n + 1]
    if r.shape[0] != n + 1:
        raise ValueError(f"dither record has {r.shape[0]} samples after the lead-in, "
                         f"{n + 1} needed")
    out = {}
    for a in range(3):
        amp = amplitude_arcsec[a]
        if amp == 0.0:
            continue
        f = omega_rad_s[a] / (2 * math.pi)

        def amp_of(x, integrating, f=f):
            if detector == "lsq":
                return dither.lsq_amplitude(x, sample_s, f)
            return dither.fft_amplitude(x, sample_s, f, window="hann" if detector == "hann"
                                        else "rect", integrating=integrating)

        # The dither phase at the record start: sin(w (t0 + k dt)).
        phase = dither.phasor(float(omega_rad_s[a] * r[0, 0]))
        g = [amp_of(r[:, 1 + b], True) / phase for b in range(3)]
        box = boxcar_response(omega_rad_s[a], sample_s, optics_frames)
        o = [amp_of(r[:, 4 + b], False) / phase / box for b in range(3)]
        gc = _less_known_cross_counts(g, o, cross_coupling)[a]
        size = dither.magnitude
        seen = size(o[a]) > 0.0  # no optical reference (e.g. on the target): nan
        cross = {AXES[b]: dither.projected(g[b] - o[b], o[a]) / size(o[a]) if seen else np.nan
                 for b in range(3) if b != a}
        out[AXES[a]] = {
            "gyro": g[a], "optical": o[a], "commanded_arcsec": amp,
            "scale_factor_optical": (dither.projected(o[a], gc) / size(gc) if seen
                                     else np.nan),
            "scale_factor_command": amp / size(gc),
            "tracking_ratio": size(o[a]) / amp,
            "cross": cross,
        }
    return out


def boxcar_response(omega_rad_s, sample_s, frames):
    """Complex gain of the mean of ``frames`` frames ending at each sample.

    At ``omega_rad_s``: ``H = (1/M) sum_j exp(-i w j dt)``, j = 0..M-1,
    dt = ``sample_s`` / M. The mean lags the sample by (M - 1)/2 frames;
    uncorrected, for the default yaw dither (25.6 s, 10 frames of 0.01 s)
    the gain (1 - 2.5e-5) and the 11 mrad lag, through the projection of the
    optics on the gyro's phase (cos 11 mrad = 1 - 6.1e-5), would bias the
    scale factor by about -86 ppm; roll (51.2 s) by a quarter of that.
    """
    m = max(1, int(frames))
    dt = sample_s / m
    terms = [dither.phasor(-omega_rad_s * dt * j) for j in range(m)]
    return complex(math.fsum(t.real for t in terms) / m, math.fsum(t.imag for t in terms) / m)


#: Register 23 slot of each cross-coupling word: (counting gyro axis, moving axis) -> slot.
_CROSS_WORDS = {(1, 0): ("roll_into_pitch", wr.ROLL_INTO_PITCH),
                (2, 0): ("roll_into_yaw", wr.ROLL_INTO_YAW),
                (1, 2): ("yaw_into_pitch", wr.YAW_INTO_PITCH),
                (0, 2): ("yaw_into_roll", wr.YAW_INTO_ROLL)}


def _less_known_cross_counts(g, o, cross_coupling):
    """Gyro amplitudes less the counts known cross-coupling makes of the optics' motion."""
    if not cross_coupling:
        return g
    g = list(g)
    for (b, c), (name, _) in _CROSS_WORDS.items():
        word = float(cross_coupling.get(name, 0.0))
        if word != 0.0:
            g[b] = g[b] - word * o[c]
    return g


def cross_coupling_words(w) -> dict:
    """The cross-coupling words of register 23 ``w`` by name (zeros: none known)."""
    return {name: float(w[slot]) for name, slot in _CROSS_WORDS.values()}


def dither_analysis(m, records):
    """Analyse the dither record of the mode and store the results in register 23.

    An action: ``m`` is the mission (:class:`~allsky.sequencer.host.Host`),
    ``records`` the samples the mode's legs kept, by name.

    The record is the one the mode's first leg kept (``records["dither record"]``,
    :data:`allsky.sequencer.modes.MODE_TABLE`); the estimates are kept on the
    mission (``m.dither_estimates``, ``m.dither_record``) for the comparison.
    Cross-coupling words already in register 23 (a misalignment correction
    made apart from the dither, which its method assumes; neutral zeros
    unless one was loaded) are taken as known (:func:`analyse`) and kept.
    """
    d = m.cfg.dither
    p = m.params
    record = records["dither record"]
    w = m.view.word23
    est = analyse(record, d.sample_s, d.lead_in_s, d.record_s, p.dither.amplitude_arcsec,
                  p.dither.omega_rad_s, d.detector, optics_frames=p.dither_sample_frames,
                  cross_coupling=cross_coupling_words(w))
    m.dither_estimates = est
    m.dither_record = record
    key = "scale_factor_optical" if d.estimator == "optical" else "scale_factor_command"
    words = {name: float(w[k]) for name, k in wr.WORD23.items()}  # all six are journaled
    if "roll" in est:
        words["sf_roll"] = est["roll"][key]
    if "yaw" in est:
        words["sf_yaw"] = est["yaw"][key]
    if d.store_cross_coupling:
        if "roll" in est:
            words["roll_into_pitch"] = est["roll"]["cross"]["pitch"]
            words["roll_into_yaw"] = est["roll"]["cross"]["yaw"]
        if "yaw" in est:
            words["yaw_into_pitch"] = est["yaw"]["cross"]["pitch"]
            words["yaw_into_roll"] = est["yaw"]["cross"]["roll"]
    m.board.load_word23(words)


def target_hold_dither(m):
    """Dither while holding on the target after Mode 6-2.

    The computer's errors hold mission ``m``'s vehicle (a
    :class:`~allsky.sequencer.host.Host`; it flies one leg more).

    There is no optical reference on the target (the Sun sensor is off the
    Sun, S14/S15 open), so only estimate 1 (gyro against command) exists, and
    it carries the loop's tracking error: with the default loop the gyro
    follows the command 2-3 % over amplitude, so the estimate is off by
    that much whatever the truth. Returns the estimates; register 23 is
    left unchanged.
    """
    d = m.cfg.dither
    rec_rows = int(np.ceil((d.lead_in_s + d.record_s) / d.sample_s)) + 4
    record = m.extra_leg("6-2", d.lead_in_s + d.record_s + 10.0, "dither record on target",
                         legs.PROGRAM_TARGET_DITHER, legs.WATCH_ELAPSED,
                         hold_s=d.lead_in_s + d.record_s + 2 * d.sample_s,
                         record_rows=rec_rows)
    return analyse(record, d.sample_s, d.lead_in_s, d.record_s, m.params.dither.amplitude_arcsec,
                   m.params.dither.omega_rad_s, d.detector,
                   optics_frames=m.params.dither_sample_frames)
