"""A three-axis multiplicative extended Kalman filter on the counters and optics.

The filter reads what the hardware gives, at the telemetry rate: up/down
counters 14/16/18 (pulses x pulse weight, differenced per sample, with the
drift DAC 7/9/11 compensation that S1-S3 subtracted added back), sun sensor
104 pitch/yaw and star tracker 105 yaw/pitch when they see their targets.
From the Sun's and the stars' inertial directions and the sensors' axes it
estimates 15 error states:

* attitude error (3) [rad], body axes, multiplicative: the true attitude
  matrix is ``(I - [dtheta x]) A_est``;
* gyro drift (3) [rad/s]: gyro drift + the chain's integrator drift + the
  rate random walk, what Mode 3 measures;
* the gyro triad's inverse sensitivity ``S^-1 = I + E`` (9): the diagonal
  of ``E`` (about ``-sf``) and its six off-diagonal elements (about ``-M``)
  for the sensitivity ``S = diag(1 + sf) (I + M)`` of
  :mod:`allsky.hardware.gyro`. The body increment ``(I + E)(y - b dt)`` is
  linear in ``E``, so a scale-factor error of some 1000 ppm leaves no
  second-order error behind after a full turn (with ``sf`` itself as the
  state it would, ``sf^2 x 360 deg``, several arcsec). Scale factors,
  misalignments and register 23's four cross-coupling factors follow from
  ``S = (I + E)^-1`` exactly.

It needs no model of the vehicle's dynamics or actuators: the gyros carry
the attitude from sample to sample. The per-sample loop is compiled
(:func:`run_filter`, allocation-free; scratch allocated once per call).

A :class:`LegRecorder` attaches to a flight through the mission's hooks
(:class:`allsky.sim.mission.Hooks`, a callback before and after each leg)
and keeps each leg's telemetry together with the counters at the leg's ends,
so that counters cleared or preset between legs do not break the
differences; :func:`samples_from_legs` turns that into the filter's input;
:func:`estimate` runs the filter; :func:`fly` flies a plan, runs the filter
on the calibration modes' data, loads its results into register 23 and the
drift counters (as Modes 3-5 would) and flies Mode 6 with them;
:func:`observability` gives the sigmas against time for the figure; the
equations and the validation are in ``docs/kalman.md``, section "A
three-axis filter on the recorded mission".
"""

import math
from typing import NamedTuple

import numpy as np

from allsky import units, xarrays, xmath
from allsky.hardware.dac import dac
from allsky.jit import njit, njit_alloc
from allsky.sequencer.modes import MODE_CODE
from allsky.sim.frame_loop import sun_inertial
from allsky.sim.mission import LEGACY_PLAN, Hooks, Mission
from allsky.sim.recorder import INDEX
from allsky.sim.results import fly_calibrating
from allsky.vehicle import quaternion
from allsky.vehicle.quaternion import rotate_to_body
from allsky.vocabulary import AXES

#: Number of error states.
N_STATE = 15
ATT, BIAS, SF, MIS = 0, 3, 6, 9  #: first index of each block of the error state
#: Off-diagonal states, in order: (gyro i, body axis j) of ``E[i, j]`` (about ``-M[i, j]``).
MISALIGNMENT_PAIRS = ((0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1))
#: State index of each element ``E[a, j]`` of the inverse sensitivity's deviation.
E_INDEX = np.array([[SF + a if a == j else MIS + MISALIGNMENT_PAIRS.index((a, j))
                     for j in range(3)] for a in range(3)], dtype=np.int64)
#: Register 23's cross-coupling factors as elements ``S[i, j]`` of the sensitivity.
CROSS_COUPLING_ELEMENTS = {"roll_into_pitch": (1, 0), "roll_into_yaw": (2, 0),
                           "yaw_into_pitch": (1, 2), "yaw_into_roll": (0, 2)}
#: Modes whose data the filter uses, by the plan's calibration modes.
FILTER_MODES = {"legacy": ("3", "4", "5"), "dither": ("3", "dither")}
#: The calibration modes of each plan (timed as the calibration, as in the comparison).
CALIBRATION_MODES = {"legacy": ("4", "5"), "dither": ("dither",)}
# Columns of the per-sample measurement arrays: two angles [rad] and a validity flag.
VALID = 2


class Prior(NamedTuple):
    """1-sigma uncertainties the filter starts with (estimates start at zero)."""

    attitude_arcsec: float = 60.0  #: [arcsec] of the attitude from the first Sun and star
    drift_deg_h: float = 3.0  #: [deg/h] gyro drift
    scale_factor_ppm: float = 3000.0  #: [ppm] scale-factor errors
    misalignment_arcsec: float = 300.0  #: [arcsec] misalignments (off-diagonal of M)


#: The prior of :func:`estimate` unless another is given.
DEFAULT_PRIOR = Prior()
#: [sigma] innovations beyond this are rejected (a wrong star or a saturated output)
GATE_SIGMA = 6.0


class FilterModel(NamedTuple):
    """Noises and geometry the filter is designed with (data sheet, not truth)."""

    arw_rad_rt_s: float  #: [rad/s^0.5] gyro angle random walk
    rrw_rad_s_rt_s: float  #: [rad/s^1.5] gyro rate random walk
    sun_noise_rad: float  #: [rad] sun sensor 104 white noise per output and sample
    tracker_noise_rad: float  #: [rad] star tracker 105 white noise per output and sample
    readout_rad: float  #: [rad] counter readout noise, one pulse weight / sqrt(12)
    sun_linear_rad: float  #: [rad] sun sensor linear half-range (saturated beyond)
    sun0_inertial: np.ndarray  #: [-] Sun direction at t = 0
    sun_rate_inertial: np.ndarray  #: [1/s] its rate of change
    stars_inertial: np.ndarray  #: [-] (n, 3) the stars of the tracker's magnitude window
    frame_s: float  #: [s] frame: measurements are one frame older than their row


def filter_model(m: Mission) -> FilterModel:
    """The :class:`FilterModel` of mission ``m``'s scenario and sky."""
    cfg, p = m.cfg, m.params
    return FilterModel(
        arw_rad_rt_s=cfg.gyro.arw_deg_rt_h * units.DEG2RAD / math.sqrt(units.HOUR_S),
        rrw_rad_s_rt_s=(cfg.gyro.rrw_deg_h_rt_h * units.DEG2RAD / units.HOUR_S
                        / math.sqrt(units.HOUR_S)),
        sun_noise_rad=cfg.sun_sensor.noise_arcsec * units.ARCSEC2RAD,
        tracker_noise_rad=cfg.star_tracker.noise_arcsec * units.ARCSEC2RAD,
        readout_rad=cfg.electronics.vfc_pulse_weight_arcsec * units.ARCSEC2RAD / math.sqrt(12),
        sun_linear_rad=cfg.sun_sensor.linear_range_arcsec * units.ARCSEC2RAD,
        sun0_inertial=np.asarray(p.sun0_inertial, dtype=float),
        sun_rate_inertial=np.asarray(p.sun_rate_inertial, dtype=float),
        stars_inertial=np.ascontiguousarray(p.tracker.stars_inertial, dtype=float),
        frame_s=float(p.frame_s))


# ------------------------------------------------------------------ recording the data


class LegEnd(NamedTuple):
    """The state at one end of a leg (plain copies)."""

    time_s: float  #: [s] mission time
    counters: np.ndarray  #: [pulses] up/down counters 14/16/18
    drift_counters: np.ndarray  #: [pulses] drift counters 13/15/17 (drift DACs 7/9/11)
    drift_gate: np.ndarray  #: [-] 1.0 where S1/S2/S3 is closed
    x: np.ndarray  #: true plant state [q, w] (for the truth only)
    dtheta_rad: np.ndarray  #: true body increment of the last frame (truth only)
    rw_arcsec_s: np.ndarray  #: true rate-random-walk state of the gyros (truth only)


class LegData(NamedTuple):
    """One leg's telemetry and the state at its two ends."""

    mode: str  #: the mode the leg belongs to
    start: LegEnd  #: the state as the leg began
    end: LegEnd  #: the state as it ended
    rows: np.ndarray  #: the leg's telemetry rows (COLUMNS)


def _leg_end(m) -> LegEnd:
    s = m.state
    return LegEnd(m.now_s(), s.counters.copy(), s.drift_counters.copy(),
                  np.array([float(s.switches[k]) for k in (1, 2, 3)]), s.x.copy(),
                  s.dtheta_rad.copy(), s.gyro_rw_arcsec_s.copy())


class LegRecorder:
    """Hooks that keep the legs' telemetry and the counters at their ends.

    Actions between legs clear or preset counters 14/16/18; the state kept at
    each leg's start and end lets the filter difference the counters within
    legs only. Only the legs of ``modes`` (None: all) record telemetry, so
    the others cost what they cost without the filter. Recording does not
    change the flight. Fly with ``m.run_mode(recorder.hooks)`` (or
    :func:`allsky.sim.results.fly_calibrating` with ``hooks=recorder.hooks``).

    Parameters
    ----------
    modes : sequence of str, optional
        The modes whose legs are recorded; None records every leg.
    """

    def __init__(self, modes=None):
        self.record_modes = None if modes is None else tuple(modes)
        #: :class:`LegData` of the recorded legs, in order.
        self.legs_flown = []
        self._start = None
        #: The hooks to fly with (:class:`allsky.sim.mission.Hooks`).
        self.hooks = Hooks(before_leg=self._before, after_leg=self._after)

    def _before(self, m, mode, what):
        if self.record_modes is not None and mode not in self.record_modes:
            self._start = None
            return False
        self._start = _leg_end(m)
        return True

    def _after(self, m, mode, what, rows):
        if self._start is not None:
            self.legs_flown.append(LegData(mode, self._start, _leg_end(m), rows))
            self._start = None


class Recorded(NamedTuple):
    """A mission and the legs a :class:`LegRecorder` kept of its flight."""

    mission: Mission  #: the mission, to be flown with ``recorder.hooks``
    recorder: LegRecorder  #: the recorder attached to it

    @property
    def legs_flown(self) -> list:
        """The :class:`LegData` kept, in flight order."""
        return self.recorder.legs_flown


def recording(cfg, plan=LEGACY_PLAN, modes=None) -> Recorded:
    """A mission of ``cfg`` flying ``plan``, and a recorder of the legs of ``modes``."""
    return Recorded(Mission(cfg, telemetry=True, plan=plan), LegRecorder(modes))


class Samples(NamedTuple):
    """The filter's input, one row per sample (and the truth beside it)."""

    time_s: np.ndarray  #: [s] epoch of the sample (row time - one frame)
    dt_s: np.ndarray  #: [s] interval since the previous sample
    gyro_rad: np.ndarray  #: (n, 3) [rad] counter increments, drift compensation added back
    sun: np.ndarray  #: (n, 3) sun sensor pitch, yaw [rad], 1.0 when valid
    tracker: np.ndarray  #: (n, 3) star tracker yaw, pitch [rad], 1.0 when valid
    mode: np.ndarray  #: (n,) telemetry mode code
    truth_q: np.ndarray  #: (n, 4) true attitude at the epoch (nan: not known)
    truth_bias_rad_s: np.ndarray  #: (n, 3) true drift at leg ends (nan elsewhere)
    leg_end: np.ndarray  #: (n,) bool, sample at the end of a leg


def _back_one_frame(q, dtheta):
    """Attitudes one frame earlier, ``q (x) dq(-dtheta)``, row by row (n, 4)."""
    h = -0.5 * np.atleast_2d(dtheta)
    n = np.sqrt(np.sum(h * h, axis=1))
    k = np.where(n > 0, xarrays.sin_many(n) / np.where(n > 0, n, 1.0), 1.0)
    dw, dx, dy, dz = xarrays.cos_many(n), h[:, 0] * k, h[:, 1] * k, h[:, 2] * k
    q = np.atleast_2d(q)
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    out = np.column_stack((w * dw - x * dx - y * dy - z * dz, w * dx + x * dw + y * dz - z * dy,
                           w * dy - x * dz + y * dw + z * dx, w * dz + x * dy - y * dx + z * dw))
    return out / xarrays.norm_rows(out)[:, None]


def samples_from_legs(m: Mission, legs_flown, modes, truth=True) -> Samples:
    """The filter's input from the legs of ``modes`` that mission ``m`` flew.

    ``legs_flown`` are the :class:`LegData` a :class:`LegRecorder` kept.

    Per leg: the counters at its start, at each telemetry row and at its end
    are differenced (the counters wrap at ``electronics.counter_bits``);
    intervals of no time are dropped. The drift DACs' output, where S1-S3
    subtracted it, is added back so that the filter sees the gyro's own
    drift. The optical outputs of a row are valid when present and, for the
    sun sensor, inside its linear range. Every epoch is the row's (or the
    leg end's) time less one frame: the sensors and the counters' last
    count belong to the attitude at the start of the frame that recorded them.
    Without ``truth`` the truth columns are left nan (the filter needs none).
    """
    el = m.params.electronics
    frame = float(m.params.frame_s)
    legs = [leg for leg in legs_flown if leg.mode in modes]
    if not legs:
        raise ValueError(f"no legs of modes {modes} were flown")
    rows = np.concatenate([leg.rows for leg in legs])
    sizes = np.array([leg.rows.shape[0] for leg in legs], dtype=np.int64)
    # The drift DACs' output where S1-S3 subtracted it, per leg [arcsec/s].
    comp = np.array([[dac(int(leg.start.drift_counters[a]), el.drift_dac_bits,
                          el.drift_lsb_arcsec_s) * leg.start.drift_gate[a] for a in range(3)]
                     for leg in legs])
    n_max = rows.shape[0] + len(legs)
    out = Samples(np.empty(n_max), np.empty(n_max), np.empty((n_max, 3)),
                  np.empty((n_max, 3)), np.empty((n_max, 3)), np.empty(n_max),
                  np.full((n_max, 4), np.nan), np.full((n_max, 3), np.nan),
                  np.zeros(n_max, dtype=np.bool_))
    source = np.empty(n_max, dtype=np.int64)
    cols = np.array([INDEX[k] for k in ("time", "counter14", "counter16", "counter18",
                                        "sun_pitch", "sun_yaw", "sun_present", "tracker_yaw",
                                        "tracker_pitch", "star_present")], dtype=np.int64)
    scal = np.array([frame, m.pulse_weight_arcsec, m.cfg.sun_sensor.linear_range_arcsec,
                     units.ARCSEC2RAD, float(el.counter_bits)])
    n = _build_samples(rows, sizes, np.array([leg.start.time_s for leg in legs]),
                       np.array([leg.end.time_s for leg in legs]),
                       np.array([leg.start.counters for leg in legs], dtype=np.int64),
                       np.array([leg.end.counters for leg in legs], dtype=np.int64), comp,
                       np.array([MODE_CODE[leg.mode] for leg in legs]), cols, scal,
                       out.time_s, out.dt_s, out.gyro_rad, out.sun, out.tracker, out.mode,
                       out.leg_end, source)
    out = Samples(*[x[:n] for x in out])
    if truth:
        src = source[:n]
        at_row = src >= 0
        q_cols = [INDEX[k] for k in ("q_w", "q_x", "q_y", "q_z")]
        w_cols = [INDEX[k] for k in ("rate_x", "rate_y", "rate_z")]
        r = rows[src[at_row]]
        # A row's attitude is one frame past its epoch, turned at about the row's rate.
        out.truth_q[at_row] = _back_one_frame(r[:, q_cols], r[:, w_cols] * frame)
        leg_of = -1 - src[~at_row]
        out.truth_q[~at_row] = _back_one_frame(
            np.array([legs[k].end.x[0:4] for k in leg_of]).reshape(-1, 4),
            np.array([legs[k].end.dtheta_rad for k in leg_of]).reshape(-1, 3))
        drift = (np.asarray(m.params.gyro.drift_arcsec_s, dtype=float)
                 + np.asarray(m.params.vfc.integrator_drift_arcsec_s, dtype=float))
        ends = np.flatnonzero(out.leg_end)
        leg_of_row = np.repeat(np.arange(len(legs)), sizes)
        src_end = src[ends]
        leg_k = np.array([leg_of_row[i] if i >= 0 else -1 - i for i in src_end], dtype=int)
        rw = np.array([leg.end.rw_arcsec_s for leg in legs])
        out.truth_bias_rad_s[ends] = (drift + rw[leg_k]) * units.ARCSEC2RAD
    return out


@njit
def _build_samples(rows, sizes, t_start, t_end, c_start, c_end, comp, mode_code, cols, scal,
                   time_s, dt_s, gyro, sun, trk, mode, leg_end, source):
    """The loop of :func:`samples_from_legs`; returns the number of samples written.

    ``source`` gets the row a sample ends at, or ``-1 - leg`` for a leg's end.
    """
    frame, weight, lin, arcsec2rad = scal[0], scal[1], scal[2], scal[3]
    modulus = 1 << int(scal[4])
    half = modulus >> 1
    n = 0
    r0 = 0
    for leg in range(sizes.shape[0]):
        t_prev = t_start[leg]
        c0, c1, c2 = c_start[leg, 0], c_start[leg, 1], c_start[leg, 2]
        first = n
        for j in range(sizes[leg] + 1):
            if j < sizes[leg]:
                row = rows[r0 + j]
                t = row[cols[0]]
                n0, n1, n2 = int(row[cols[1]]), int(row[cols[2]]), int(row[cols[3]])
            else:
                t = t_end[leg]
                n0, n1, n2 = c_end[leg, 0], c_end[leg, 1], c_end[leg, 2]
            dt = t - t_prev
            if dt > 0.5 * frame:
                time_s[n] = t - frame
                dt_s[n] = dt
                # Counter differences, wrapped at the counters' length.
                d0 = (n0 - c0 + half) % modulus - half
                d1 = (n1 - c1 + half) % modulus - half
                d2 = (n2 - c2 + half) % modulus - half
                gyro[n, 0] = (d0 * weight + dt * comp[leg, 0]) * arcsec2rad
                gyro[n, 1] = (d1 * weight + dt * comp[leg, 1]) * arcsec2rad
                gyro[n, 2] = (d2 * weight + dt * comp[leg, 2]) * arcsec2rad
                mode[n] = mode_code[leg]
                leg_end[n] = False
                if j < sizes[leg]:
                    sp, sy = row[cols[4]], row[cols[5]]
                    sun[n, 0] = sp * arcsec2rad
                    sun[n, 1] = sy * arcsec2rad
                    sun[n, 2] = 1.0 if (row[cols[6]] > 0.5 and abs(sp) < lin
                                        and abs(sy) < lin) else 0.0
                    trk[n, 0] = row[cols[7]] * arcsec2rad
                    trk[n, 1] = row[cols[8]] * arcsec2rad
                    trk[n, 2] = 1.0 if row[cols[9]] > 0.5 else 0.0
                    source[n] = r0 + j
                else:
                    for i in range(3):
                        sun[n, i] = 0.0
                        trk[n, i] = 0.0
                    source[n] = -1 - leg
                n += 1
            t_prev = t
            c0, c1, c2 = n0, n1, n2
        if n > first:
            leg_end[n - 1] = True
        r0 += sizes[leg]
    return n


# ------------------------------------------------------------------ the filter


@njit
def _compose(q, dw, dx, dy, dz):
    """``q <- q (x) [dw, dx, dy, dz]``, renormalised."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    nw = w * dw - x * dx - y * dy - z * dz
    nx = w * dx + x * dw + y * dz - z * dy
    ny = w * dy - x * dz + y * dw + z * dx
    nz = w * dz + x * dy - y * dx + z * dw
    k = 1.0 / math.sqrt(nw * nw + nx * nx + ny * ny + nz * nz)
    q[0], q[1], q[2], q[3] = nw * k, nx * k, ny * k, nz * k


@njit
def _update(P, q, p, ph, h0, h1, h2, nu, r, gate2, last):
    """One scalar measurement: innovation ``nu``, attitude row ``h``, noise ``r``.

    Returns False (nothing changed) if the innovation fails the gate.
    The attitude correction goes into ``q`` at once, the others into ``p``;
    ``last`` (2,) gets the innovation and its predicted variance.
    """
    # Only the upper triangle of P is read and written here; the loop mirrors it
    # once a sample.
    n = P.shape[0]
    ph[0] = P[0, 0] * h0 + P[0, 1] * h1 + P[0, 2] * h2
    ph[1] = P[0, 1] * h0 + P[1, 1] * h1 + P[1, 2] * h2
    ph[2] = P[0, 2] * h0 + P[1, 2] * h1 + P[2, 2] * h2
    for i in range(3, n):
        ph[i] = P[0, i] * h0 + P[1, i] * h1 + P[2, i] * h2
    s = h0 * ph[0] + h1 * ph[1] + h2 * ph[2] + r
    last[0] = nu
    last[1] = s
    if nu * nu > gate2 * s:
        return False
    g = nu / s
    # The attitude correction, to first order: q <- q (x) [1, dtheta/2].
    _compose(q, 1.0, 0.5 * ph[0] * g, 0.5 * ph[1] * g, 0.5 * ph[2] * g)
    for i in range(3, n):
        p[i - 3] += ph[i] * g
    inv = 1.0 / s
    for i in range(n):
        k = ph[i] * inv
        for j in range(i, n):
            P[i, j] -= k * ph[j]
    return True


@njit
def _angle_update(P, q, p, ph, s, num, den_a, z, r, gate2, last):
    """An ``atan2(num . s, den . s)`` sensor output ``z`` [rad] against prediction.

    ``num`` = (index, sign) picks and signs the component of the body vector
    ``s`` in the numerator, ``den_a`` is the index of the denominator's.
    """
    na, sa = num
    u = sa * s[na]
    v = s[den_a]
    hz = math.atan2(u, v)
    d2 = u * u + v * v
    # Gradient of atan2(u, v) with respect to s, then H = J x s.
    j0 = j1 = j2 = 0.0
    gu, gv = v / d2, -u / d2
    if na == 0:
        j0 += sa * gu
    elif na == 1:
        j1 += sa * gu
    else:
        j2 += sa * gu
    if den_a == 0:
        j0 += gv
    elif den_a == 1:
        j1 += gv
    else:
        j2 += gv
    h0 = j1 * s[2] - j2 * s[1]
    h1 = j2 * s[0] - j0 * s[2]
    h2 = j0 * s[1] - j1 * s[0]
    # The output's second-order term in the attitude error, taken as noise. A turn
    # about s itself moves no direction sensor, to any order; across s the term's
    # variance is at most tr(P_att across s)^2 / 2. Without it a degree-sized error
    # (the yaw after Mode 5's turn) makes the first update take curvature for
    # information.
    sps = (s[0] * s[0] * P[0, 0] + s[1] * s[1] * P[1, 1] + s[2] * s[2] * P[2, 2]
           + 2.0 * (s[0] * s[1] * P[0, 1] + s[0] * s[2] * P[0, 2] + s[1] * s[2] * P[1, 2]))
    tr = P[0, 0] + P[1, 1] + P[2, 2] - sps
    return _update(P, q, p, ph, h0, h1, h2, z - hz, r + 0.5 * tr * tr, gate2, last)


@njit
def _filter_loop(time_s, dt_s, gyro, sun, trk, sun0, sun_rate, stars, noise, q, p, P,
                 out_q, out_p, out_var, checkpoints, out_P, counts, innov, last, c, rot, tmat,
                 ph, vec,
                 uu, body):
    """The samples of :func:`run_filter`, with its scratch arrays handed in."""
    arw2, rrw2, r_sun, r_trk, gate2 = noise[0], noise[1], noise[2], noise[3], noise[4]
    n = time_s.shape[0]
    ci = 0
    for k in range(n):
        dt = dt_s[k]
        # -- propagation: dtheta = (I + E) (y - b dt), linear in E
        u0 = gyro[k, 0] - p[0] * dt
        u1 = gyro[k, 1] - p[1] * dt
        u2 = gyro[k, 2] - p[2] * dt
        c[0, 0], c[0, 1], c[0, 2] = 1.0 + p[3], p[6], p[7]
        c[1, 0], c[1, 1], c[1, 2] = p[8], 1.0 + p[4], p[9]
        c[2, 0], c[2, 1], c[2, 2] = p[10], p[11], 1.0 + p[5]
        d0 = c[0, 0] * u0 + c[0, 1] * u1 + c[0, 2] * u2
        d1 = c[1, 0] * u0 + c[1, 1] * u1 + c[1, 2] * u2
        d2 = c[2, 0] * u0 + c[2, 1] * u1 + c[2, 2] * u2
        # Attitude: q <- q (x) dq(dtheta); the error's transition is the step's rotation
        # (body k -> k+1), from the same half-angle sine and cosine.
        nn = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        if nn > 1e-12:
            a0, a1, a2 = d0 / nn, d1 / nn, d2 / nn
            ch, sh = math.cos(0.5 * nn), math.sin(0.5 * nn)
        else:
            a0, a1, a2, ch, sh = 0.0, 0.0, 0.0, 1.0, 0.0
        _compose(q, ch, sh * a0, sh * a1, sh * a2)
        sth = 2.0 * sh * ch
        omc = 2.0 * sh * sh
        cth = 1.0 - omc
        rot[0, 0] = cth + omc * a0 * a0
        rot[0, 1] = omc * a0 * a1 + sth * a2
        rot[0, 2] = omc * a0 * a2 - sth * a1
        rot[1, 0] = omc * a1 * a0 - sth * a2
        rot[1, 1] = cth + omc * a1 * a1
        rot[1, 2] = omc * a1 * a2 + sth * a0
        rot[2, 0] = omc * a2 * a0 + sth * a1
        rot[2, 1] = omc * a2 * a1 - sth * a0
        rot[2, 2] = cth + omc * a2 * a2
        # ... -(I + E) dt on the drift, and u_j on E[a, j] (row a's own parameters).
        uu[0], uu[1], uu[2] = u0, u1, u2
        # T = Phi_att P (3 x 15), using the sparsity of the attitude row of Phi.
        for a in range(3):
            e_a = E_INDEX[a]
            for col in range(N_STATE):
                acc = rot[a, 0] * P[0, col] + rot[a, 1] * P[1, col] + rot[a, 2] * P[2, col]
                acc -= dt * (c[a, 0] * P[3, col] + c[a, 1] * P[4, col] + c[a, 2] * P[5, col])
                acc += uu[0] * P[e_a[0], col] + uu[1] * P[e_a[1], col] + uu[2] * P[e_a[2], col]
                tmat[a, col] = acc
        # P_att,att = T Phi_att^T + Q, the same sparsity.
        for a in range(3):
            for b in range(a, 3):
                e_b = E_INDEX[b]
                v = tmat[a, 0] * rot[b, 0] + tmat[a, 1] * rot[b, 1] + tmat[a, 2] * rot[b, 2]
                v -= dt * (tmat[a, 3] * c[b, 0] + tmat[a, 4] * c[b, 1] + tmat[a, 5] * c[b, 2])
                v += uu[0] * tmat[a, e_b[0]] + uu[1] * tmat[a, e_b[1]] \
                    + uu[2] * tmat[a, e_b[2]]
                if a == b:
                    v += arw2 * dt
                P[a, b] = v
                P[b, a] = v
            for col in range(3, N_STATE):
                P[a, col] = tmat[a, col]
                P[col, a] = tmat[a, col]
        for i in range(3):
            P[BIAS + i, BIAS + i] += rrw2 * dt
        # -- updates: sun sensor 104, then star tracker 105
        t = time_s[k]
        if sun[k, VALID] > 0.5:
            sun_inertial(sun0, sun_rate, t, vec)
            rotate_to_body(q, vec, body)
            if body[0] > 0.0:
                # pitch = atan2(-s_z, s_x)
                ok = _angle_update(P, q, p, ph, body, (2, -1.0), 0, sun[k, 0], r_sun,
                                   gate2, last)
                counts[0 if ok else 1] += 1
                _keep_innovation(innov, k, 0, last, ok)
                rotate_to_body(q, vec, body)
                # yaw = atan2(s_y, s_x)
                ok = _angle_update(P, q, p, ph, body, (1, 1.0), 0, sun[k, 1], r_sun,
                                   gate2, last)
                counts[0 if ok else 1] += 1
                _keep_innovation(innov, k, 1, last, ok)
        if trk[k, VALID] > 0.5:
            # The star of the window whose predicted outputs are nearest the measured.
            best, kb = 1e300, -1 if stars.shape[0] != 1 else 0
            for s_k in range(stars.shape[0] if kb < 0 else 0):
                rotate_to_body(q, stars[s_k], body)
                if body[2] <= 0.0:
                    continue
                ey = math.atan2(-body[1], body[2]) - trk[k, 0]
                ep = math.atan2(body[0], body[2]) - trk[k, 1]
                if ey * ey + ep * ep < best:
                    best, kb = ey * ey + ep * ep, s_k
            if kb >= 0:
                rotate_to_body(q, stars[kb], body)
                # yaw output = atan2(-s_y, s_z)
                ok = _angle_update(P, q, p, ph, body, (1, -1.0), 2, trk[k, 0], r_trk,
                                   gate2, last)
                counts[2 if ok else 3] += 1
                _keep_innovation(innov, k, 2, last, ok)
                rotate_to_body(q, stars[kb], body)
                # pitch output = atan2(s_x, s_z)
                ok = _angle_update(P, q, p, ph, body, (0, 1.0), 2, trk[k, 1], r_trk,
                                   gate2, last)
                counts[2 if ok else 3] += 1
                _keep_innovation(innov, k, 3, last, ok)
        # -- outputs (the updates kept the upper triangle: mirror it)
        for i in range(N_STATE):
            for j in range(i + 1, N_STATE):
                P[j, i] = P[i, j]
        for i in range(4):
            out_q[k, i] = q[i]
        for i in range(12):
            out_p[k, i] = p[i]
        for i in range(N_STATE):
            out_var[k, i] = P[i, i]
        if ci < checkpoints.shape[0] and checkpoints[ci] == k:
            for i in range(N_STATE):
                for j in range(N_STATE):
                    out_P[ci, i, j] = P[i, j]
            ci += 1


@njit
def _keep_innovation(innov, k, m, last, ok):
    """Innovation, its variance and acceptance of output ``m`` at sample ``k`` (if kept)."""
    if innov.shape[0] > k:
        innov[k, m, 0] = last[0]
        innov[k, m, 1] = last[1]
        innov[k, m, 2] = 1.0 if ok else 0.0


@njit_alloc
def run_filter(time_s, dt_s, gyro, sun, trk, sun0, sun_rate, stars, noise, q, p, P,
               out_q, out_p, out_var, checkpoints, out_P, counts, innov):
    """Run the filter over the samples; state ``q``, ``p``, ``P`` updated in place.

    Parameters
    ----------
    time_s, dt_s : ndarray (n,)
        Epochs and intervals [s] (:class:`Samples`).
    gyro : ndarray (n, 3)
        Counter increments with the drift compensation added back [rad].
    sun, trk : ndarray (n, 3)
        Sun sensor pitch, yaw and tracker yaw, pitch [rad] with the validity flag.
    sun0, sun_rate : ndarray (3,)
        Sun direction at t = 0 and its rate [1/s].
    stars : ndarray (m, 3)
        Unit vectors of the stars of the tracker's window.
    noise : ndarray (6,)
        ARW^2 [rad^2/s], RRW^2 [rad^2/s^3], sun and tracker measurement
        variances [rad^2], gate^2 [-], sun sensor linear range [rad].
    q : ndarray (4,)
        Attitude estimate (inertial -> body).
    p : ndarray (12,)
        Drift [rad/s], the diagonal of ``E`` and its off-diagonal elements in
        the order of :data:`MISALIGNMENT_PAIRS` (:data:`E_INDEX`).
    P : ndarray (15, 15)
        Error covariance.
    out_q, out_p, out_var : ndarray (n, 4), (n, 12), (n, 15)
        Per sample after its updates: attitude, parameters, variance of each state.
    checkpoints : ndarray of int64 (c,)
        Increasing sample indices at which ``P`` is copied into ``out_P`` (c, 15, 15).
    counts : ndarray of int64 (4,)
        Sun updates accepted, rejected; tracker updates accepted, rejected.
    innov : ndarray (n, 4, 3) or (0, 4, 3)
        Per sample and output (sun pitch, sun yaw, tracker yaw, tracker
        pitch): the innovation [rad], its predicted variance [rad^2] and 1.0
        if accepted; left as it is where the output was not used. Shape
        (0, 4, 3): not kept.
    """
    # Scratch, allocated once per call; the per-sample loop allocates nothing.
    _filter_loop(time_s, dt_s, gyro, sun, trk, sun0, sun_rate, stars, noise, q, p, P,
                 out_q, out_p, out_var, checkpoints, out_P, counts, innov, np.empty(2),
                 np.empty((3, 3)),
                 np.empty((3, 3)), np.empty((3, N_STATE)), np.empty(N_STATE), np.empty(3),
                 np.empty(3), np.empty(3))


# ------------------------------------------------------------------ driving it


class Estimate(NamedTuple):
    """The filter's run over a mission's samples."""

    samples: Samples  #: the samples filtered (those after the initialising one)
    q: np.ndarray  #: (n, 4) attitude estimates
    params: np.ndarray  #: (n, 12) drift [rad/s], E's diagonal [-], E's off-diagonal [rad]
    #: (n, 15) 1-sigma of each error state; the attitude's with the present counter
    #: readout error (as :attr:`covariances`)
    sigma: np.ndarray
    checkpoints: np.ndarray  #: sample indices where the covariance was kept (leg ends)
    covariances: np.ndarray  #: (c, 15, 15) the covariance at the checkpoints
    counts: np.ndarray  #: sun accepted, rejected; tracker accepted, rejected
    first: int  #: the sample the filter was initialised at (from Sun and star)
    #: (n, 4, 3) innovation [rad], its variance [rad^2], accepted (1.0) per sample and
    #: output (sun pitch, sun yaw, tracker yaw, tracker pitch); nan where not used
    innovations: np.ndarray = None


def _body_vectors(sun_row, trk_row):
    """Body unit vectors of the Sun and the tracked star from the sensors' angles."""
    sb = np.array([1.0, math.tan(sun_row[1]), -math.tan(sun_row[0])])
    tb = np.array([math.tan(trk_row[1]), -math.tan(trk_row[0]), 1.0])
    return sb / np.linalg.norm(sb), tb / np.linalg.norm(tb)


def triad(model: FilterModel, t_s, sun_row, trk_row) -> np.ndarray:
    """Attitude quaternion from one Sun and one star measurement (TRIAD, Sun first).

    The star is the one of the window whose angle from the Sun matches the
    measured one best. ``model`` gives the Sun's path and the window's stars,
    ``t_s`` [s] is the sample's epoch, ``sun_row`` the sun sensor's (pitch,
    yaw [rad], valid) and ``trk_row`` the tracker's (yaw, pitch [rad],
    valid), as rows of :class:`Samples`.
    """
    sb, tb = _body_vectors(sun_row, trk_row)
    si = model.sun0_inertial + model.sun_rate_inertial * t_s
    si = si / np.linalg.norm(si)
    ang = float(sb @ tb)
    star = model.stars_inertial[int(np.argmin(np.abs(model.stars_inertial @ si - ang)))]

    def frame(a, b):
        c = np.cross(a, b)
        c /= np.linalg.norm(c)
        return np.column_stack((a, c, np.cross(a, c)))

    a = frame(sb, tb) @ frame(si, star).T  # body from inertial
    return quaternion.from_dcm(a)


def prior_covariance(prior: Prior = DEFAULT_PRIOR) -> np.ndarray:
    """Diagonal initial covariance of the 15 error states, from ``prior``'s sigmas."""
    sig = np.concatenate([
        np.full(3, prior.attitude_arcsec * units.ARCSEC2RAD),
        np.full(3, prior.drift_deg_h * units.DEG_H2ARCSEC_S * units.ARCSEC2RAD),
        np.full(3, prior.scale_factor_ppm * units.PPM2FRACTION),
        np.full(6, prior.misalignment_arcsec * units.ARCSEC2RAD)])
    return np.diag(sig**2)


def noise_vector(model: FilterModel) -> np.ndarray:
    """The ``noise`` argument of :func:`run_filter`, from the filter's ``model``."""
    return np.array([model.arw_rad_rt_s**2, model.rrw_rad_s_rt_s**2,
                     model.sun_noise_rad**2 + model.readout_rad**2,
                     model.tracker_noise_rad**2 + model.readout_rad**2, GATE_SIGMA**2,
                     model.sun_linear_rad])


def estimate(model: FilterModel, samples: Samples, prior: Prior = DEFAULT_PRIOR) -> Estimate:
    """Initialise from the first sample seeing Sun and star, and filter the rest.

    ``model`` is the filter's design (:func:`filter_model`) and ``samples``
    its input (:func:`samples_from_legs`). The attitude starts at
    :func:`triad`, drift, scale factors and misalignments at zero, the
    covariance at :func:`prior_covariance` of ``prior``. The covariance is
    kept at every leg end (``samples.leg_end``).
    """
    both = np.flatnonzero((samples.sun[:, VALID] > 0.5) & (samples.tracker[:, VALID] > 0.5))
    if both.size == 0:
        raise ValueError("the Sun and a star were never seen together: no initial attitude")
    first = int(both[0])
    q = triad(model, samples.time_s[first], samples.sun[first], samples.tracker[first])
    rest = slice(first + 1, None)
    s = Samples(*[a[rest] for a in samples])
    n = s.time_s.size
    p = np.zeros(12)
    cov = prior_covariance(prior)
    out_q, out_p, out_var = np.empty((n, 4)), np.empty((n, 12)), np.empty((n, N_STATE))
    ck = np.flatnonzero(s.leg_end).astype(np.int64)
    out_cov = np.empty((ck.size, N_STATE, N_STATE))
    counts = np.zeros(4, dtype=np.int64)
    innov = np.full((n, 4, 3), np.nan)
    run_filter(s.time_s, s.dt_s, s.gyro_rad, s.sun, s.tracker, model.sun0_inertial,
               model.sun_rate_inertial, model.stars_inertial, noise_vector(model), q, p, cov,
               out_q, out_p, out_var, ck, out_cov, counts, innov)
    # The attitude the filter carries is the counters' angle less its drift estimate, so it
    # holds the present counter's readout error, which the filter (the readout in the
    # optics' noise, the rate-integrating form of docs/kalman.md) leaves out of its
    # attitude covariance: P_att = P_dd + sigma_e^2 (Markley and Reynolds).
    out_var[:, :3] += model.readout_rad ** 2
    for i in range(3):
        out_cov[:, i, i] += model.readout_rad ** 2
    return Estimate(s, out_q, out_p, np.sqrt(np.maximum(out_var, 0.0)), ck, out_cov, counts,
                    first, innov)


def sensitivity(params) -> np.ndarray:
    """The gyro sensitivity ``S = (I + E)^-1`` of parameter vector ``params`` (12)."""
    e = np.zeros((3, 3))
    for a in range(3):
        for j in range(3):
            e[a, j] = params[E_INDEX[a, j] - 3]
    return xmath.inv(np.eye(3) + e)


def _register_values(params) -> np.ndarray:
    """Drift [deg/h] x3, scale factors (roll, yaw), cross-coupling x4, sf x3, M x6."""
    s = sensitivity(params)
    drift = np.asarray(params[0:3]) * units.RAD2ARCSEC / units.DEG_H2ARCSEC_S
    cc = [s[i, j] for i, j in CROSS_COUPLING_ELEMENTS.values()]
    mis = [s[i, j] / s[i, i] for i, j in MISALIGNMENT_PAIRS]
    return np.concatenate([drift, [1.0 / s[0, 0], 1.0 / s[2, 2]], cc, np.diag(s) - 1.0, mis])


def calibration(params) -> dict:
    """The filter's estimate in the calibration summary's terms.

    ``drift_deg_h`` per axis, ``scale_factor`` (true / counted) for roll
    and yaw, the four ``cross_coupling`` factors of register 23 (counts on
    the other axis per unit true angle), as
    :meth:`allsky.sim.mission.Mission.calibration` and
    :func:`allsky.hardware.gyro.perfect_calibration` give them. ``params`` is
    the estimate's parameter vector (12: drift [rad/s], then ``E``).
    """
    v = _register_values(params)
    return {"drift_deg_h": dict(zip(AXES, (float(d) for d in v[0:3]))),
            "scale_factor": {"roll": float(v[3]), "yaw": float(v[4])},
            "cross_coupling": {k: float(x) for k, x in zip(CROSS_COUPLING_ELEMENTS, v[5:9])}}


def load(m: Mission, params, by="the Kalman filter") -> None:
    """Put the estimate where Modes 3-5 put theirs: register 23, drift counters 13-17.

    Scale factors and cross-coupling factors go into register 23; the drift
    goes into the drift counters as the count the drift DACs 7/9/11 turn
    into that rate (rounded to one count, clipped to the DAC's range).
    ``m`` is the mission, changed in place through its board (each load
    journaled as made ``by`` the estimator); ``params`` the estimate's
    parameter vector (12).
    """
    cal = calibration(params)
    m.board.load_word23({"sf_roll": cal["scale_factor"]["roll"],
                         "sf_yaw": cal["scale_factor"]["yaw"],
                         **{k: cal["cross_coupling"][k] for k in CROSS_COUPLING_ELEMENTS}},
                        by=by)
    el = m.params.electronics
    hi = (1 << (el.drift_dac_bits - 1)) - 1
    codes = {}
    for a, axis in enumerate(AXES):
        code = round(params[a] * units.RAD2ARCSEC / el.drift_lsb_arcsec_s)
        codes[axis] = min(max(code, -hi - 1), hi)
    m.board.load_drift(codes, by=by)


def sigmas(params, cov) -> dict:
    """1-sigma of the calibration's quantities, from the estimate and its covariance.

    ``drift_deg_h`` per axis, ``scale_factor_ppm`` (roll, yaw; of true /
    counted), ``cross_coupling_arcsec`` (register 23's four),
    ``gyro_scale_factor_ppm`` per gyro and ``misalignment_arcsec`` (``M[i, j]``
    by ``"i,j"``), through the Jacobian of ``S = (I + E)^-1`` (central
    differences). ``params`` is the parameter vector (12) and ``cov`` the
    15 x 15 error covariance (its parameter block is used).
    """
    p = np.asarray(params, dtype=float)
    jac = np.empty((18, 12))
    for k in range(12):
        h = 1e-7 if k >= 3 else 1e-12
        up, dn = p.copy(), p.copy()
        up[k] += h
        dn[k] -= h
        jac[:, k] = (_register_values(up) - _register_values(dn)) / (2 * h)
    sd = np.sqrt(np.diag(xmath.matmul(xmath.matmul(jac, np.asarray(cov)[3:, 3:]), jac.T)))
    return {"drift_deg_h": dict(zip(AXES, (float(x) for x in sd[0:3]))),
            "scale_factor_ppm": {"roll": float(sd[3] * units.FRACTION2PPM),
                                 "yaw": float(sd[4] * units.FRACTION2PPM)},
            "cross_coupling_arcsec": {k: float(x * units.RAD2ARCSEC)
                                      for k, x in zip(CROSS_COUPLING_ELEMENTS, sd[5:9])},
            "gyro_scale_factor_ppm": dict(zip(AXES, (float(x * units.FRACTION2PPM)
                                                     for x in sd[9:12]))),
            "misalignment_arcsec": {f"{i},{j}": float(x * units.RAD2ARCSEC)
                                    for (i, j), x in zip(MISALIGNMENT_PAIRS, sd[12:18])}}


def true_parameters(m: Mission, bias_rad_s) -> np.ndarray:
    """The parameter vector (12) the filter should find, with the drift ``bias_rad_s``.

    ``E`` comes from mission ``m``'s true gyro sensitivity; ``bias_rad_s`` is
    the (3,) true drift [rad/s].
    """
    e = xmath.inv(np.asarray(m.params.gyro.sensitivity)) - np.eye(3)
    out = np.empty(12)
    out[0:3] = bias_rad_s
    for a in range(3):
        for j in range(3):
            out[E_INDEX[a, j] - 3] = e[a, j]
    return out


def rotation_error(a_est, a_true):
    """Rotation vectors ``e`` with ``A_true = exp(-[e x]) A_est``, exactly (n, 3).

    ``a_est`` and ``a_true`` are body-from-inertial matrices, (3, 3) or (n, 3,
    3). To first order ``A_true = (I - [e x]) A_est``, the filter's attitude
    error; this is the whole rotation, right at any angle below 180 deg.
    """
    r = a_true @ np.swapaxes(a_est, -1, -2)
    vee = 0.5 * np.stack([r[..., 1, 2] - r[..., 2, 1], r[..., 2, 0] - r[..., 0, 2],
                          r[..., 0, 1] - r[..., 1, 0]], axis=-1)
    s = np.linalg.norm(vee, axis=-1)
    c = 0.5 * (np.trace(r, axis1=-2, axis2=-1) - 1.0)
    ang = np.arctan2(s, c)
    k = np.where(s > 1e-300, ang / np.where(s > 1e-300, s, 1.0), 1.0)
    return vee * k[..., None]



def errors_at(m: Mission, est: Estimate, k: int):
    """The true error state (15) at checkpoint sample ``k`` (true minus estimated).

    ``est`` is the filter's :class:`Estimate` over mission ``m`` (flown with
    its samples' truth).

    The attitude error is the whole rotation from the estimate to the truth,
    ``A_true = exp(-[e x]) A_est`` (:func:`rotation_error`): the half skew
    part of ``A_true A_est^T``, the small-angle form, is short of the angle
    by its sine's curvature, which at a degree-sized error mid-turn is a
    change of the NEES that no covariance explains.
    """
    s = est.samples
    a_true = quaternion.dcm_body_from_inertial(s.truth_q[k])
    a_est = quaternion.dcm_body_from_inertial(est.q[k])
    att = rotation_error(a_est[None], a_true[None])[0]
    return np.concatenate([att, true_parameters(m, s.truth_bias_rad_s[k]) - est.params[k]])


def nees(m: Mission, est: Estimate) -> np.ndarray:
    """Normalised estimation error squared at each checkpoint (leg end), shape (c,).

    ``est`` is the filter's :class:`Estimate` over mission ``m``
    (:func:`errors_at`).
    """
    out = np.empty(est.checkpoints.size)
    for c, k in enumerate(est.checkpoints):
        e = errors_at(m, est, int(k))
        out[c] = float(e @ np.linalg.solve(est.covariances[c], e))
    return out


class Flight(NamedTuple):
    """A mission whose calibration is the filter's, and what it measured."""

    mission: Mission  #: the mission flown
    estimate: Estimate  #: None when the mission aborted before the calibration ended
    time_s: float  #: [s] duration of the plan's calibration modes
    durations: dict  #: [s] each calibration mode's duration
    excursion_arcsec: float  #: largest excursion during the calibration modes
    propellant_kg: float  #: used by the calibration modes
    filter_s: float  #: [s] wall time of building the samples and filtering


def fly(cfg, plan_name="legacy", prior: Prior = DEFAULT_PRIOR, through_mode6=True,
        truth=True) -> Flight:
    """Fly ``plan_name`` ("legacy" or "dither") with the filter's calibration.

    The mission flies the plan; at the end of its calibration modes (Modes
    4-5, or the dither) the filter runs on the data of Mode 3 and those
    modes, its estimate replaces what the plan stored (register 23, drift
    counters) and the mission flies Mode 6 with it. Calibration time,
    excursion and propellant are measured as :mod:`allsky.studies.compare`
    measures them. ``cfg`` is the scenario and ``prior`` the filter's
    :class:`Prior`. Without ``through_mode6`` the flight ends after the
    calibration; without ``truth`` the samples carry no truth (no NEES).
    """
    import time

    from allsky.sim.mission import DITHER_PLAN

    plan = LEGACY_PLAN if plan_name == "legacy" else DITHER_PLAN
    cal_modes = CALIBRATION_MODES[plan_name]
    m, rec = recording(cfg, plan=plan, modes=FILTER_MODES[plan_name])
    found = {"est": None, "wall": 0.0}

    def calibrate(mm):
        """The filter over the recorded legs, its estimate loaded; go on to Mode 6?"""
        if not mm.finished:
            t0 = time.perf_counter()
            found["est"] = estimate(filter_model(mm), samples_from_legs(
                mm, rec.legs_flown, FILTER_MODES[plan_name], truth), prior)
            load(mm, found["est"].params[-1])
            found["wall"] = time.perf_counter() - t0
        return through_mode6

    t_cal, prop, durations = fly_calibrating(m, cal_modes, on_end=calibrate, hooks=rec.hooks)
    est, wall = found["est"], found["wall"]
    return Flight(m, est, t_cal, durations, float(m.state.max_excursion_rad[0]
                                                 * units.RAD2ARCSEC), prop, wall)


class Observability(NamedTuple):
    """The filter's sigmas against time, for a figure.

    Scale factors and misalignments are to first order minus the elements of
    ``E``; their sigmas are those of the elements.
    """

    time_s: np.ndarray  #: [s] mission time of each sample
    mode: np.ndarray  #: telemetry mode code of each sample
    scale_factor_ppm: np.ndarray  #: (n, 3) 1-sigma of the scale-factor errors
    misalignment_arcsec: np.ndarray  #: (n, 6) 1-sigma of the misalignments (MISALIGNMENT_PAIRS)
    drift_deg_h: np.ndarray  #: (n, 3) 1-sigma of the drift


def observability(est: Estimate) -> Observability:
    """Sigmas of scale factors, misalignments and drift of ``est`` (:class:`Estimate`)."""
    sg = est.sigma  # first order: sigma(sf_i) = sigma(E_ii), sigma(M_ij) = sigma(E_ij)
    return Observability(est.samples.time_s, est.samples.mode,
                         sg[:, SF:SF + 3] * units.FRACTION2PPM,
                         sg[:, MIS:MIS + 6] * units.RAD2ARCSEC,
                         sg[:, BIAS:BIAS + 3] * units.RAD2ARCSEC / units.DEG_H2ARCSEC_S)


# ------------------------------------------------------------------ consistency


class Consistency(NamedTuple):
    """NEES over runs whose gyro errors are drawn from the filter's prior."""

    nees: np.ndarray  #: (runs, checkpoints) NEES at each leg end of the filtered modes
    mean_final: float  #: mean over runs of the NEES at the last leg end
    bounds: tuple  #: two-sided 95 % bounds of that mean for a consistent filter
    aborted: int  #: missions that did not reach the end of their calibration


def draw_truth(prior: Prior, rng) -> list:
    """``--set`` overrides: drift, scale factors, misalignments drawn from ``prior``.

    ``rng`` is the numpy Generator drawn from; each call takes the next draw.
    """
    drift = rng.normal(0.0, prior.drift_deg_h, 3)
    sf = rng.normal(0.0, prior.scale_factor_ppm, 3)
    mis = rng.normal(0.0, prior.misalignment_arcsec, (3, 3))
    np.fill_diagonal(mis, 0.0)
    rows = ", ".join("[" + ", ".join(f"{v!r}" for v in r) + "]" for r in mis.tolist())
    return [f"gyro.drift_deg_h=[{', '.join(repr(v) for v in drift.tolist())}]",
            f"gyro.scale_factor_error_ppm=[{', '.join(repr(v) for v in sf.tolist())}]",
            f"gyro.misalignment_arcsec=[{rows}]"]


def consistency(cfg, runs=50, seed=0, plan_name="legacy", prior: Prior = DEFAULT_PRIOR,
                workers=1) -> Consistency:
    """Fly ``runs`` missions with gyro errors drawn from ``prior``; NEES of each.

    Run ``k`` flies mission seed ``cfg.mission.seed + k`` with the errors of
    the ``k``-th draw of a generator seeded with ``seed``. ``cfg`` is the
    scenario and ``plan_name`` the plan whose calibration the filter follows
    ("legacy" or "dither"). With ``workers`` > 1 the missions are flown in
    that many processes.
    """
    from scipy.stats import chi2

    rng = np.random.default_rng(seed)
    data = cfg.as_dict()
    jobs = [(data, int(cfg.mission.seed) + k, draw_truth(prior, rng), plan_name, prior)
            for k in range(runs)]
    if workers > 1:
        from concurrent.futures import ProcessPoolExecutor
        with ProcessPoolExecutor(workers) as pool:
            rows = list(pool.map(_nees_run, jobs))
    else:
        rows = [_nees_run(j) for j in jobs]
    done = [r for r in rows if r is not None]
    width = min(len(r) for r in done)
    table = np.array([r[:width - 1].tolist() + [r[-1]] for r in done])
    n = len(done)
    lo, hi = chi2.ppf([0.025, 0.975], N_STATE * n) / n
    return Consistency(table, float(table[:, -1].mean()), (float(lo), float(hi)),
                       runs - n)


def _nees_run(job):
    from allsky.config import scenario_from_dict

    data, seed, truth, plan_name, prior = job
    cfg = scenario_from_dict(data, [f"mission.seed={seed}", *truth])
    f = fly(cfg, plan_name, prior, through_mode6=False)
    return None if f.estimate is None else nees(f.mission, f.estimate)
