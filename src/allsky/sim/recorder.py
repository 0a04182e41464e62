"""Telemetry recorder: the columns, and the compiled stages that fill them.

:data:`COLUMNS` is the one list of the telemetry columns (name, unit,
meaning); :func:`record_telemetry` writes a row in exactly that order, and
:data:`N_TLM` is derived from the list. Files, their formats and the
generated column page are :mod:`allsky.sim.telemetry`.

The dither record of the comparison mode (:func:`record_dither`, ``N_REC``
columns) is the raw material of the scale-factor estimate
(:mod:`allsky.sequencer.dither`).
"""

from typing import NamedTuple

import numpy as np

from allsky.hardware.wiring import N_SWITCHES, SELECTORS
from allsky.jit import njit_stage
from allsky.sequencer.modes import MODE_CODE
from allsky.units import RAD2ARCSEC


class Column(NamedTuple):
    """One telemetry column."""

    name: str  #: short name, as in :data:`INDEX`
    unit: str  #: unit written in brackets after the name in files
    meaning: str  #: what the value is, with the patent numeral of its block


#: The columns, in the order :func:`record_telemetry` writes them.
COLUMNS = (
    Column("time", "s", "mission time since ejection"),
    Column("mode", "-", "mode code: " + ", ".join(
        f"{code:g} (Mode {name})" if name != "dither" else f"{code:g} (dither comparison mode)"
        for name, code in MODE_CODE.items()) + "; `sequencer.modes.MODE_CODE`"),
    Column("q_w", "-", "attitude quaternion inertial -> body, scalar part"),
    Column("q_x", "-", "attitude quaternion, x part"),
    Column("q_y", "-", "attitude quaternion, y part"),
    Column("q_z", "-", "attitude quaternion, z part"),
    Column("rate_x", "rad/s", "true body rate about +x (roll)"),
    Column("rate_y", "rad/s", "true body rate about +y (pitch)"),
    Column("rate_z", "rad/s", "true body rate about +z (yaw)"),
    Column("sun_pitch", "arcsec", "sun sensor 104 pitch output (linear within "
                                  "`sun_sensor.linear_range_arcsec`, saturated beyond; "
                                  "0 when the Sun is absent)"),
    Column("sun_yaw", "arcsec", "sun sensor 104 yaw output"),
    Column("sun_present", "-", "1 when the Sun is inside the sun sensor's presence cone"),
    Column("tracker_yaw", "arcsec", "star tracker 105 yaw output (rotation about +x that "
                                    "brings the star to the boresight)"),
    Column("tracker_pitch", "arcsec", "star tracker 105 pitch output (rotation about +y)"),
    Column("star_present", "-", "1 when the tracker is locked on a star of its "
                                "magnitude window"),
    Column("counter14", "pulses", "roll up/down counter 14 (one pulse = "
                                  "`electronics.vfc_pulse_weight_arcsec`)"),
    Column("counter16", "pulses", "pitch up/down counter 16"),
    Column("counter18", "pulses", "yaw up/down counter 18"),
    Column("drift_counter13", "pulses", "roll drift counter 13 (Mode 3 count; feeds drift "
                                        "DAC 7)"),
    Column("drift_counter15", "pulses", "pitch drift counter 15 (drift DAC 9)"),
    Column("drift_counter17", "pulses", "yaw drift counter 17 (drift DAC 11)"),
    Column("register25", "lsb", "roll storage register 25 (one lsb = "
                                "`electronics.register_lsb_arcsec`)"),
    Column("register26", "lsb", "pitch storage register 26"),
    Column("register27", "lsb", "yaw storage register 27"),
    Column("valve_roll", "-", "roll valve command of PWPF modulator 34 to jets 39: "
                              "-1, 0 or +1"),
    Column("valve_pitch", "-", "pitch valve command, modulator 35, jets 40"),
    Column("valve_yaw", "-", "yaw valve command, modulator 36, jets 41"),
    Column("amp31", "V", "roll control amplifier 31 output"),
    Column("amp32", "V", "pitch control amplifier 32 output"),
    Column("amp33", "V", "yaw control amplifier 33 output"),
    Column("error_roll", "arcsec", "roll error computed by CPU 22 (Modes 6-1, 6-2)"),
    Column("error_pitch", "arcsec", "pitch error computed by CPU 22 (Mode 6-2)"),
    Column("error_yaw", "arcsec", "yaw error computed by CPU 22 (Mode 6-2)"),
    Column("propellant", "kg", "propellant remaining"),
    Column("switches", "bitmask S1..S19", "bit k-1 set when on/off switch Sk is closed "
                                          "(S7, S8 excluded); `switch_closed`"),
    Column("s7_s8", "axis", "axis selected by S7/S8 for CPU 22: 0 roll, 1 pitch, 2 yaw"),
    Column("overflow", "bitmask 14,16,18,13,15,17", "overflow flags latched by counters "
                                                    "14, 16, 18, 13, 15, 17 (bits 0 to 5)"),
    Column("corrected_roll", "arcsec", "CPU 22 roll angle turned, scale factor applied"),
    Column("corrected_yaw", "arcsec", "CPU 22 yaw angle turned, scale factor applied"),
    Column("intermediate_pitch", "arcsec", "CPU 22 pitch counter angle less the "
                                           "cross-coupling corrections"),
)
#: Column name -> its index in a row.
INDEX = {c.name: i for i, c in enumerate(COLUMNS)}
#: Columns of a telemetry row.
N_TLM = len(COLUMNS)

#: The on/off switches of the bitmask column (the selectors hold an axis instead).
_ON_OFF = tuple(k for k in range(1, N_SWITCHES + 1) if k not in SELECTORS)
#: The selector whose axis the ``s7_s8`` column shows (S7, moved with S8).
_SELECTOR = SELECTORS[0]


@njit_stage
def record_telemetry(tlm, tlm_rows, every_frames, s, mode_code, fine, trk, volts):
    """Write a row of :data:`COLUMNS` into ``tlm`` every ``every_frames`` frames.

    ``tlm_rows`` (1,) is the fill count of the preallocated ``tlm``
    (rows, N_TLM); a full buffer or ``every_frames`` 0 records nothing.
    ``fine`` and ``trk`` are the sun sensor 104 and star tracker 105 outputs
    [arcsec, arcsec, present], ``volts`` the control amplifiers 31-33 [V].
    """
    if every_frames > 0 and s.frame[0] % every_frames == 0 and tlm_rows[0] < tlm.shape[0]:
        _write_row(tlm[tlm_rows[0]], s, mode_code, fine, trk, volts)
        tlm_rows[0] += 1


@njit_stage
def _write_row(row, s, mode_code, fine, trk, volts):
    """One row, column by column in :data:`COLUMNS` order."""
    row[0] = s.time_s[0]
    row[1] = mode_code
    for i in range(7):  # q_w .. q_z, rate_x .. rate_z
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
    for k in _ON_OFF:
        if s.switches[k]:
            m |= 1 << (k - 1)
    row[34] = m
    row[35] = s.switches[_SELECTOR]
    of = 0
    for i in range(6):
        if s.overflow[i]:
            of |= 1 << i
    row[36] = of
    row[37] = s.cpu[0]
    row[38] = s.cpu[1]
    row[39] = s.cpu[2]


#: Dither record columns: leg time [s], counters 14/16/18 and the optics' roll, pitch,
#: yaw [arcsec].
N_REC = 7


@njit_stage
def record_dither(rec, rec_rows, every_frames, t_leg_s, frame, counters, pulse_weight_arcsec,
                  fine, trk):
    """Every ``every_frames`` frames, a row of the dither record into ``rec``.

    The row holds the leg time, counters 14/16/18 [arcsec] and the attitude
    the optics see [arcsec] per axis, as rotations made: roll from the
    tracker, pitch and yaw from the Sun. The counters are read at the
    sample; the optics are the mean of the frames since the previous
    sample (a boxcar of ``every_frames`` frames, as a sensor's electronics
    would average, rather than one frame's noise). The leg's first frame
    opens the record with a point sample, so that every later row averages
    frames of this leg only. ``rec_rows`` (1,) is its fill count; while a
    row fills, its time column counts the frames summed into it.
    """
    k = rec_rows[0]
    if k >= rec.shape[0]:
        return
    # Rotations made, from the optics: the Sun gives pitch and yaw; the
    # tracker's yaw output mixes roll with yaw, because the star sits off
    # the boresight in the tracker pitch direction: for small angles
    # yaw_out = -roll + yaw tan(pitch_out), so roll = -yaw_out + yaw tan(pitch_out).
    pitch = -fine[0]
    yaw = -fine[1]
    roll = -trk[0] + yaw * np.tan(trk[1] / RAD2ARCSEC)
    r = rec[k]
    if k == 0:
        r[0] = 0.0  # the buffer is not cleared: the first row starts its own sums
        r[4] = 0.0
        r[5] = 0.0
        r[6] = 0.0
    r[0] += 1.0
    r[4] += roll
    r[5] += pitch
    r[6] += yaw
    if k == 0 or frame % every_frames == 0:
        n = r[0]
        r[0] = t_leg_s
        for a in range(3):
            r[1 + a] = counters[a] * pulse_weight_arcsec
            r[4 + a] /= n
        rec_rows[0] += 1
        if k + 1 < rec.shape[0]:
            nxt = rec[k + 1]
            nxt[0] = 0.0
            nxt[4] = 0.0
            nxt[5] = 0.0
            nxt[6] = 0.0
