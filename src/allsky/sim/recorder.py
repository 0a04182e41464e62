"""Telemetry recorder: the schema, and the compiled stages that fill it.

:data:`COLUMNS` is the one description of the telemetry: each :class:`Column`
is a record of its name, unit, meaning, kind, the values it may hold and how
the replay page carries it. :func:`record_telemetry` writes a row through
the columns' names (:data:`INDEX`); the files (:mod:`allsky.apps.telemetry_files`),
their checks, ``docs/telemetry.md`` and the replay's tables are all derived
from the list. :data:`FORMAT` numbers the schema; :data:`FORMATS` keeps the
column names of each earlier format, so that an older file whose columns
the newer format only added to is still read.

The dither record of the comparison mode (:func:`record_dither`, ``N_REC``
columns) is the raw material of the scale-factor estimate
(:mod:`allsky.sequencer.dither`).
"""

from typing import NamedTuple

import numpy as np

from allsky import xmath
from allsky.clock import frame_time
from allsky.hardware.wiring import N_SWITCHES, SELECTORS
from allsky.jit import njit_stage
from allsky.units import RAD2ARCSEC
from allsky.vocabulary import MODE_CODE

# Kinds of column (Column.kind).
TIME = "time"  #: mission time, strictly increasing
CODE = "code"  #: one of a set of codes (the mode)
REAL = "real"  #: a measured or computed real number
INTEGER = "integer"  #: an integer (a counter, a register), exact in float64
FLAG = "flag"  #: 0 or 1
SET = "set"  #: one of a few integers (a valve command, a selector's contact)
BITMASK = "bitmask"  #: an integer whose bits are flags

# How the replay page carries a column (Column.replay).
EXACT = "exact"  #: every row, exactly (integers, delta-encoded)
RUNS = "runs"  #: as runs of equal values (flags, codes, bitmasks)
DIGITS = "digits"  #: every row, one digit per row (a selector, valve commands)
NOT_SHOWN = ""  #: not in the page


class Column(NamedTuple):
    """One telemetry column: a record of what it holds."""

    name: str  #: short name, as in :data:`INDEX`
    unit: str  #: unit written in brackets after the name in files
    meaning: str  #: what the value is, with the patent numeral of its block
    kind: str = REAL  #: TIME, CODE, REAL, INTEGER, FLAG, SET or BITMASK
    #: values it may hold: a tuple of codes, a ``range`` (SET, BITMASK), None (any)
    allowed: object = None
    #: how the replay carries it: a float scale (kept as round(value * scale), every few
    #: rows on long missions), EXACT, RUNS, DIGITS or NOT_SHOWN
    replay: object = NOT_SHOWN


_MODE_WORDS = ", ".join(f"{code:g} (Mode {name})" if name != "dither"
                        else f"{code:g} (dither comparison mode)"
                        for name, code in MODE_CODE.items())

#: The columns, in the order of a row. Columns are only ever appended: a file of an
#: earlier :data:`FORMATS` entry holds a prefix of them.
COLUMNS = (
    Column("time", "s", "mission time since ejection", TIME),
    Column("mode", "-", f"mode code: {_MODE_WORDS}; `vocabulary.MODE_CODE`", CODE,
           tuple(MODE_CODE.values()), RUNS),
    Column("q_w", "-", "attitude quaternion inertial -> body, scalar part", REAL, None, 1e5),
    Column("q_x", "-", "attitude quaternion, x part", REAL, None, 1e5),
    Column("q_y", "-", "attitude quaternion, y part", REAL, None, 1e5),
    Column("q_z", "-", "attitude quaternion, z part", REAL, None, 1e5),
    Column("rate_x", "rad/s", "true body rate about +x (roll)", REAL, None, RAD2ARCSEC),
    Column("rate_y", "rad/s", "true body rate about +y (pitch)", REAL, None, RAD2ARCSEC),
    Column("rate_z", "rad/s", "true body rate about +z (yaw)", REAL, None, RAD2ARCSEC),
    Column("sun_pitch", "arcsec", "sun sensor 104 pitch output (linear within "
                                  "`sun_sensor.linear_range_arcsec`, saturated beyond; "
                                  "0 when the Sun is absent)", REAL, None, 10.0),
    Column("sun_yaw", "arcsec", "sun sensor 104 yaw output", REAL, None, 10.0),
    Column("sun_present", "-", "1 when the Sun is inside the sun sensor's presence cone",
           FLAG, (0, 1), RUNS),
    Column("tracker_yaw", "arcsec", "star tracker 105 yaw output (rotation about +x that "
                                    "brings the star to the boresight)", REAL, None, 10.0),
    Column("tracker_pitch", "arcsec", "star tracker 105 pitch output (rotation about +y): "
                                      "the star's position along the slit, its cone angle",
           REAL, None, 10.0),
    Column("star_present", "-", "1 when the tracker holds a target in its slit", FLAG,
           (0, 1), RUNS),
    Column("counter14", "pulses", "roll up/down counter 14 (one pulse = "
                                  "`electronics.vfc_pulse_weight_arcsec`)", INTEGER, None,
           EXACT),
    Column("counter16", "pulses", "pitch up/down counter 16", INTEGER, None, EXACT),
    Column("counter18", "pulses", "yaw up/down counter 18", INTEGER, None, EXACT),
    Column("drift_counter13", "pulses", "roll drift counter 13 (Mode 3 count; feeds drift "
                                        "DAC 7)", INTEGER, None, EXACT),
    Column("drift_counter15", "pulses", "pitch drift counter 15 (drift DAC 9)", INTEGER, None,
           EXACT),
    Column("drift_counter17", "pulses", "yaw drift counter 17 (drift DAC 11)", INTEGER, None,
           EXACT),
    Column("register25", "lsb", "roll storage register 25 (one lsb = "
                                "`electronics.register_lsb_arcsec`)", INTEGER, None, EXACT),
    Column("register26", "lsb", "pitch storage register 26", INTEGER, None, EXACT),
    Column("register27", "lsb", "yaw storage register 27", INTEGER, None, EXACT),
    Column("valve_roll", "-", "roll valve command of PWPF modulator 34 to jets 39: "
                              "-1, 0 or +1", SET, (-1, 0, 1), DIGITS),
    Column("valve_pitch", "-", "pitch valve command, modulator 35, jets 40", SET, (-1, 0, 1),
           DIGITS),
    Column("valve_yaw", "-", "yaw valve command, modulator 36, jets 41", SET, (-1, 0, 1),
           DIGITS),
    Column("amp31", "V", "roll control amplifier 31 output", REAL, None, 1e4),
    Column("amp32", "V", "pitch control amplifier 32 output", REAL, None, 1e4),
    Column("amp33", "V", "yaw control amplifier 33 output", REAL, None, 1e4),
    Column("error_roll", "arcsec", "roll error computed by CPU 22 (Modes 6-1, 6-2)", REAL,
           None, 10.0),
    Column("error_pitch", "arcsec", "pitch error computed by CPU 22 (Mode 6-2)", REAL, None,
           10.0),
    Column("error_yaw", "arcsec", "yaw error computed by CPU 22 (Mode 6-2)", REAL, None, 10.0),
    Column("propellant", "kg", "propellant remaining", REAL, None, 1e5),
    Column("switches", "bitmask S1..S19", "bit k-1 set when on/off switch Sk is closed "
                                          "(S7, S8 excluded); `switch_closed`", BITMASK,
           range(2 ** N_SWITCHES), RUNS),
    Column("s7_s8", "axis", "axis selected by S7/S8 for CPU 22: 0 roll, 1 pitch, 2 yaw", SET,
           (0, 1, 2), DIGITS),
    Column("overflow", "bitmask 14,16,18,13,15,17", "overflow flags latched by counters "
                                                    "14, 16, 18, 13, 15, 17 (bits 0 to 5)",
           BITMASK, range(2 ** 6), RUNS),
    Column("corrected_roll", "arcsec", "CPU 22 roll angle turned, scale factor applied", REAL,
           None, 10.0),
    Column("corrected_yaw", "arcsec", "CPU 22 yaw angle turned, scale factor applied", REAL,
           None, 10.0),
    Column("intermediate_pitch", "arcsec", "CPU 22 pitch counter angle less the "
                                           "cross-coupling corrections", REAL, None, 10.0),
    # Format 2: the truth beside the computer's errors, the wheels, the jets' on-time.
    Column("true_error", "arcsec", "true angle between the roll axis (+x, the instruments' "
                                   "line of sight) and the target being flown", REAL, None,
           10.0),
    Column("wheel_h_x", "N m s", "reaction wheels' momentum, body x (0 on the jet vehicle)",
           REAL, None, 1e4),
    Column("wheel_h_y", "N m s", "reaction wheels' momentum, body y", REAL, None, 1e4),
    Column("wheel_h_z", "N m s", "reaction wheels' momentum, body z", REAL, None, 1e4),
    Column("wheel_torque_x", "N m", "reaction wheels' motor torque on the wheels, body x "
                                    "(the body feels its opposite)", REAL, None, 1e5),
    Column("wheel_torque_y", "N m", "reaction wheels' motor torque, body y", REAL, None, 1e5),
    Column("wheel_torque_z", "N m", "reaction wheels' motor torque, body z", REAL, None, 1e5),
    Column("unloading", "-", "1 while jets 39-41 unload the wheels' momentum", FLAG, (0, 1),
           RUNS),
    Column("jet_on_roll", "s", "time modulator 34 has held a valve of jets 39 open since "
                               "ejection (the duty over an interval is its difference)", REAL,
           None, 1e3),
    Column("jet_on_pitch", "s", "the same for modulator 35 and jets 40", REAL, None, 1e3),
    Column("jet_on_yaw", "s", "the same for modulator 36 and jets 41", REAL, None, 1e3),
    Column("gyro_roll", "arcsec/s", "rate gyro 1 output, the roll rate it measures (a faulted "
           "gyro's, as faulted): what converter 8 turns into pulses for counter 14, before drift "
           "DAC 7 is taken off; the true rate is rate_x", REAL, None, 100.0),
    Column("gyro_pitch", "arcsec/s", "rate gyro 2 output (converter 10, counter 16, drift "
           "DAC 9)", REAL, None, 100.0),
    Column("gyro_yaw", "arcsec/s", "rate gyro 3 output (converter 12, counter 18, drift DAC 11)",
           REAL, None, 100.0),
)
#: Column name -> its index in a row.
INDEX = {c.name: i for i, c in enumerate(COLUMNS)}
#: Columns of a telemetry row.
N_TLM = len(COLUMNS)
#: The schema's number, written in every file (CSV header comment, Parquet metadata).
FORMAT = 3
#: Each format's columns, by number, frozen by its last column: a later format only appends
#: columns, and a column appended without a new format fails the check below.
FORMATS = {number: tuple(c.name for c in COLUMNS[:INDEX[last] + 1])
           for number, last in ((1, "intermediate_pitch"), (2, "jet_on_yaw"),
                                (3, "gyro_yaw"))}

# Where the row writer puts each group of columns: their names, read from the schema.
_TIME, _MODE, _Q_W, _RATE_X = INDEX["time"], INDEX["mode"], INDEX["q_w"], INDEX["rate_x"]
_SUN_PITCH, _SUN_YAW, _SUN_PRESENT = INDEX["sun_pitch"], INDEX["sun_yaw"], INDEX["sun_present"]
_TRACKER_YAW, _TRACKER_PITCH = INDEX["tracker_yaw"], INDEX["tracker_pitch"]
_STAR_PRESENT = INDEX["star_present"]
_COUNTER, _DRIFT_COUNTER = INDEX["counter14"], INDEX["drift_counter13"]
_REGISTER, _VALVE, _AMP = INDEX["register25"], INDEX["valve_roll"], INDEX["amp31"]
_ERROR, _PROPELLANT, _SWITCHES = INDEX["error_roll"], INDEX["propellant"], INDEX["switches"]
_SELECTOR_COLUMN, _OVERFLOW = INDEX["s7_s8"], INDEX["overflow"]
_CORRECTED_ROLL, _CORRECTED_YAW = INDEX["corrected_roll"], INDEX["corrected_yaw"]
_INTERMEDIATE_PITCH, _TRUE_ERROR = INDEX["intermediate_pitch"], INDEX["true_error"]
_WHEEL_H, _WHEEL_TORQUE, _UNLOADING = INDEX["wheel_h_x"], INDEX["wheel_torque_x"], \
    INDEX["unloading"]
_JET_ON, _GYRO = INDEX["jet_on_roll"], INDEX["gyro_roll"]


def _check_groups() -> None:
    """Raise ValueError unless each group the writer fills by offset is in order."""
    groups = (("q_w", "q_x", "q_y", "q_z", "rate_x", "rate_y", "rate_z"),
              ("counter14", "counter16", "counter18"),
              ("drift_counter13", "drift_counter15", "drift_counter17"),
              ("register25", "register26", "register27"),
              ("valve_roll", "valve_pitch", "valve_yaw"), ("amp31", "amp32", "amp33"),
              ("error_roll", "error_pitch", "error_yaw"),
              ("wheel_h_x", "wheel_h_y", "wheel_h_z"),
              ("wheel_torque_x", "wheel_torque_y", "wheel_torque_z"),
              ("jet_on_roll", "jet_on_pitch", "jet_on_yaw"),
              ("gyro_roll", "gyro_pitch", "gyro_yaw"))
    for g in groups:
        if [INDEX[n] for n in g] != list(range(INDEX[g[0]], INDEX[g[0]] + len(g))):
            raise ValueError(f"telemetry columns {g} must be consecutive, in this order")
    for old in FORMATS.values():
        if tuple(c.name for c in COLUMNS[:len(old)]) != old:
            raise ValueError("telemetry formats may only append columns")
    if FORMATS[FORMAT] != tuple(c.name for c in COLUMNS):
        raise ValueError(f"the columns after format {FORMAT}'s need a new format: add it to "
                         "FORMATS (its last column) and raise FORMAT")


_check_groups()

#: The on/off switches of the bitmask column (the selectors hold an axis instead).
_ON_OFF = tuple(k for k in range(1, N_SWITCHES + 1) if k not in SELECTORS)
#: The selector whose axis the ``s7_s8`` column shows (S7, moved with S8).
_SELECTOR = SELECTORS[0]


@njit_stage
def record_telemetry(tlm, tlm_rows, every_frames, ck, s, mode_code, fine, trk, gyro, volts,
                     wheel_hb, wheel_u_body, unloading):
    """Write a row of :data:`COLUMNS` into ``tlm`` every ``every_frames`` frames.

    ``tlm_rows`` (1,) is the fill count of the preallocated ``tlm``
    (rows, N_TLM), whose last row is kept for :func:`record_last_row`; a full
    buffer or ``every_frames`` 0 records nothing.
    ``fine`` and ``trk`` are the sun sensor 104 and star tracker 105 outputs
    [arcsec, arcsec, present], ``gyro`` the gyros' outputs of the frame
    [arcsec/s], ``volts`` the control amplifiers 31-33 [V];
    ``wheel_hb`` and ``wheel_u_body`` the wheels' momentum [N m s] and motor
    torque [N m] in body axes, ``unloading`` 1 while the jets unload them.
    ``s`` is the mission state (:class:`allsky.sim.state.State`) after the
    frame, ``mode_code`` the leg's mode code (:data:`allsky.vocabulary.MODE_CODE`);
    ``ck`` the mission's clock (:class:`allsky.clock.ClockParams`): a row's
    time is its frame's, computed.
    """
    if every_frames > 0 and s.frame[0] % every_frames == 0 and tlm_rows[0] < tlm.shape[0] - 1:
        _write_row(tlm[tlm_rows[0]], ck, s, mode_code, fine, trk, gyro, volts, wheel_hb,
                   wheel_u_body, unloading)
        tlm_rows[0] += 1


@njit_stage
def record_last_row(tlm, every_frames, ck, s, mode_code, fine, trk, gyro, volts, wheel_hb,
                    wheel_u_body, unloading):
    """The row of the frame a slice of the loop ends on, into ``tlm``'s last row.

    That row is kept apart from the decimated ones (:func:`record_telemetry`
    leaves it free): the mission appends it to the telemetry when the flight
    ends off the telemetry's grid, so the record ends at its exact last frame.
    ``every_frames``, ``ck``, ``s``, ``mode_code``, ``fine``, ``trk``, ``gyro``,
    ``volts``, ``wheel_hb``, ``wheel_u_body`` and ``unloading`` are those of
    :func:`record_telemetry`.
    """
    if every_frames > 0 and tlm.shape[0] > 0:
        _write_row(tlm[tlm.shape[0] - 1], ck, s, mode_code, fine, trk, gyro, volts, wheel_hb,
                   wheel_u_body, unloading)


@njit_stage
def _write_row(row, ck, s, mode_code, fine, trk, gyro, volts, wheel_hb, wheel_u_body, unloading):
    """One row, through the columns' names."""
    row[_TIME] = frame_time(ck, s.frame[0])
    row[_MODE] = mode_code
    for i in range(7):  # q_w .. q_z, rate_x .. rate_z
        row[_Q_W + i] = s.x[i]
    row[_SUN_PITCH] = fine[0]
    row[_SUN_YAW] = fine[1]
    row[_SUN_PRESENT] = fine[2]
    row[_TRACKER_YAW] = trk[0]
    row[_TRACKER_PITCH] = trk[1]
    row[_STAR_PRESENT] = trk[2]
    for i in range(3):
        row[_COUNTER + i] = s.counters[i]
        row[_DRIFT_COUNTER + i] = s.drift_counters[i]
        row[_REGISTER + i] = s.registers[i]
        row[_VALVE + i] = s.pwpf_out[i]
        row[_AMP + i] = volts[i]
        row[_ERROR + i] = s.cpu[3 + i]
        row[_WHEEL_H + i] = wheel_hb[i]
        row[_WHEEL_TORQUE + i] = wheel_u_body[i]
        row[_JET_ON + i] = s.jet_on_s[i]
        row[_GYRO + i] = gyro[i]
    row[_PROPELLANT] = s.propellant_kg[0]
    m = 0
    for k in _ON_OFF:
        if s.switches[k]:
            m |= 1 << (k - 1)
    row[_SWITCHES] = m
    row[_SELECTOR_COLUMN] = s.switches[_SELECTOR]
    of = 0
    for i in range(6):
        if s.overflow[i]:
            of |= 1 << i
    row[_OVERFLOW] = of
    row[_CORRECTED_ROLL] = s.cpu[0]
    row[_CORRECTED_YAW] = s.cpu[1]
    row[_INTERMEDIATE_PITCH] = s.cpu[2]
    row[_TRUE_ERROR] = true_error_arcsec(s.x, s.target_inertial)
    row[_UNLOADING] = unloading


@njit_stage
def true_error_arcsec(x, target_inertial):
    """True angle [arcsec] between the roll axis (+x) and ``target_inertial``.

    ``x`` holds the attitude quaternion inertial -> body in its first four
    entries; +x in inertial axes is the first row of the body-from-inertial
    matrix.
    """
    w, a, b, c = x[0], x[1], x[2], x[3]
    n = w * w + a * a + b * b + c * c
    ex = (w * w + a * a - b * b - c * c) / n
    ey = 2.0 * (a * b + w * c) / n
    ez = 2.0 * (a * c - w * b) / n
    tx, ty, tz = target_inertial[0], target_inertial[1], target_inertial[2]
    cx = ey * tz - ez * ty
    cy = ez * tx - ex * tz
    cz = ex * ty - ey * tx
    return xmath.atan2(np.sqrt(cx * cx + cy * cy + cz * cz), ex * tx + ey * ty + ez * tz) \
        * RAD2ARCSEC


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

    Parameters
    ----------
    t_leg_s : float
        [s] time in the leg, written as the row's time.
    frame : int
        The mission's frame counter; a row closes when it is a multiple of
        ``every_frames``.
    counters : numpy.ndarray
        [pulses] up/down counters 14, 16, 18.
    pulse_weight_arcsec : float
        [arcsec/pulse] the converters' pulse weight.
    fine, trk : numpy.ndarray
        Sun sensor 104 and star tracker 105 outputs [arcsec, arcsec, present].
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
    roll = -trk[0] + yaw * xmath.tan(trk[1] / RAD2ARCSEC)
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
