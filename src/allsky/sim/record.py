"""The record a flight leaves: summary, calibration, targets, end and snapshot.

A mission (:class:`allsky.sim.mission.Mission`) owns its record and drives
it; these functions read what the mission holds (its state, scenario,
parameters, journal, timeline and target log) and write the summary, the
truth at the end and the snapshot it resumes from, without importing the
mission. The summary's fields are declared in :data:`SUMMARY_FIELDS` (name,
unit, meaning) and checked where the summary is written; the journal's
kinds declare theirs in :data:`allsky.vocabulary.EVENT_KINDS`, and the
telemetry its columns in :mod:`allsky.sim.telemetry`.
"""

from typing import NamedTuple

import numpy as np

from allsky import clock, units
from allsky.computer import word_registers as wr
from allsky.config import faults as fault_config
from allsky.hardware import gyro, star_tracker
from allsky.hardware.dac import dac
from allsky.sim import faults as sim_faults
from allsky.sim import journal, results, sky_rows
from allsky.sim import state as sim_state
from allsky.sim.braking import flight_warning
from allsky.sim.telemetry import INDEX
from allsky.vehicle import environment, wheels
from allsky.vocabulary import AXES

#: The layout of a snapshot; 4 since the clock became the frame index (a format-3
#: state's times were summed floats, and its leg clock seconds).
STATE_FORMAT = 4
#: The telemetry's time column.
TIME = INDEX["time"]


class SummaryField(NamedTuple):
    """One top-level field of the ``--json`` summary."""

    name: str  #: its key
    unit: str  #: its unit ("" for a name, a flag, an object or a list)
    meaning: str  #: in words
    always: bool = True  #: every summary carries it


S = SummaryField
#: The summary's fields (docs/journal.md shows the summary; apps/summaries checks a file
#: read back against the part of them the figures and the page use).
SUMMARY_FIELDS = (
    S("status", "", "the sequencer's judgement: `running`, `complete`, `aborted`, or `ended`"),
    S("abort_reason", "", "why the mission aborted (null otherwise)"),
    S("modes", "", "the timeline: `mode`, `start_s`, `end_s` [s] and `exit` of each mode"),
    S("calibration", "", "what the mission stored: drift [deg/h], register 23's words; null "
                         "before Mode 5 (or the dither mode) ended"),
    S("truth", "", "the calibration a perfect computer would store"),
    S("calibration_applied", "", "`calibration.apply`"),
    S("target", "", "the first target: programmed angles [deg], true pointing error [arcsec]"),
    S("propellant_kg", "kg", "propellant used since ejection"),
    S("mission_time_s", "s", "the time the flight stands at"),
    S("seed", "", "`mission.seed`"),
    S("reference_star", "", "`star_tracker.reference_star`"),
    S("locked_star", "", "the star the tracker held at the loop's last use"),
    S("counter_overflow", "", "per counter, whether it overflowed (latched)"),
    S("drift_dac_clipped", "", "per axis, whether the drift count is beyond its DAC's scale"),
    S("end", "", "the truth at the end of the flight (:func:`end`)"),
    S("hold", "", "the hold on the first target's measurements", False),
    S("faults", "", "the scenario's faults, each with its `onset_s` [s]", False),
    S("targets", "", "every target begun, in flight order (:func:`targets`)"),
    S("wheels", "", "the reaction wheels at the end (a wheel vehicle)", False),
    S("orbit", "", "the orbit's part (a mission in orbit)", False),
    S("warnings", "", "one sentence for each thing a reader must not miss"),
    S("events", "", "the journal (docs/journal.md)"),
)
del S
#: Summary field name -> :class:`SummaryField`.
SUMMARY_FIELD = {f.name: f for f in SUMMARY_FIELDS}


def check_summary(out) -> dict:
    """Refuse a summary ``out`` with a field :data:`SUMMARY_FIELDS` does not declare.

    Also one without a field every summary carries. Returns ``out``.
    """
    unknown = sorted(set(out) - set(SUMMARY_FIELD))
    missing = sorted(f.name for f in SUMMARY_FIELDS if f.always and f.name not in out)
    if unknown or missing:
        raise ValueError(f"summary: undeclared field(s) {unknown}, missing {missing}")
    return out


#: The last scenario :func:`tracker_star_names` was asked for, and its names (a scenario
#: is immutable; the summary asks twice, a live session at every lock).
_NAMES_OF = [None, ()]


def tracker_star_names(cfg) -> list:
    """Names of the stars the tracker can lock, in the order of ``Params.tracker``.

    ``cfg`` is the scenario: its magnitude window, date, moving bodies and wrong-star faults.
    """
    if _NAMES_OF[0] is not cfg:
        names = sky_rows.sky_rows(cfg).names  # the window's stars, then the bodies flown
        # A wrong star (a fault) is tracked after them (allsky.sim.faults).
        _NAMES_OF[:] = [cfg, tuple(names + [s for s in sim_faults.wrong_stars(cfg.faults)
                                            if s not in names])]
    return list(_NAMES_OF[1])


class ModeRecord(NamedTuple):
    """One line of the mode timeline.

    Examples
    --------
    >>> import allsky
    >>> m = allsky.Mission(allsky.load_scenario())
    >>> record = m.run_mode()                       # Mode 1: Sun orientation
    >>> record.mode, record.start_s, record.end_s   # [s]
    ('1', 0.0, 187.3)
    >>> record.exit
    'sun pitch and yaw settled; S14, S15 closed'
    """

    mode: str  #: the mode's name in the mode table ("1" ... "6-2", "dither", ...)
    start_s: float  #: [s] mission time the mode started
    end_s: float  #: [s] mission time it ended
    #: how it ended: the mode's exit text, "aborted: ..." or "ended by ground command: ..."
    exit: str


def target_name(spec) -> str:
    """A target's name: the star's, or its RA and Dec [deg].

    ``spec`` is a target as :func:`target_specs` gives one.
    """
    if "star" in spec:
        return spec["star"]
    return f"RA {spec['ra_deg']:g} deg, Dec {spec['dec_deg']:+g} deg"


def new_target_record(cfg, index, start_s) -> dict:
    """The record of target ``index`` as its flight begins at ``start_s`` [s].

    ``cfg`` is the scenario, whose targets :func:`target_specs` lists.

    Keys: name, the target (star, or ra_deg and dec_deg), start_s and end_s
    [s], programmed_roll_deg and programmed_yaw_deg; at the end of its Mode
    6-2, where the sequencer declares it on target, the truth beside the
    computer's judgement: pointing_error_arcsec (true), body_rate_deg_s
    (true) and computed_error_arcsec (CPU 22's); hold (the hold's
    measurements) and hold_end_pointing_error_arcsec, locked_star; None until
    known. A target flown from the one before on the gyros
    (``sequencer.between_targets = "direct"``) gains turn_roll_deg and
    turn_yaw_deg, the turn CPU 22 formed (:meth:`Mission.targets`).
    """
    spec = target_specs(cfg)[index]
    return {"name": target_name(spec), **spec, "start_s": float(start_s), "end_s": None,
            "programmed_roll_deg": None, "programmed_yaw_deg": None,
            "pointing_error_arcsec": None, "body_rate_deg_s": None,
            "computed_error_arcsec": None, "hold_end_pointing_error_arcsec": None,
            "hold": None, "locked_star": None}


def restore(m, h) -> None:
    """Set mission ``m``'s record from a snapshot's history ``h`` ({}: a new one).

    The inverse of :func:`snapshot`: the timeline, leg count, counted angles,
    status, programmed angles and turns, the reference Sun, the hold, the
    target records, the star last held and the journal.
    """
    m.timeline = [ModeRecord(*r) for r in h.get("timeline", [])]
    m.leg_count = int(h.get("leg_count", 0))
    m.counted_arcsec = dict(h.get("counted_arcsec", {}))
    m.status = h.get("status", "running")
    m.abort_reason = h.get("abort_reason")
    m.programmed_roll_deg = h.get("programmed_roll_deg")
    m.programmed_yaw_deg = h.get("programmed_yaw_deg")
    # [deg] the turn from the target held to the one flown (between_targets = "direct")
    m.turn_roll_deg = h.get("turn_roll_deg")
    m.turn_yaw_deg = h.get("turn_yaw_deg")
    # The Sun [inertial] the first target's angles were computed for: the reference
    # attitude every target's angles are measured from when flown one from the other
    m.reference_sun_inertial = h.get("reference_sun_inertial")
    # The body axes CPU 22 holds after the turns from target to target ("direct")
    m.held_axes = h.get("held_axes")
    # Measurements of the hold on target (master_sequencer.measure_hold); None if not flown
    m.hold = h.get("hold")
    # One record per target begun (new_target_record); the last is being flown
    m.target_log = [dict(r) for r in h.get("targets", [])] or [new_target_record(m.cfg, 0, 0.0)]
    # The star tracker 105 last held, by name, when a new magnitude window left it out
    m.locked_before = h.get("locked_star_name")
    # What happened, in order
    m.journal = journal.Journal(h.get("events"))


def resume_args(history, arrays, newer) -> tuple:
    """The scenario, state, next mode and history a snapshot resumes with.

    ``history`` and ``arrays`` are the snapshot's two parts (:func:`snapshot`),
    ``newer`` the arrays added since the format's first files, standing for
    what an older file meant (:func:`allsky.sim.mission.newer_state_arrays`).

    Raises
    ------
    ValueError
        A history of another format than :data:`STATE_FORMAT`.
    KeyError
        A state array missing from ``arrays``.
    """
    from allsky.config import scenario_from_dict

    if history.get("format") != STATE_FORMAT:
        raise ValueError(f"a mission state of format {history.get('format')!r}, not "
                         f"{STATE_FORMAT} (format 3 held summed times, before the exact "
                         "clock)")
    # Copies, so that one snapshot can be resumed any number of times; the arrays
    # added since the format's first files stand for what an older file meant.
    arrays = {**newer, **arrays}
    lock = np.asarray(arrays["tracker_lock"], dtype=float)
    if lock.shape[0] < star_tracker.N_LOCK:  # entries added since: as a new lock's
        arrays["tracker_lock"] = np.concatenate([lock, star_tracker.new_lock()[lock.shape[0]:]])
    state = sim_state.State(**{k: np.array(arrays[k], copy=True)
                               for k in sim_state.State._fields})
    cfg = scenario_from_dict(history["scenario"])
    return cfg, state, history["next_mode"], history


def python_of(f):
    """The Python body of a compiled block ``f`` (itself when compiling is off)."""
    return getattr(f, "py_func", f)


def target_specs(cfg) -> list:
    """The scenario's targets in flight order: a star's name or an RA and Dec each.

    Each is ``{"star": name}`` or ``{"ra_deg": ..., "dec_deg": ...}``, from
    ``target.sequence`` when given, else the one target of ``target.star``
    or ``target.ra_deg`` + ``target.dec_deg`` of scenario ``cfg``.
    """
    t = cfg.target
    if t.sequence is not None:
        return [{"star": e} if isinstance(e, str)
                else {"ra_deg": float(e["ra_deg"]), "dec_deg": float(e["dec_deg"])}
                for e in t.sequence]
    if t.star is not None:
        return [{"star": t.star}]
    return [{"ra_deg": t.ra_deg, "dec_deg": t.dec_deg}]


def calibration(m) -> dict:
    """What the mission stored: the drift counted and applied, and register 23.

    ``drift_deg_h`` is what drift counters 13/15/17 counted,
    ``drift_applied_deg_h`` what drift DACs 7/9/11 apply from it: the
    same unless the count is beyond a DAC's full scale
    (:meth:`drift_dac_clipped`).

    ``m`` is the mission (:class:`allsky.sim.mission.Mission`).
    """
    el = m.params.electronics
    lsb = el.drift_lsb_arcsec_s / units.DEG_H2ARCSEC_S
    counted = [float(d * el.drift_lsb_arcsec_s) for d in m.state.drift_counters]
    applied = [float(python_of(dac)(int(d), el.drift_dac_bits, lsb))
               for d in m.state.drift_counters]
    out = {"drift_deg_h": dict(zip(AXES, counted)),
           "drift_applied_deg_h": dict(zip(AXES, applied))}
    out.update(wr.computed_as_dict(m.state.word23))
    return out


def drift_dac_clipped(m) -> dict:
    """Per axis: is the drift count beyond its drift DAC's full scale (7, 9, 11)?

    ``m`` is the mission (:class:`allsky.sim.mission.Mission`).
    """
    bits = m.params.electronics.drift_dac_bits
    return {axis: int(python_of(dac)(int(d), bits, 1)) != int(d)
            for axis, d in zip(AXES, m.state.drift_counters)}


def end(m) -> dict:
    """The truth at the end of the flight (so far): time, target, error, rates, gas.

    Keys: ``t_s`` [s], ``target`` (the last target begun), ``mode`` (the
    last mode flown), ``true_pointing_error_arcsec``, ``body_rate_deg_s``
    (roll, pitch, yaw), ``propellant_kg`` (used since ejection) and
    ``propellant_remaining_kg``.

    ``m`` is the mission (:class:`allsky.sim.mission.Mission`).
    """
    return {"t_s": m.now_s(), "target": m.target_log[-1]["name"],
            "mode": m.current_mode,
            "true_pointing_error_arcsec": float(m.pointing_error_arcsec()),
            "body_rate_deg_s": journal.rate_deg_s(m.state.x[4:7]),
            "propellant_kg": float(m.cfg.jets.propellant_kg
                                   - m.state.propellant_kg[0]),
            "propellant_remaining_kg": float(m.state.propellant_kg[0])}


def summary(m) -> dict:
    """The ``--json`` summary (a stable contract).

    ``target`` is the first target: its programmed angles and its true
    pointing error at the end of its flight (after its hold, if any).
    ``targets`` lists every target begun (:meth:`targets`; one entry for
    a single target), each with the truth where its Mode 6-2 declared it
    on target. Beside the machine's judgement (``status``, the mode
    timeline) stands what happened: ``end`` (:meth:`end`, the truth at
    the end of the flight, the last target flown), ``drift_dac_clipped``
    and ``counter_overflow``, ``warnings`` (one sentence for each thing a
    reader must not miss, :func:`allsky.sim.results.warnings`) and
    ``events``, the journal (:mod:`allsky.sim.journal`).

    ``m`` is the mission (:class:`allsky.sim.mission.Mission`).
    """
    done = [r.mode for r in m.timeline]
    records = m.targets()
    first = records[0]
    if len(records) == 1:
        pointing = m.pointing_error_arcsec() if m.status == "complete" else None
    else:  # the first target's flight has ended
        pointing = (first["hold_end_pointing_error_arcsec"] if first["hold"] is not None
                    else first["pointing_error_arcsec"])
    target = {"programmed_roll_deg": first["programmed_roll_deg"],
              "programmed_yaw_deg": first["programmed_yaw_deg"],
              "pointing_error_arcsec": pointing}
    target.update(target_specs(m.cfg)[0])
    calibration = m.calibration() if ("5" in done or "dither" in done) else None
    out = {
        "status": m.status,
        "abort_reason": m.abort_reason,
        "modes": [{"mode": r.mode, "start_s": r.start_s, "end_s": r.end_s, "exit": r.exit}
                  for r in m.timeline],
        "calibration": calibration,
        "truth": gyro.perfect_calibration(m.params.gyro,
                                          m.params.vfc.integrator_drift_arcsec_s),
        "calibration_applied": m.apply_calibration,
        "target": target,
        "propellant_kg": float(m.cfg.jets.propellant_kg - m.state.propellant_kg[0]),
        "mission_time_s": m.now_s(),
        "seed": int(m.cfg.mission.seed),
        "reference_star": m.cfg.star_tracker.reference_star,
        "locked_star": m.locked_star(),
        "counter_overflow": {
            name: bool(f) for name, f in zip(
                ("counter14", "counter16", "counter18", "drift13", "drift15", "drift17"),
                m.state.overflow)},
        "drift_dac_clipped": m.drift_dac_clipped(),
        "end": m.end(),
    }
    if first["hold"] is not None:
        out["hold"] = first["hold"]
    if m.cfg.faults:
        out["faults"] = [{**f, "onset_s": (clock.time_s(m.params.clock, int(onset))
                                           if onset >= 0.0 else None)}
                         for f, onset in zip(m.cfg.as_dict()["faults"],
                                             m.state.fault_state[sim_faults.ONSET])]
    out["targets"] = records
    if m.cfg.actuators.kind == "wheels":
        out["wheels"] = m.wheel_summary()
    if m.params.orbit.n > 0:
        out["orbit"] = m.orbit_summary()
    out["warnings"] = results.warnings(out, m.journal, fault_config.describe,
                                       m.params.sequencer.settle_threshold_arcsec)
    braking = flight_warning(m.cfg, m.state.propellant_kg[0])
    if braking is not None:  # the scenario's, before any time: first
        out["warnings"].insert(0, braking)
    out["events"] = [dict(e) for e in m.journal.events]
    return check_summary(out)


def glare_edges(journal, ck) -> list:
    """The journal's ``earth_glare`` entries as ``(frame, active)``, in time order.

    ``journal`` is the flight's :class:`allsky.sim.journal.Journal`, ``ck``
    the mission's clock: each entry's frame is the one its time names.
    """
    return [(clock.frame_at(ck, e["t_s"]), e["active"]) for e in journal.of_kind("earth_glare")]


def orbit_summary(m) -> dict:
    """The orbit's part of the summary (a mission in orbit only).

    ``sunlit_fraction`` of the Sun's disk at the end; ``sunlit_margin_s``,
    the time from the end of the flight to the next orbit sunset (the
    onset of the penumbra; 0 in the shadow, None past the orbit's
    samples); ``eclipsed_s`` and ``occulted``, the time spent in the
    shadow and the bodies the Earth hid while flying; ``earth_glare_s``, the
    time sunlit Earth blinded star tracker 105, and ``glare_took_star``,
    whether it took a star the loop was closed on; ``torques``, each
    environment torque's ``peak_n_m`` and ``impulse_n_m_s`` (its
    magnitude integrated over the flight), or None where it is off.

    ``m`` is the mission (:class:`allsky.sim.mission.Mission`).
    """
    o = m.params.orbit
    ck = m.params.clock
    end = m.frame
    horizon = (o.n - 1) * o.step_frames
    dark = environment.first_dark(o, end, horizon)
    margin = None if dark < 0 else clock.time_s(ck, dark - end)
    flown = environment.sunlit_series(o, 0, end)
    keys = {"gravity_gradient": m.cfg.orbit.gravity_gradient,
            "aerodynamic": m.cfg.orbit.aerodynamic,
            "solar_pressure": m.cfg.orbit.solar_pressure}
    torques = {name: ({"peak_n_m": float(o.peak[environment.PEAK, i]),
                       "impulse_n_m_s": float(o.peak[environment.IMPULSE, i])}
                      if on else None) for i, (name, on) in enumerate(keys.items())}
    occulted = sorted({e["body"] for e in m.journal.of_kind("occultation")
                       if e["active"]})
    glare = m.journal.of_kind("earth_glare")
    blinded, since = 0, None  # frames blinded, and the frame the open one began
    for f, active in glare_edges(m.journal, ck):
        if active:
            since = f
        elif since is not None:
            blinded, since = blinded + f - since, None
    if since is not None:
        blinded += end - since
    return {"kind": m.cfg.orbit.kind,
            "sunlit_fraction": float(environment.sunlit_at(o, end)) if end < horizon else None,
            "sunlit_margin_s": margin,
            "eclipsed_s": clock.time_s(ck, int(np.count_nonzero(flown < 1.0))),
            "occulted": occulted,
            "earth_glare_s": clock.time_s(ck, blinded),
            "glare_took_star": any(e["active"] and e["in_use"] and e["star"] is not None
                                   for e in glare),
            "torques": torques}


def wheel_summary(m) -> dict:
    """The reaction wheels at the end: momenta, the largest fraction of a limit held.

    ``m`` is the mission (:class:`allsky.sim.mission.Mission`).
    """
    n = len(m.cfg.wheels.axes)
    h = m.state.wheel_h[:n]
    return {"momentum_n_m_s": [float(x) for x in h],
            "speed_rad_s": [float(x) for x in wheels.wheel_speeds_rad_s(
                m.params.wheels, h, m.state.x[4:7])],
            "peak_momentum_fraction": float(m.state.wheel_peak_fraction[0]),
            "unloading_propellant_kg": float(m.cfg.jets.propellant_kg
                                             - m.state.propellant_kg[0])}


def snapshot(m):
    """The mission at the current mode boundary, as data to keep and resume from.

    :mod:`allsky.apps.states` writes it to a file and reads it back.

    Returns
    -------
    history : dict
        JSON-serialisable: ``format`` (:data:`STATE_FORMAT`), plan, timeline,
        next mode, leg count, counted angles, status, abort reason,
        programmed angles, the scenario (:meth:`Scenario.as_dict`), once
        flown, the hold's measurements and, with several targets, their
        records (:meth:`targets`).
    arrays : dict of numpy.ndarray
        Copies of the state arrays, by :class:`allsky.sim.state.State` field.

    ``m`` is the mission (:class:`allsky.sim.mission.Mission`).
    """
    history = {"format": STATE_FORMAT, "next_mode": m.next_mode, "plan": list(m.plan),
               "timeline": [list(r) for r in m.timeline], "leg_count": m.leg_count,
               "counted_arcsec": m.counted_arcsec, "status": m.status,
               "abort_reason": m.abort_reason,
               "programmed_roll_deg": m.programmed_roll_deg,
               "programmed_yaw_deg": m.programmed_yaw_deg,
               "scenario": m.cfg.as_dict(),
               "events": [dict(e) for e in m.journal.events]}
    if m.hold is not None:
        history["hold"] = m.hold
    for key in ("turn_roll_deg", "turn_yaw_deg", "reference_sun_inertial", "held_axes"):
        if getattr(m, key) is not None:
            history[key] = getattr(m, key)
    if m.locked_before is not None:
        history["locked_star_name"] = m.locked_before
    if len(m.target_log) > 1 or m.cfg.target.sequence is not None:
        history["targets"] = [dict(r) for r in m.target_log]
    arrays = {k: v.copy() for k, v in m.state._asdict().items()}
    return history, arrays


def targets(m) -> list:
    """The record of every target begun (:func:`new_target_record`), in flight order.

    The last one's is completed with what the mission holds now; its
    ``end_s`` is the mission time once the mission is finished.

    ``m`` is the mission (:class:`allsky.sim.mission.Mission`).
    """
    out = [dict(r) for r in m.target_log]
    cur = out[-1]
    hold = m.hold if m.hold is not None and "hold_s" in m.hold else None
    cur.update(programmed_roll_deg=m.programmed_roll_deg,
               programmed_yaw_deg=m.programmed_yaw_deg, hold=hold,
               hold_end_pointing_error_arcsec=(hold["end_pointing_error_arcsec"]
                                               if hold else None),
               locked_star=m.locked_star())
    if m.turn_roll_deg is not None:  # flown from the target before, on the gyros
        cur.update(turn_roll_deg=m.turn_roll_deg, turn_yaw_deg=m.turn_yaw_deg)
    if m.finished:
        cur["end_s"] = m.now_s()
    return out


def on_target(m) -> dict:
    """The truth where Mode 6-2 declares the vehicle on target, and CPU 22's errors.

    Keys: ``pointing_error_arcsec`` (true), ``body_rate_deg_s`` (true,
    per axis), ``computed_error_arcsec`` (CPU 22's roll, pitch and yaw
    errors, what the sequencer judged by).

    ``m`` is the mission (:class:`allsky.sim.mission.Mission`).
    """
    return {"pointing_error_arcsec": m.pointing_error_arcsec(),
            "body_rate_deg_s": journal.rate_deg_s(m.state.x[4:7]),
            "computed_error_arcsec": dict(zip(AXES, map(float, m.state.cpu[3:6])))}


class OrbitJournal:
    """The eclipses and occultations of a flight in orbit, journaled as they pass."""

    def __init__(self):
        self.frame = 0  #: the frame journaled up to
        self.phase = 0  #: 0 sunlit, 1 penumbra, 2 umbra at that frame
        self.hidden = None  #: which bodies the Earth hid at that frame
        self._rows = (None, None, None)  #: (scenario, orbit, their rows): :meth:`_rows_of`

    def _rows_of(self, m):
        """``(names, fixed, moving)`` of mission ``m``'s scenario, kept while it flies.

        The names of the journal's rows (the fixed stars, "target", the
        moving bodies), the fixed stars' directions, the bodies' columns of
        ``orbit.bodies_i``; a scenario and its orbit's samples are never
        changed in place, so a ground command's new ones are new objects.
        """
        cfg, orbit, rows = self._rows
        o = m.params.orbit
        if cfg is not m.cfg or orbit is not o:
            names = tracker_star_names(m.cfg)[:o.stars_inertial.shape[0]]
            fixed = np.setdiff1d(np.arange(len(names)), o.body_rows)  # the stars: fixed rows
            moving = o.body_rows[o.body_rows >= 0]  # the bodies in the window: by interval
            rows = ([*(names[j] for j in fixed), "target", *(names[j] for j in moving)],
                    np.ascontiguousarray(o.stars_inertial[fixed]),
                    np.nonzero(o.body_rows >= 0)[0])
            self._rows = (m.cfg, o, rows)
        return rows


    def note(self, m) -> bool:
        """Journal the eclipses and occultations of mission ``m`` since the last call.

        They depend on the orbit and the date only, not on the attitude: they
        are found from the orbit's samples, interpolated as the frame loop
        interpolates them (:mod:`allsky.vehicle.environment`), frame by frame
        where a row can cross the limb
        (:func:`allsky.vehicle.environment.occultation_steps`).
        Returns whether any entry was written.
        """
        o = m.params.orbit
        first, last = self.frame, m.frame
        if last <= first:
            return False
        self.frame = last
        ck = m.params.clock
        at, phases, fractions, self.phase = environment.eclipse_steps(o, first, last,
                                                                       self.phase)
        wrote = at.shape[0] > 0
        names = ("sunlit", "penumbra", "umbra")
        for k, phase, f in zip(at, phases, fractions):
            m.journal.note(clock.time_s(ck, first + int(k)), m.current_mode, "eclipse",
                           phase=names[phase], active=bool(phase != 0),
                           sunlit_fraction=float(f))
        bodies, stars, moving = self._rows_of(m)
        dirs = np.ascontiguousarray(np.vstack([stars,
                                               np.asarray(m.state.target_inertial)[None]]))
        seen = self.hidden if self.hidden is not None else np.zeros(len(bodies), dtype=bool)
        steps, self.hidden = environment.occultation_steps(o, dirs, moving, first, last, seen)
        for k, j, active in steps:
            m.journal.note(clock.time_s(ck, first + int(k)), m.current_mode, "occultation",
                           body=bodies[j], active=bool(active))
            wrote = True
        return wrote


class TelemetryRecord:
    """A flight's telemetry, kept leg by leg, and the row of its last frame.

    ``n_columns`` is the telemetry's width (:data:`allsky.sim.telemetry.COLUMNS`).
    The frame loop writes a slice's decimated rows into a buffer whose last
    row is the slice's last frame (:func:`allsky.sim.recorder.record_last_row`);
    :meth:`slice` keeps both, :meth:`end_leg` closes a leg, :meth:`rows` reads
    the record.
    """

    def __init__(self, n_columns):
        self.n_columns = n_columns
        self.legs = []  #: each leg's rows flown
        self.leg = []  #: the leg in flight, slice by slice
        self.last = None  #: the row of the last frame flown (None before the first slice)

    def slice(self, buf, filled) -> None:
        """Keep the ``filled`` rows a slice wrote into ``buf``, and its last frame's."""
        if filled[0]:
            self.leg.append(buf[: filled[0]].copy())
            filled[0] = 0
        if len(buf) and not np.isnan(buf[-1, TIME]):  # written when the slice ended
            self.last = buf[-1].copy()

    def end_leg(self, every) -> np.ndarray:
        """Close the leg in flight (kept if ``every`` > 0: it recorded); returns its rows."""
        rows = np.vstack(self.leg) if self.leg else np.empty((0, self.n_columns))
        self.leg = []
        if every and len(rows):
            self.legs.append(rows)
        return rows

    def rows(self, start_row=0, ended=False) -> np.ndarray:
        """The rows from ``start_row`` on; with ``ended`` the last frame's row closes them.

        That row is added when the flight ended between two decimated rows,
        so that the record ends at the flight's exact last frame.
        """
        pieces, skip = [], int(start_row)
        every = [*self.legs, *self.leg]
        if ended and self.last is not None:
            tail = next((p[-1, TIME] for p in reversed(every) if len(p)), -np.inf)
            if self.last[TIME] > tail:
                every.append(self.last[None, :])
        for piece in every:
            if skip >= len(piece):
                skip -= len(piece)
                continue
            pieces.append(piece[skip:])
            skip = 0
        if not pieces:
            return np.empty((0, self.n_columns))
        return np.vstack(pieces)
