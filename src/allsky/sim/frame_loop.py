"""The per-frame loop: one compiled function that runs the vehicle frame by frame.

It reads top to bottom like the patent's block diagram::

    sensors (gyros 1-3, sun sensor 104, star tracker 105)
    -> summing amplifiers 4-6 (drift DACs 7/9/11 via S1-S3, rate commands 120/128 via S16/S17)
    -> voltage-to-frequency converters 8/10/12 -> up/down counters 14/16/18
                                            (and drift counters 13/15/17 via S4-S6)
    -> computer 111 (sequencer 21 steps S7/S8; CPU 22 -> storage registers 25-27)
    -> DACs 28-30 and optical errors through S9-S15 -> control amplifiers 31-33
    -> PWPF modulators 34-36 -> jets 39-41 -> rigid-body plant
    -> master sequencer 20's watch of the error signals, telemetry

The master sequencer itself (switch actions, mode rules) is Python
(:mod:`allsky.sequencer.master_sequencer`): it sets the switches, then calls
:func:`run_leg` with a *leg* (:mod:`allsky.sequencer.legs`), the condition that ends the current step of a
mode. The loop returns when that condition is met, at the leg's timeout, or
on an abort (propellant gone, Sun or star lost). All state lives in the
arrays of :class:`allsky.sim.state.State`, so a mission can be saved and resumed between legs.
"""

import numpy as np

from allsky.computer.computer_sequencer import sequencer_step
from allsky.computer.cpu import target_step
from allsky.gauss import seed as gauss_seed
from allsky.hardware.control_amp import control_amp
from allsky.hardware.dac import dac
from allsky.hardware.gyro import RRW_STEP_S, gyro_output
from allsky.hardware.jets import jets
from allsky.hardware.pwpf import pwpf_step
from allsky.hardware.rate_command import rate_command
from allsky.hardware.star_tracker import star_tracker
from allsky.hardware.storage_register import store
from allsky.hardware.summing_amp import summing_amp
from allsky.hardware.sun_acquisition import sun_acquisition
from allsky.hardware.sun_sensor import coarse_sun, sun_sensor
from allsky.hardware.updown_counter import count
from allsky.hardware.vfc import vfc
from allsky.jit import njit, njit_alloc
from allsky.sequencer.dither import dither_command
from allsky.sequencer.legs import (
    CLOCK_FRAMES,
    CLOCK_SETTLE,
    CLOCK_STAR_GONE,
    CLOCK_SUN_GONE,
    CLOCK_T_LEG,
    EXIT_DONE,
    EXIT_PAUSE,
    EXIT_PROPELLANT,
    EXIT_STAR_LOST,
    EXIT_SUN_LOST,
    EXIT_TIMEOUT,
    N_SIGNALS,
    PROGRAM_DITHER,
    PROGRAM_MODE1,
    PROGRAM_TARGET,
    PROGRAM_TARGET_DITHER,
    PROGRAM_TARGET_ROLL,
    SIG_ERROR_PITCH,
    SIG_ERROR_ROLL,
    SIG_ERROR_YAW,
    SIG_SUN_PITCH,
    SIG_SUN_YAW,
    SIG_TRACKER_PITCH,
    SIG_TRACKER_YAW,
    WATCH_ELAPSED,
    WATCH_HANDOVER,
)
from allsky.vehicle.plant import rk4_step
from allsky.vehicle.quaternion import rotate_to_body

# Telemetry columns (see allsky.sim.telemetry for names and units).
N_TLM = 40
# Dither record columns: t, counters 14/16/18, optical roll/pitch/yaw.
N_REC = 7
# Rows of 3-vectors of per-leg scratch (sensor outputs, amplifier signals, torque).
N_SCRATCH = 14


@njit
def _sun_inertial(p, t_s, out):
    n = 0.0
    for i in range(3):
        out[i] = p.sun0_inertial[i] + p.sun_rate_inertial[i] * t_s
        n += out[i] * out[i]
    n = np.sqrt(n)
    for i in range(3):
        out[i] /= n


@njit_alloc
def run_leg(p, s, leg, tlm, tlm_rows, rec, rec_rows):
    """Run frames until the leg's condition, timeout or an abort.

    ``tlm`` is a preallocated (rows, N_TLM) telemetry buffer and
    ``tlm_rows`` (1,) its fill count. ``rec`` (rows, N_REC) receives the
    dither record of a PROGRAM_DITHER leg: every ``dither_sample_frames``
    frames, time, counters 14/16/18 [arcsec] and the attitude the optics
    see [arcsec] per axis (roll from the tracker, pitch and yaw from the Sun),
    as rotations made.
    A leg may pause at mission time ``leg.pause_at_s``: the loop returns
    EXIT_PAUSE with its progress in ``s.leg_clock``, and the same leg run
    again with ``resume=1`` carries on as if it had never stopped (the noise
    generator is not reseeded). Returns ``(exit_code, leg_time_s)``.
    """
    # The scratch is allocated here, once per leg; the frames themselves are
    # compiled without the reference-counted runtime (allsky.jit) and cannot allocate.
    return _run_frames(p, s, leg, tlm, tlm_rows, rec, rec_rows, np.zeros((N_SCRATCH, 3)),
                       np.zeros(N_SIGNALS))


@njit
def _run_frames(p, s, leg, tlm, tlm_rows, rec, rec_rows, scratch, sig):
    """The frames of :func:`run_leg`; ``scratch`` (N_SCRATCH, 3) and ``sig`` (N_SIGNALS,)."""
    if not leg.resume:
        gauss_seed(s.rng, leg.seed)
        s.leg_clock[:] = 0.0
    dt = p.frame_s
    el = p.electronics
    sq = p.sequencer
    sw = s.switches
    # Per-leg scratch, rows of ``scratch`` (allocated by run_leg, once per leg).
    sun_i = scratch[0]
    sun_b = scratch[1]
    coarse = scratch[2]
    fine = scratch[3]
    trk = scratch[4]
    gyro = scratch[5]
    comp = scratch[6]
    line = scratch[7]
    pos = scratch[8]
    rate = scratch[9]
    volts = scratch[10]
    torque = scratch[11]
    dith = scratch[12]
    ff = scratch[13]
    pw = p.vfc.pulse_weight_arcsec
    rrw_every = max(1, round(RRW_STEP_S / dt))
    timer = s.leg_clock[CLOCK_SETTLE]
    sun_gone = s.leg_clock[CLOCK_SUN_GONE]
    star_gone = s.leg_clock[CLOCK_STAR_GONE]
    t_leg = s.leg_clock[CLOCK_T_LEG]
    done = int(s.leg_clock[CLOCK_FRAMES])
    n_max = int(np.ceil(leg.timeout_s / dt - 1e-9))
    for frame_in_leg in range(done, n_max):
        # --- sensors -------------------------------------------------------
        _sun_inertial(p, s.time_s[0], sun_i)
        rotate_to_body(s.x, sun_i, sun_b)
        sun_sensor(p.sun, sun_b, fine, s.rng)
        star_tracker(p.tracker, s.x, trk, s.rng)
        gyro_output(p.gyro, s.dtheta_rad, dt, s.gyro_rw_arcsec_s, gyro,
                    s.frame[0] % rrw_every == 0, s.rng)
        # --- summing amplifiers 4, 5, 6 ------------------------------------
        for a in range(3):
            drift = dac(s.drift_counters[a], el.drift_dac_bits, el.drift_lsb_arcsec_s)
            if a == 0:
                cmd = rate_command(el.rate_command_arcsec_s, s.rate_sign[0])
                cmd_sw = sw[16]
            elif a == 2:
                cmd = rate_command(el.rate_command_arcsec_s, s.rate_sign[1])
                cmd_sw = sw[17]
            else:
                cmd = 0.0
                cmd_sw = 0
            comp[a], line[a] = summing_amp(gyro[a], drift, sw[1 + a], cmd, cmd_sw)
        # --- converters 8/10/12, counters 14/16/18, drift counters 13/15/17
        for a in range(3):
            n = vfc(p.vfc, a, comp[a], dt, s.vfc_residue_pulses)
            count(s.counters, a, n, el.counter_bits, el.overflow_mode, s.overflow, a)
            if sw[4 + a]:
                count(s.drift_counters, a, n, el.drift_counter_bits, el.overflow_mode,
                      s.overflow, 3 + a)
        # --- computer 111 ---------------------------------------------------
        all_axes = leg.program == PROGRAM_TARGET or leg.program == PROGRAM_TARGET_DITHER
        dithering = leg.program == PROGRAM_DITHER or leg.program == PROGRAM_TARGET_DITHER
        if leg.program == PROGRAM_TARGET_ROLL or all_axes:
            a = sequencer_step(sw, s.frame[0], el.computer_step_frames)
            if a == 0 or (a > 0 and all_axes):
                err = target_step(a, s.counters[a] * pw, s.word23, s.word24, s.cpu)
                store(s.registers, a, err, el.register_bits, el.register_lsb_arcsec)
        # --- DACs 28-30 and optical errors -> control amplifiers 31-33 -------
        if leg.program == PROGRAM_MODE1:
            coarse_sun(p.sun, sun_b, coarse, s.rng)
            sun_acquisition(p.mode1, p.sun.linear_range_arcsec, fine, coarse, comp, pos, rate)
        else:
            pos[0] = sw[12] * trk[0] \
                + sw[9] * dac(s.registers[0], el.register_bits, el.register_lsb_arcsec)
            pos[1] = sw[13] * trk[1] + sw[14] * fine[0] \
                + sw[10] * dac(s.registers[1], el.register_bits, el.register_lsb_arcsec)
            pos[2] = sw[15] * fine[1] \
                + sw[11] * dac(s.registers[2], el.register_bits, el.register_lsb_arcsec)
            for a in range(3):
                rate[a] = line[a]
        if dithering:
            dither_command(p.dither, t_leg, dith, ff)
            for a in range(3):
                pos[a] += dith[a]
        for a in range(3):
            integrate = leg.program != PROGRAM_MODE1 and not (a == 0 and sw[18]) \
                and not (a == 2 and sw[19])
            volts[a] = control_amp(p.control, a, pos[a], rate[a], s.amp_integral_arcsec,
                                   integrate, dt)
            if dithering:  # feed-forward through the actuator path
                volts[a] += ff[a]
        # --- PWPF modulators 34-36 -> jets 39-41 ------------------------------
        for a in range(3):
            pwpf_step(p.pwpf, a, volts[a], s.pwpf_filter_v, s.pwpf_out, s.pwpf_on_frames)
        tank_ok = jets(p.jets, s.pwpf_out, dt, s.propellant_kg, torque)
        # --- plant ----------------------------------------------------------
        rk4_step(p.plant, s.x, torque, dt, s.dtheta_rad)
        s.time_s[0] += dt
        s.frame[0] += 1
        t_leg += dt
        if s.excursion_ref_q[0] != 0.0 or s.excursion_ref_q[1] != 0.0 \
                or s.excursion_ref_q[2] != 0.0 or s.excursion_ref_q[3] != 0.0:
            e = _rotation_angle(s.excursion_ref_q, s.x)
            s.max_excursion_rad[0] = max(s.max_excursion_rad[0], e)
        # --- telemetry -------------------------------------------------------
        if p.telemetry_every > 0 and s.frame[0] % p.telemetry_every == 0 \
                and tlm_rows[0] < tlm.shape[0]:
            _record(tlm[tlm_rows[0]], s, leg, fine, trk, volts)
            tlm_rows[0] += 1
        if dithering and s.frame[0] % p.dither_sample_frames == 0 \
                and rec_rows[0] < rec.shape[0]:
            r = rec[rec_rows[0]]
            r[0] = t_leg
            for a in range(3):
                r[1 + a] = s.counters[a] * pw
            # Rotations made, from the optics: the Sun gives pitch and yaw; the
            # tracker's yaw output mixes roll with yaw, because the star sits off
            # the boresight in the tracker pitch direction: for small angles
            # yaw_out = -roll + yaw tan(pitch_out), so roll = -yaw_out + yaw tan(pitch_out).
            r[5] = -fine[0]
            r[6] = -fine[1]
            r[4] = -trk[0] + r[6] * np.tan(trk[1] / 206264.80624709636)
            rec_rows[0] += 1
        # --- master sequencer 20's watch -------------------------------------
        if not tank_ok:
            return EXIT_PROPELLANT, t_leg
        sun_in_use = sw[14] == 1 or sw[15] == 1
        star_in_use = sw[12] == 1 or sw[13] == 1
        sun_gone = sun_gone + dt if (sun_in_use and fine[2] < 0.5) else 0.0
        star_gone = star_gone + dt if (star_in_use and trk[2] < 0.5) else 0.0
        if sun_gone > sq.sensor_loss_s:
            return EXIT_SUN_LOST, t_leg
        if star_gone > sq.sensor_loss_s:
            return EXIT_STAR_LOST, t_leg
        sig[SIG_SUN_PITCH] = fine[0] if fine[2] > 0.5 else 1e9
        sig[SIG_SUN_YAW] = fine[1] if fine[2] > 0.5 else 1e9
        sig[SIG_TRACKER_YAW] = trk[0] if trk[2] > 0.5 else 1e9
        sig[SIG_TRACKER_PITCH] = trk[1] if trk[2] > 0.5 else 1e9
        sig[SIG_ERROR_ROLL] = s.cpu[3]
        sig[SIG_ERROR_PITCH] = s.cpu[4]
        sig[SIG_ERROR_YAW] = s.cpu[5]
        if leg.watch == WATCH_ELAPSED:
            if t_leg >= leg.hold_s - 0.5 * dt:
                return EXIT_DONE, t_leg
        elif leg.watch == WATCH_HANDOVER:
            if t_leg > leg.blank_s and abs(sig[leg.handover_signal]) < sq.handover_arcsec:
                return EXIT_DONE, t_leg
        else:
            ok = True
            for k in range(N_SIGNALS):
                if (leg.settle_mask >> k) & 1 and abs(sig[k]) >= sq.settle_threshold_arcsec:
                    ok = False
            timer = timer + dt if ok else 0.0
            if timer >= leg.hold_s - 0.5 * dt:
                return EXIT_DONE, t_leg
        if s.time_s[0] >= leg.pause_at_s - 0.5 * dt and frame_in_leg + 1 < n_max:
            s.leg_clock[CLOCK_T_LEG] = t_leg
            s.leg_clock[CLOCK_SETTLE] = timer
            s.leg_clock[CLOCK_SUN_GONE] = sun_gone
            s.leg_clock[CLOCK_STAR_GONE] = star_gone
            s.leg_clock[CLOCK_FRAMES] = frame_in_leg + 1
            return EXIT_PAUSE, t_leg
    return EXIT_TIMEOUT, t_leg


@njit
def _rotation_angle(qa, qb):
    """Angle [rad] of the rotation taking attitude ``qa`` to ``qb`` (atan2 form)."""
    w = qa[0] * qb[0] + qa[1] * qb[1] + qa[2] * qb[2] + qa[3] * qb[3]
    x = qa[0] * qb[1] - qa[1] * qb[0] - qa[2] * qb[3] + qa[3] * qb[2]
    y = qa[0] * qb[2] + qa[1] * qb[3] - qa[2] * qb[0] - qa[3] * qb[1]
    z = qa[0] * qb[3] - qa[1] * qb[2] + qa[2] * qb[1] - qa[3] * qb[0]
    return 2.0 * np.arctan2(np.sqrt(x * x + y * y + z * z), abs(w))


@njit
def _record(row, s, leg, fine, trk, volts):
    row[0] = s.time_s[0]
    row[1] = leg.mode_code
    for i in range(7):
        row[2 + i] = s.x[i]
    row[9] = fine[0]
    row[10] = fine[1]
    row[11] = fine[2]
    row[12] = trk[0]
    row[13] = trk[1]
    row[14] = trk[2]
    for i in range(3):
        row[15 + i] = s.counters[i]
        row[18 + i] = s.drift_counters[i]
        row[21 + i] = s.registers[i]
        row[24 + i] = s.pwpf_out[i]
        row[27 + i] = volts[i]
        row[30 + i] = s.cpu[3 + i]
    row[33] = s.propellant_kg[0]
    m = 0
    for k in range(1, 20):
        if k != 7 and k != 8 and s.switches[k]:
            m |= 1 << (k - 1)
    row[34] = m
    row[35] = s.switches[7]
    of = 0
    for i in range(6):
        if s.overflow[i]:
            of |= 1 << i
    row[36] = of
    row[37] = s.cpu[0]
    row[38] = s.cpu[1]
    row[39] = s.cpu[2]
