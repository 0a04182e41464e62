"""The mission's journal: what happened, recorded once, when it happened.

Master sequencer 20 and the mission driver write the entries they cause
(a mode's start and end, each switch operation, each named action, each
register or DAC write, the abort) through :meth:`Journal.note`. The frame
loop writes, frame by frame, what only it sees happen (:func:`note_frame`,
:func:`note_clip`, :func:`note_wheels`, :func:`note_faults`): the star in the tracker's slit
changing, a lock the tracker refused (the cone-angle check) or dropped (the bright gate),
a counter overflowing, a drift DAC applying its full scale rather
than the count, a wheel reaching its momentum limit, the jets unloading, a
fault's onset and end. Those go into a small buffer of the mission state
(``State.journal``, :data:`ROWS` rows of :data:`WIDTH` numbers), which the
mission drains into the journal after every slice of frames
(:meth:`Journal.drain`), so the buffer never fills within a slice of
ordinary flight; what would not fit is counted, never silently lost.

Each entry is a dict ``{"t_s", "mode", "kind", ...}``; the kinds and
their fields are :data:`allsky.vocabulary.EVENT_KINDS` (``docs/journal.md``).
The summary carries the journal (``events``), a snapshot carries it so that
a resumed mission's journal equals an uninterrupted one's, and every reader
-- the report, ``allsky step``, the figures, the replay -- reads it instead
of reconstructing the flight from telemetry.
"""

import math

import numpy as np

from allsky import clock
from allsky.hardware import star_tracker as trk
from allsky.hardware.star_tracker import FALSE_TARGET
from allsky.jit import njit_stage
from allsky.units import ARCSEC2DEG, RAD2DEG
from allsky.vehicle.environment import surface_brightness as _brightness
from allsky.vocabulary import AXES, EVENT_KIND, FAULT_KINDS, GROUND_COMMANDS, SATURATIONS

#: Rows of the frame loop's buffer. The mission drains it every slice of at most
#: 1e5 frames; an ordinary flight writes a few entries per slice.
ROWS = 512
#: Numbers per row: frame, kind, what, index, and three values (:data:`FRAME` ...).
WIDTH = 7
FRAME, KIND, WHAT, INDEX, A, B, C = range(WIDTH)

STAR_LOCK = EVENT_KIND["star_lock"].code
LOCK_REJECTED = EVENT_KIND["lock_rejected"].code
LOCK_DROPPED = EVENT_KIND["lock_dropped"].code
SATURATION = EVENT_KIND["saturation"].code
FAULT = EVENT_KIND["fault"].code
EARTH_GLARE = EVENT_KIND["earth_glare"].code

# Saturation codes (row WHAT), in the order of the vocabulary's SATURATIONS.
DAC_CLIP, COUNTER_OVERFLOW, WHEEL_LIMIT, WHEEL_UNLOADING = 1, 2, 3, 4
_SATURATION_NAMES = dict(zip((DAC_CLIP, COUNTER_OVERFLOW, WHEEL_LIMIT, WHEEL_UNLOADING),
                             SATURATIONS))


# What the loop last saw (State.journal_seen), to write an entry when it changes.
SEEN_STAR = 0  #: the star in the slit (index; -1 none, FALSE_TARGET)
SEEN_OVERFLOW = 1  #: the overflow latches of counters 14, 16, 18, 13, 15, 17, bits 0-5
SEEN_CLIP = 2  #: 3 drift DACs 7, 9, 11 applying their full scale
SEEN_UNLOADING = 5  #: the wheels' unloader running
SEEN_WHEEL = 6  #: one per wheel (allsky.config.schema.WHEELS_MAX): at its momentum limit
#: Fault slots follow the wheels (SEEN_WHEEL + WHEELS_MAX), one per fault slot.
#: A wheel is at its momentum limit from this fraction of it, and leaves it below
#: :data:`WHEEL_LIMIT_RELEASE` (a band, so that a wheel held at its limit is one entry).
WHEEL_LIMIT_FRACTION = 1.0 - 1e-9
WHEEL_LIMIT_RELEASE = 0.99
#: Counter numerals in the order of ``State.overflow``.
OVERFLOW_NUMERALS = ("14", "16", "18", "13", "15", "17")
#: Drift DAC numeral per axis.
DRIFT_DAC = ("7", "9", "11")
#: Drift counter numeral per axis.
DRIFT_COUNTER = ("13", "15", "17")
#: Up/down counter numeral per axis.
COUNTER = ("14", "16", "18")


def new_buffer(wheels_max: int, faults_max: int):
    """``(journal, journal_n, journal_seen)`` for a new mission state.

    The buffer is empty; nothing has been seen: no star, no overflow, no
    clip, no unloading, no wheel at its limit, no fault acting. ``seen`` has
    room for ``wheels_max`` wheels and ``faults_max`` fault slots.
    """
    seen = np.zeros(SEEN_WHEEL + wheels_max + faults_max)
    seen[SEEN_STAR] = -1.0
    return np.zeros((ROWS, WIDTH)), np.zeros(2, dtype=np.int64), seen


@njit_stage
def _write(journal, journal_n, frame, kind, what, index, a, b, c):
    """Append one row; count it as lost when the buffer is full (``journal_n[1]``)."""
    k = journal_n[0]
    if k >= journal.shape[0]:
        journal_n[1] += 1
        return
    row = journal[k]
    row[FRAME] = frame
    row[KIND] = kind
    row[WHAT] = what
    row[INDEX] = index
    row[A] = a
    row[B] = b
    row[C] = c
    journal_n[0] = k + 1


@njit_stage
def note_frame(journal, journal_n, seen, frame, star, star_in_use, cone_arcsec, overflow, lock):
    """What changed this frame: the star in the slit, a refusal, a drop, an overflow.

    ``star`` is the index of the target in star tracker 105's slit (-1
    none, :data:`FALSE_TARGET`) and ``cone_arcsec`` its pitch output;
    ``lock`` the tracker's memory, which flags a lock the cone-angle check
    refused or the bright gate dropped in this frame
    (:mod:`allsky.hardware.star_tracker`); ``overflow`` the latches of
    counters 14, 16, 18, 13, 15, 17. The latches are compared as one
    bitmask, so that an ordinary frame costs four comparisons.

    Parameters
    ----------
    journal : numpy.ndarray
        The loop's buffer (``State.journal``, :data:`ROWS` x :data:`WIDTH`), appended to.
    journal_n : numpy.ndarray
        (2,) int64: rows written, and rows lost to a full buffer.
    seen : numpy.ndarray
        What the loop last saw (``State.journal_seen``), updated.
    frame : int
        The frame the entry happened in (the mission's clock).
    star_in_use : bool
        The tracker's outputs are switched into the control amplifiers
        (S12/S13); the entries carry it.
    """
    if lock[trk.NEW_REFUSAL] != trk.NONE:
        _write(journal, journal_n, frame, LOCK_REJECTED, 0, lock[trk.NEW_REFUSAL],
               lock[trk.REFUSED_CONE_ARCSEC], 0.0, star_in_use)
    if lock[trk.NEW_DROP] != trk.NONE:
        _write(journal, journal_n, frame, LOCK_DROPPED, 0, lock[trk.NEW_DROP],
               lock[trk.SEEN_MAG], 0.0, star_in_use)
    if star != seen[SEEN_STAR]:
        _write(journal, journal_n, frame, STAR_LOCK, 0, star, seen[SEEN_STAR],
               cone_arcsec if star != -1 else 0.0, star_in_use)
        seen[SEEN_STAR] = star
    mask = (overflow[0] | (overflow[1] << 1) | (overflow[2] << 2) | (overflow[3] << 3)
            | (overflow[4] << 4) | (overflow[5] << 5))
    if mask != seen[SEEN_OVERFLOW]:
        was = int(seen[SEEN_OVERFLOW])
        for i in range(6):
            if (mask >> i) & 1 and not (was >> i) & 1:
                _write(journal, journal_n, frame, SATURATION, COUNTER_OVERFLOW, i, 1.0, 0.0, 0.0)
        seen[SEEN_OVERFLOW] = mask


@njit_stage
def note_glare(journal, journal_n, frame, active, held, cos_incidence, star_in_use):
    """Sunlit Earth entering (``active``) or leaving star tracker 105's slit.

    ``held`` is the target the tracker held as it was blinded (-1 none,
    :data:`FALSE_TARGET`), ``cos_incidence`` the cosine of the Sun's
    incidence at the slit's most directly lit point of the Earth;
    ``star_in_use``: S12 or S13 closed. ``journal``, ``journal_n`` and
    ``frame`` are :func:`note_frame`'s.
    """
    _write(journal, journal_n, frame, EARTH_GLARE, 0, held if active else -1,
           1.0 if active else 0.0, cos_incidence, star_in_use)


@njit_stage
def note_clip(journal, journal_n, seen, frame, drift_counters, drift_gate, dac_hi, dac_lo):
    """A drift DAC 7/9/11 starting or ceasing to apply its full scale, not the count.

    ``drift_gate`` (3,) is 1.0 where S1-S3 feed the DACs, whose codes span
    ``dac_lo .. dac_hi``. The frame loop calls it when a leg starts (S1-S3
    move only between legs), every frame of a leg that counts drift into a
    fed DAC, and after a fault's upset.

    Parameters
    ----------
    journal : numpy.ndarray
        The loop's buffer (``State.journal``, :data:`ROWS` x :data:`WIDTH`), appended to.
    journal_n : numpy.ndarray
        (2,) int64: rows written, and rows lost to a full buffer.
    seen : numpy.ndarray
        What the loop last saw (``State.journal_seen``), updated.
    frame : int
        The frame the entry happened in (the mission's clock).
    drift_counters : numpy.ndarray
        [pulses] drift counters 13, 15, 17: the codes the DACs are fed.
    dac_hi, dac_lo : int
        [pulses] the drift DACs' largest and smallest code (their full scale).
    """
    for a in range(3):
        code = drift_counters[a]
        clip = 1.0 if drift_gate[a] != 0.0 and (code > dac_hi or code < dac_lo) else 0.0
        if clip != seen[SEEN_CLIP + a]:
            applied = dac_hi if code > dac_hi else (max(code, dac_lo))
            _write(journal, journal_n, frame, SATURATION, DAC_CLIP, a, clip, code, applied)
            seen[SEEN_CLIP + a] = clip


@njit_stage
def note_wheels(journal, journal_n, seen, frame, unloading, wheel_h, max_momentum):
    """The unloader starting or stopping, a wheel reaching or leaving its limit.

    Parameters
    ----------
    journal : numpy.ndarray
        The loop's buffer (``State.journal``, :data:`ROWS` x :data:`WIDTH`), appended to.
    journal_n : numpy.ndarray
        (2,) int64: rows written, and rows lost to a full buffer.
    seen : numpy.ndarray
        What the loop last saw (``State.journal_seen``), updated.
    frame : int
        The frame the entry happened in (the mission's clock).
    unloading : int
        1 while the jets unload the wheels.
    wheel_h : numpy.ndarray
        [N m s] each wheel's momentum.
    max_momentum : numpy.ndarray
        [N m s] each wheel's momentum limit.
    """
    if unloading != seen[SEEN_UNLOADING]:
        _write(journal, journal_n, frame, SATURATION, WHEEL_UNLOADING, -1, unloading, 0.0, 0.0)
        seen[SEEN_UNLOADING] = unloading
    for i in range(max_momentum.shape[0]):
        frac = abs(wheel_h[i]) / max_momentum[i]
        was = seen[SEEN_WHEEL + i]
        now = 1.0 if frac >= WHEEL_LIMIT_FRACTION or (was != 0.0 and frac >= WHEEL_LIMIT_RELEASE) \
            else 0.0
        if now != was:
            _write(journal, journal_n, frame, SATURATION, WHEEL_LIMIT, i, now, wheel_h[i],
                   max_momentum[i])
            seen[SEEN_WHEEL + i] = now


@njit_stage
def note_faults(journal, journal_n, seen, first, frame, n, fault_state, onset_row,
                duration_frames):
    """A fault's onset or end: it acts in the frames ``onset <= n < onset + duration``.

    ``first`` is the index in ``seen`` of fault slot 0; the onsets are row
    ``onset_row`` of ``fault_state`` (:data:`allsky.sim.faults.ONSET`).

    Parameters
    ----------
    journal : numpy.ndarray
        The loop's buffer (``State.journal``, :data:`ROWS` x :data:`WIDTH`), appended to.
    journal_n : numpy.ndarray
        (2,) int64: rows written, and rows lost to a full buffer.
    frame : int
        The frame the entry happened in (the mission's clock).
    n : int
        Fault slots in use (the scenario's faults).
    duration_frames : numpy.ndarray
        [frames] how long each fault acts from its onset (``clock.NEVER``: to the end).
    """
    for i in range(n):
        o = fault_state[onset_row, i]
        act = 1.0 if 0.0 <= o <= frame < o + duration_frames[i] else 0.0
        if act != seen[first + i]:
            _write(journal, journal_n, frame, FAULT, 0, i, act, 0.0, 0.0)
            seen[first + i] = act


class Decoder:
    """What the journal's numbers name: star names, faults, wheels, scalings.

    Parameters
    ----------
    star_names : list of str
        The tracker's stars, by index (:func:`allsky.sim.mission.tracker_star_names`).
    faults : list of dict
        The scenario's ``[[faults]]``.
    describe : callable
        A fault in words (:func:`allsky.config.faults.describe`).
    drift_lsb_deg_h : float
        [deg/h] per drift-counter pulse as the drift DACs apply it.
    ck : allsky.clock.ClockParams
        The mission's clock: a row's frame becomes the entry's ``t_s``.
    reference_cone_deg : float
        [deg] cone angle of the planned reference star (refusals carry it).
    cone_check_deg : float
        [deg] ``star_tracker.cone_angle_check_deg``.
    gate_magnitude : float or None
        [mag] the tracker's bright gate (drops carry it); None without a gate.
    """

    def __init__(self, star_names, faults, describe, drift_lsb_deg_h, ck,
                 reference_cone_deg=0.0, cone_check_deg=0.0, gate_magnitude=None):
        self.clock = ck
        self.star_names = list(star_names)
        self.faults = list(faults)
        self.describe = describe
        self.drift_lsb_deg_h = float(drift_lsb_deg_h)
        self.reference_cone_deg = float(reference_cone_deg)
        self.cone_check_deg = float(cone_check_deg)
        self.gate_magnitude = gate_magnitude

    def star(self, index):
        """A star's name; None for no star; "stray light" for a false target.

        ``index`` is the tracker's target index (-1 none, ``FALSE_TARGET``).
        """
        k = int(index)
        if k == FALSE_TARGET:
            return "stray light"
        return self.star_names[k] if 0 <= k < len(self.star_names) else None

    def entry(self, row) -> dict:
        """One row of the loop's buffer as journal fields (all but ``t_s`` and ``mode``).

        ``row`` is a row of :data:`WIDTH` numbers (time, kind, what, index, values).
        """
        kind, what, i = int(row[KIND]), int(row[WHAT]), int(row[INDEX])
        a, b, c = float(row[A]), float(row[B]), float(row[C])
        if kind == STAR_LOCK:
            return {"kind": "star_lock", "star": self.star(i), "previous": self.star(a),
                    "cone_angle_deg": (b * ARCSEC2DEG if i != -1 else None),
                    "in_use": bool(c)}
        if kind == LOCK_REJECTED:
            return {"kind": "lock_rejected", "star": self.star(i),
                    "cone_angle_deg": a * ARCSEC2DEG,
                    "reference_cone_angle_deg": self.reference_cone_deg,
                    "check_deg": self.cone_check_deg, "in_use": bool(c)}
        if kind == LOCK_DROPPED:
            return {"kind": "lock_dropped", "star": self.star(i), "magnitude": a,
                    "gate_magnitude": self.gate_magnitude, "in_use": bool(c)}
        if kind == EARTH_GLARE:
            out = {"kind": "earth_glare", "active": bool(a), "star": self.star(i)}
            if a:
                out.update(cos_incidence=b, surface_brightness_mag_arcsec2=_brightness(b))
            out["in_use"] = bool(c)
            return out
        if kind == FAULT:
            f = self.faults[i]
            return {"kind": "fault", "fault": i, "fault_kind": f["kind"],
                    "text": self.describe(f), "active": bool(a)}
        name = _SATURATION_NAMES[what]
        out = {"kind": "saturation", "what": name, "active": bool(a)}
        if what == DAC_CLIP:
            out.update(block=DRIFT_DAC[i], axis=AXES[i], counted_pulses=int(b),
                       applied_pulses=int(c), counted_deg_h=b * self.drift_lsb_deg_h,
                       applied_deg_h=c * self.drift_lsb_deg_h)
        elif what == COUNTER_OVERFLOW:
            out.update(block=OVERFLOW_NUMERALS[i], axis=AXES[i % 3])
        elif what == WHEEL_LIMIT:
            out.update(block="wheels", wheel=i, momentum_n_m_s=b, limit_n_m_s=c)
        else:
            out.update(block="wheels")
        return out


#: What a ground command's entry may carry beyond its declared fields: any command's own
#: fields, and a fault command's fields of its kind.
COMMAND_FIELDS = frozenset(
    [f for c in GROUND_COMMANDS for f in c.fields + c.optional]
    + [f for k in FAULT_KINDS for f in k.fields + k.optional])


#: kind -> (the fields it may carry, the fields it must), from its declaration
_ALLOWED = {name: (spec.names | (COMMAND_FIELDS if spec.more else frozenset()), spec.required)
            for name, spec in EVENT_KIND.items()}


def check_fields(kind, fields) -> None:
    """Refuse an entry of ``kind`` whose ``fields`` its declaration does not allow.

    Raises ValueError naming an unknown kind, a field the kind does not
    declare (:data:`allsky.vocabulary.EVENT_KINDS`) or one it requires and
    the entry lacks.
    """
    sets = _ALLOWED.get(kind)
    if sets is None:
        raise ValueError(f"unknown journal kind {kind!r}")
    allowed, required = sets
    keys = fields.keys()
    if keys <= allowed and required <= keys:
        return
    unknown = sorted(set(fields) - allowed)
    missing = sorted(required - set(fields))
    raise ValueError(f"journal entry {kind!r}: "
                     + "; ".join(([f"undeclared field(s) {unknown}"] if unknown else [])
                                 + ([f"missing field(s) {missing}"] if missing else [])))


class Journal:
    """The mission's journal: a list of entries in the order they happened.

    Parameters
    ----------
    events : list of dict, optional
        Entries already written (a resumed mission's).
    """

    def __init__(self, events=None):
        self.events = [dict(e) for e in (events or [])]
        #: entries the frame loop could not write (its buffer was full); 0 in any
        #: flight the buffer was sized for
        self.lost = 0

    def note(self, t_s, mode, kind, **fields) -> dict:
        """Append an entry of ``kind`` (:data:`allsky.vocabulary.EVENT_KINDS`); return it.

        ``t_s`` [s] is the mission time, ``mode`` the name of the mode flown
        (None before the first), ``**fields`` the kind's fields.
        """
        check_fields(kind, fields)
        e = {"t_s": float(t_s), "mode": mode, "kind": kind, **fields}
        self.events.append(e)
        return e

    def drain(self, journal, journal_n, mode, decoder: Decoder) -> None:
        """Move the frame loop's rows into the journal and empty its buffer.

        ``journal`` and ``journal_n`` are the buffer and its counts
        (``State.journal``, ``State.journal_n``); the rows are entered in mode
        ``mode``, named by ``decoder`` (:class:`Decoder`). Rows lost to a full
        buffer are added to ``lost``.
        """
        n = int(journal_n[0])
        for row in journal[:n]:
            e = decoder.entry(row)
            kind = e.pop("kind")
            self.note(clock.time_s(decoder.clock, int(row[FRAME])), mode, kind, **e)
        journal[:n] = 0.0  # drained: the buffer holds nothing between slices
        journal_n[0] = 0
        self.lost += int(journal_n[1])
        journal_n[1] = 0

    def of_kind(self, *kinds) -> list:
        """The entries of the given kinds, in order; ``*kinds`` are kind names."""
        return [e for e in self.events if e["kind"] in kinds]

    def __len__(self):
        return len(self.events)


def rate_deg_s(rate_rad_s) -> dict:
    """Body rates ``rate_rad_s`` [rad/s] as ``{roll, pitch, yaw}`` [deg/s]."""
    return {a: float(w) * RAD2DEG for a, w in zip(AXES, rate_rad_s)}


def magnitude(values) -> float:
    """The Euclidean norm of a few numbers, ``values``."""
    return math.sqrt(sum(float(v) ** 2 for v in values))
