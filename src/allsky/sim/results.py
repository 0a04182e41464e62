"""What a mission stored against the truth, and what a reader must not miss.

One place for the "stored minus truth" arithmetic that the report, the
comparison, the Monte Carlo rows and the figures all show
(:func:`calibration_errors`), for the warnings the summary carries beside
the machine's own judgement (:func:`warnings`), and for flying a mission
while measuring its calibration modes (:func:`fly_calibrating`).
"""


from allsky import xmath
from allsky.units import FRACTION2PPM, RAD2ARCSEC
from allsky.vocabulary import AXES, CROSS_COUPLING_KEYS, SCALE_FACTOR_AXES


def calibration_errors(calibration: dict, truth: dict) -> dict:
    """Stored minus true calibration, in the units people read them in.

    Parameters
    ----------
    calibration, truth : dict
        The summary's ``calibration`` (drift DACs and register 23) and
        ``truth`` (:meth:`allsky.sim.mission.Mission.summary`).

    Returns
    -------
    dict
        ``drift_deg_h`` per axis [deg/h] (of what drift DACs 7/9/11 apply),
        ``scale_factor_ppm`` for roll and
        yaw [ppm], ``cross_coupling_arcsec`` per factor [arcsec].
    """
    # The error of what the drift DACs apply (the count, unless beyond a DAC's full scale).
    drift = calibration.get("drift_applied_deg_h", calibration["drift_deg_h"])
    return {
        "drift_deg_h": {a: drift[a] - truth["drift_deg_h"][a] for a in AXES},
        "scale_factor_ppm": {
            a: FRACTION2PPM * (calibration["scale_factor"][a] - truth["scale_factor"][a])
            for a in SCALE_FACTOR_AXES},
        "cross_coupling_arcsec": {
            k: RAD2ARCSEC * (calibration["cross_coupling"][k] - truth["cross_coupling"][k])
            for k in CROSS_COUPLING_KEYS},
    }


def fly_calibrating(m, cal_modes, on_start=None, on_end=None, hooks=None):
    """Fly ``m`` to its end, measuring its calibration modes ``cal_modes`` on the way.

    The excursion is measured from the attitude at the start of the first
    calibration mode to the end of the last. ``m`` is the mission
    (:class:`allsky.sim.mission.Mission`) and ``cal_modes`` the names of its
    calibration modes in flight order. ``on_start``, if given, is called as
    ``on_start(m)`` as the first begins; ``on_end`` as ``on_end(m)`` after the
    last, and the flight stops there if it returns False. ``hooks``
    (:class:`allsky.sim.mission.Hooks`) are passed to each mode flown (a study
    recording the legs).

    Returns
    -------
    tuple
        Calibration time [s], its propellant [kg] and each calibration
        mode's duration [s] by name.
    """
    t_cal, prop, durations = 0.0, 0.0, {}
    while not m.finished:
        name = m.plan[m.next_mode]
        if name == cal_modes[0]:
            m.track_excursion()
            if on_start is not None:
                on_start(m)
        p0 = m.state.propellant_kg[0]
        rec = m.run_mode(hooks)
        if name in cal_modes:
            t_cal += rec.end_s - rec.start_s
            durations[name] = rec.end_s - rec.start_s
            prop += p0 - m.state.propellant_kg[0]
        if name == cal_modes[-1]:
            m.track_excursion(False)
            if on_end is not None and on_end(m) is False:
                break
    return t_cal, prop, durations


#: [deg/s] A vehicle that Mode 6-2 declares on target while turning faster than this about
#: any axis is not on target: it will not stay there.
ON_TARGET_RATE_DEG_S = 0.01
#: A true pointing error more than this many times the computer's own is worth a warning.
TRUTH_FACTOR = 10.0
#: Fault kinds that blind the computer to a turn (its counters follow the gyros).
GYRO_FAULTS = ("gyro_stuck", "gyro_dead", "gyro_bias_step", "gyro_scale_factor_step",
               "counter_upset")


def _acting_faults(summary, t_s) -> list:
    """The scenario's faults acting at mission time ``t_s`` [s], as in the summary."""
    out = []
    for f in summary.get("faults") or []:
        onset = f.get("onset_s")
        if onset is not None and onset <= t_s < onset + f.get("duration_s", float("inf")):
            out.append(f)
    return out


def _likely_cause(summary, t_s, describe) -> str:
    hit = [f for f in _acting_faults(summary, t_s) if f["kind"] in GYRO_FAULTS]
    if hit:
        return "; ".join(f"{describe(f)} since {f['onset_s']:.1f} s" for f in hit)
    return ("a gyro or counter that does not see the turn (the computer's errors come from "
            "the counters)")


#: The register 23 word each calibration turn stores its scale factor in, by axis.
_SCALE_WORD = {"roll": "sf_roll", "yaw": "sf_yaw"}


def _held_at(locks, t_s):
    """The star the journal's ``star_lock`` entries ``locks`` say is held at ``t_s`` [s]."""
    held = None
    for e in locks:
        if e["t_s"] > t_s:
            break
        held = e["star"]
    return held


def wrong_star_calibrations(summary, journal) -> list:
    """``(t_s, sentence)`` for each calibration turn made on a star not the reference.

    ``summary`` is the summary being built, ``journal`` the mission's journal.

    A roll (Mode 4) or yaw (Mode 5) calibration turn is flown from the star
    held as it begins to the star held when calibration sequencer 19 stores
    register 23; either one other than ``summary["reference_star"]`` makes
    the turn's scale factor wrong by the angle between them. The sentence
    names the star and the scale factor's error against the truth [ppm].
    """
    reference = summary.get("reference_star")
    truth = summary.get("truth")
    if reference is None:
        return []
    locks = [e for e in journal.events if e["kind"] == "star_lock"]
    starts = {e["mode"]: e["t_s"] for e in journal.events if e["kind"] == "mode_start"}
    out = []
    for e in journal.events:
        if e["kind"] != "register" or e.get("word") not in _SCALE_WORD.values():
            continue
        axis = next(a for a, w in _SCALE_WORD.items() if w == e["word"])
        start = _held_at(locks, starts.get(e["mode"], e["t_s"]) - 1e-9)
        end = _held_at(locks, e["t_s"])
        wrong = [k for k in dict.fromkeys((start, end)) if k is not None and k != reference]
        if not wrong:
            continue
        stored = e["value"]
        true = truth["scale_factor"][axis] if truth else 1.0
        path = f"from {start or 'no star'} to {end or 'no star'}" if start != end \
            else "held through the turn"
        text = (f"{axis} calibration at {e['t_s']:.1f} s on "
                f"{' and '.join(wrong)} ({path}), not the reference star {reference}: "
                f"{axis} scale factor {stored:.4f} against the true {true:.4f}, "
                f"{FRACTION2PPM * (stored - true):+.0f} ppm in every {axis} the computer "
                "programs")
        out.append((e["t_s"], text))
    return out


class _Timed:
    """Warnings as they are found, each with its time."""

    def __init__(self):
        self.timed = []

    def append(self, t_s, text):
        self.timed.append({"t_s": float(t_s), "text": text})


def warnings(summary, journal, describe, settle_threshold_arcsec) -> list:
    """What a reader of the summary must not miss, one sentence each.

    The sentences of :func:`timed_warnings`, in the order of the times they
    name; ``summary``, ``journal``, ``describe`` and
    ``settle_threshold_arcsec`` are as there.
    """
    return [w["text"] for w in timed_warnings(summary, journal, describe,
                                              settle_threshold_arcsec)]


def timed_warnings(summary, journal, describe, settle_threshold_arcsec) -> list:
    """The warnings with the mission time each is about: ``[{"t_s", "text"}, ...]``.

    From the journal and the summary: a drift DAC that applies its full scale
    instead of the count; a counter that overflowed; a wheel held at its
    momentum limit; a vehicle that Mode 6-2 declares on target while it
    still turns faster than :data:`ON_TARGET_RATE_DEG_S`, with the likely
    cause; a true pointing error more than :data:`TRUTH_FACTOR` times the
    computer's own (taken as at least the sequencer's settle threshold, the
    bound its judgement "settled" claims); a calibration made on a star other
    than the reference star (:func:`wrong_star_calibrations`); journal
    entries lost.

    Parameters
    ----------
    summary : dict
        The summary being built (:meth:`allsky.sim.mission.Mission.summary`):
        its ``modes``, ``targets`` and ``faults``.
    journal : allsky.sim.journal.Journal
        The mission's journal.
    describe : callable
        A fault in words (:func:`allsky.config.faults.describe`).
    settle_threshold_arcsec : float
        [arcsec] ``sequencer.settle_threshold_arcsec``.

    Returns
    -------
    list of dict
        ``t_s`` [s] (when the saturation began, or where Mode 6-2 declared
        the target reached; the end of the flight for lost entries) and
        ``text``, sorted by time.
    """
    out = _Timed()
    dacs = {}
    for e in journal.of_kind("register"):
        if "counted_pulses" in e:
            dacs[e["register"]] = e
    for numeral, e in dacs.items():
        if e["pulses"] != e["counted_pulses"]:
            lsb = e["value"] / e["pulses"] if e["pulses"] else 0.0
            out.append(e["t_s"], f"drift DAC {numeral} ({e['word']}) is clipped since {e['t_s']:.1f} s: "
                       f"the drift counted is {e['counted_pulses'] * lsb:+.4f} deg/h, the DAC "
                       f"applies its full scale {e['value']:+.4f} deg/h, so "
                       f"{(e['counted_pulses'] - e['pulses']) * lsb:+.4f} deg/h of drift is "
                       "left uncompensated")
    for e in journal.of_kind("saturation"):
        if e["what"] == "counter_overflow" and e["active"]:
            out.append(e["t_s"], f"counter {e['block']} ({e['axis']}) overflowed at {e['t_s']:.1f} s "
                       f"in Mode {e['mode']}: the angle it holds is wrong from then on")
        elif e["what"] == "wheel_momentum_limit" and e["active"]:
            out.append(e["t_s"], f"reaction wheel {e['wheel'] + 1} reached its momentum limit "
                       f"({e['limit_n_m_s']:g} N m s) at {e['t_s']:.1f} s in Mode "
                       f"{e['mode']}: it could not take up more momentum")
    declared = [r for r in summary["modes"] if r["mode"] == "6-2"
                and not r["exit"].startswith("aborted")]
    reached = [t for t in summary["targets"] if t.get("body_rate_deg_s") is not None]
    for rec, tgt in zip(declared, reached, strict=False):
        t_s = rec["end_s"]
        rates = tgt["body_rate_deg_s"]
        axis = max(rates, key=lambda a: abs(rates[a]))
        if abs(rates[axis]) > ON_TARGET_RATE_DEG_S:
            out.append(t_s, f"Mode 6-2 declared the vehicle on {tgt['name']} at {t_s:.1f} s while "
                       f"it turned at {rates[axis]:+.3f} deg/s about {axis}: the computer's "
                       f"errors settled, the vehicle did not; likely cause: "
                       f"{_likely_cause(summary, t_s, describe)}")
        computed = tgt.get("computed_error_arcsec") or {}
        own = xmath.hypot(computed.get("pitch", 0.0), computed.get("yaw", 0.0))
        bound = max(own, settle_threshold_arcsec)
        true = tgt.get("pointing_error_arcsec")
        if true is not None and true > TRUTH_FACTOR * bound:
            out.append(t_s, f"on {tgt['name']} at {t_s:.1f} s the true pointing error is "
                       f"{true:.1f} arcsec, {true / bound:.0f} times what the computer "
                       f"judged ({own:.1f} arcsec, settle threshold "
                       f"{settle_threshold_arcsec:g} arcsec)")
    for t_s, text in wrong_star_calibrations(summary, journal):
        out.append(t_s, text)
    eclipses = journal.of_kind("eclipse")
    if summary.get("status") == "aborted" and eclipses and eclipses[-1]["phase"] == "umbra":
        e = eclipses[-1]
        out.append(e["t_s"], f"the mission aborted in orbit night: the Earth's shadow has hidden "
                   f"the Sun since {e['t_s']:.1f} s (Mode {e['mode']}), and sun sensor 104 "
                   "sees no Sun in the umbra")
    if journal.lost:
        out.append(summary.get("mission_time_s", 0.0),
                   f"the journal lost {journal.lost} entries the frame loop could not hold")
    return sorted(out.timed, key=lambda w: w["t_s"])
