"""A mission: vehicle, electronics and master sequencer, built from a scenario.

:class:`Mission` builds the frame loop's parameters from a validated
scenario, runs the modes one at a time (:meth:`Mission.run_mode`) or all of
them (:meth:`Mission.run`), and gives a snapshot at any mode boundary to
resume from (:meth:`Mission.snapshot`, :meth:`Mission.from_snapshot`; the
state files are :mod:`allsky.apps.states`). A scenario with several targets
(``target.sequence``) flies them one after the other in one plan
(:func:`allsky.sequencer.modes.mission_plan`); the mission keeps a record of
each (:meth:`Mission.targets`). :func:`run_mission` is the library function
behind ``allsky run``.
"""

import math
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from allsky import clock, units, xmath
from allsky.computer import targeting
from allsky.computer import word_registers as wr
from allsky.config import faults as fault_config
from allsky.config.cross_rules import longest_mission_s
from allsky.hardware import (
    control_amp,
    gyro,
    jets,
    pwpf,
    star_tracker,
    sun_acquisition,
    sun_sensor,
    updown_counter,
    vfc,
    wiring,
)
from allsky.hardware.dac import dac
from allsky.sequencer import dither, legs, modes
from allsky.sequencer import master_sequencer as ms
from allsky.sequencer.watch import sensors_in_use
from allsky.sim import board, frame_loop, journal, results
from allsky.sim import faults as sim_faults
from allsky.sim import state as sim_state
from allsky.sim.braking import flight_warning
from allsky.sim.telemetry import COLUMNS, INDEX
from allsky.vehicle import environment, orbit, plant, quaternion, sky, wheels
from allsky.vocabulary import AXES

#: The telemetry's time column.
TIME = INDEX["time"]

EXIT_TEXT = {
    legs.EXIT_PROPELLANT: "propellant exhausted",
    legs.EXIT_SUN_LOST: "Sun lost",
    legs.EXIT_STAR_LOST: "star lost",
}
#: The layout of a snapshot; 4 since the clock became the frame index (a format-3
#: state's times were summed floats, and its leg clock seconds).
STATE_FORMAT = 4
# The plans and the mode names, codes and titles live in the mode table
# (allsky.sequencer.modes); here under the names scripts know.
LEGACY_PLAN = modes.LEGACY_PLAN
DITHER_PLAN = modes.DITHER_PLAN
MODE_CODE = modes.MODE_CODE
MODE_TITLE = modes.MODE_TITLE
# [s] expected time from the end of the 6-1 roll to its settling (for the Sun prediction)
SETTLE_ALLOWANCE_S = 30.0
#: Frames the compiled loop runs before it returns to Python (a pause that does not change
#: the flight): 1e5 frames take about 0.05 s at the measured 0.4-0.5 us per frame, so a
#: Ctrl-C is honoured and the progress line moves well within 0.5 s.
SLICE_FRAMES = 100_000


def _python(f):
    """The Python body of a compiled block (itself when compiling is off)."""
    return getattr(f, "py_func", f)


class Hooks(NamedTuple):
    """What a front end or a study asks to hear while a mission flies (all optional).

    Passed to :meth:`Mission.run_mode` and :meth:`Mission.run`, never set on
    the mission: the flight is the same with or without them.
    """

    #: [s] of mission time between calls of ``on_pause`` inside legs (None: no pauses)
    pause_every_s: float | None = None
    #: ``on_pause(m, leg_text)`` every ``pause_every_s`` (:mod:`allsky.apps.step`), and at
    #: ``pause_at``
    on_pause: Callable | None = None
    #: ``on_slice(m, leg_text)`` after each slice of :data:`SLICE_FRAMES` frames or fewer
    #: (the progress line)
    on_slice: Callable | None = None
    #: ``before_leg(m, mode, leg_text) -> bool | None``: before each leg; its answer, when
    #: not None, says whether the leg records telemetry (a study recording some modes only)
    before_leg: Callable | None = None
    #: ``after_leg(m, mode, leg_text, rows)``: after each leg (also one that failed), with
    #: the telemetry rows it recorded
    after_leg: Callable | None = None
    #: ``pause_at(m) -> float``: [s] the mission time of the next call of ``on_pause``
    #: inside a leg, asked again after each pause (a live session's slices, the times of a
    #: saved session's commands: :mod:`allsky.sim.commands`)
    pause_at: Callable | None = None


#: No hooks: the flight straight through.
NO_HOOKS = Hooks()


class ModeRecord(NamedTuple):
    """One line of the mode timeline."""

    mode: str  #: the mode's name in the mode table ("1" ... "6-2", "dither", ...)
    start_s: float  #: [s] mission time the mode started
    end_s: float  #: [s] mission time it ended
    #: how it ended: the mode's exit text, "aborted: ..." or "ended by ground command: ..."
    exit: str


def orbit_span_s(cfg) -> float:
    """[s] how long ``cfg``'s orbit samples cover: the longest mission, an hour more.

    The hour is room for what lengthens a mission past its modes' timeouts
    (a recovery, ground commands); past the last sample the vehicle is held
    where it was (the environment stops moving).
    """
    flat = {f"{sec}.{k}": v for sec, table in cfg.as_dict().items() if isinstance(table, dict)
            for k, v in table.items()}
    flat.setdefault("target.sequence", None)
    return longest_mission_s(flat) + 3600.0


def build_params(cfg) -> sim_state.Params:
    """Frame-loop parameters from a validated scenario ``cfg``."""
    ck = clock.clock(cfg.mission.frame_s)
    dt = ck.num / ck.den
    s0, sdot = sky.sun_motion(cfg.mission.date_utc)
    lo, hi = cfg.star_tracker.magnitude_window
    stars = sky.stars_in_magnitude_window(lo, hi, cfg.mission.date_utc)
    stars_inertial = np.array([sky.radec_to_unit(s.ra_deg, s.dec_deg) for s in stars],
                              dtype=float).reshape(-1, 3)
    st = cfg.star_tracker
    tracker = star_tracker.make_params(
        st.fov_long_half_deg * units.DEG2RAD, st.fov_narrow_half_deg * units.DEG2RAD,
        float(st.noise_arcsec), stars_inertial, [s.magnitude for s in stars], (lo, hi),
        reference_cone_deg(cfg) * units.DEG2RAD, st.cone_angle_check_deg * units.DEG2RAD,
        bool(st.bright_gate), *gate_stars(cfg))
    el = cfg.electronics
    track, step = orbit.track(cfg, ck, orbit_span_s(cfg))
    return sim_state.Params(
        frame_s=dt,
        clock=ck,
        telemetry_every=int(cfg.mission.telemetry_every_frames),
        sun0_inertial=s0, sun_rate_inertial=sdot,
        plant=plant_params(cfg),
        gyro=gyro.make_params(cfg.gyro.drift_deg_h, cfg.gyro.scale_factor_error_ppm,
                              cfg.gyro.misalignment_arcsec, cfg.gyro.arw_deg_rt_h,
                              cfg.gyro.rrw_deg_h_rt_h, cfg.gyro.range_deg_s),
        sun=sun_sensor.SunSensorParams(
            float(cfg.sun_sensor.linear_range_arcsec),
            xmath.cos(cfg.sun_sensor.presence_half_angle_deg * units.DEG2RAD),
            float(cfg.sun_sensor.noise_arcsec), cfg.sun_sensor.coarse_noise_deg * units.DEG2RAD),
        tracker=tracker,
        vfc=vfc.VfcParams(float(el.vfc_pulse_weight_arcsec), float(el.vfc_max_rate_pps),
                          tuple(float(d) * units.DEG_H2ARCSEC_S
                                for d in el.integrator_drift_deg_h)),
        electronics=sim_state.ElectronicsParams(
            counter_bits=int(el.counter_bits), drift_counter_bits=int(el.drift_counter_bits),
            overflow_mode=(updown_counter.WRAP if el.counter_overflow == "wrap"
                           else updown_counter.SATURATE),
            drift_dac_bits=int(el.drift_dac_bits),
            drift_lsb_arcsec_s=el.vfc_pulse_weight_arcsec / cfg.sequencer.drift_count_s,
            register_bits=int(el.register_bits),
            register_lsb_arcsec=float(el.register_lsb_arcsec),
            rate_command_arcsec_s=el.rate_command_deg_s * units.DEG2ARCSEC,
            computer_step_frames=int(el.computer_step_frames)),
        control=control_amp.ControlParams(
            np.array(cfg.control.position_gain_v_per_arcsec, dtype=float),
            np.array(cfg.control.rate_gain_v_per_arcsec_s, dtype=float),
            np.array(cfg.control.position_limit_arcsec, dtype=float),
            float(cfg.control.output_limit_v), float(cfg.control.integral_time_s),
            float(cfg.control.integral_limit_arcsec)),
        pwpf=pwpf.make_params(cfg.pwpf.filter_gain, cfg.pwpf.time_constant_s,
                              cfg.pwpf.on_threshold_v, cfg.pwpf.off_threshold_v,
                              cfg.pwpf.full_on_v, cfg.jets.min_on_time_s, dt),
        jets=jets.make_params(cfg.jets.thrust_n, cfg.jets.moment_arm_m, cfg.jets.isp_s,
                              cfg.jets.supply, cfg.jets.tank_pressure_initial_bar,
                              cfg.jets.tank_pressure_final_bar, cfg.jets.propellant_kg),
        mode1=sun_acquisition.SunAcquisitionParams(
            float(cfg.sequencer.mode1_slew_gain_per_s),
            cfg.sequencer.mode1_slew_rate_deg_s * units.DEG2ARCSEC),
        sequencer=sim_state.SequencerParams(
            float(cfg.sequencer.settle_threshold_arcsec), float(cfg.sequencer.handover_arcsec),
            clock.frames_within(ck, cfg.sequencer.sensor_loss_s)),
        dither=dither_params(cfg),
        dither_sample_frames=max(1, clock.frames_for(ck, cfg.dither.sample_s)),
        routing=wiring.ROUTING,
        actuator=wheels.ACTUATOR_CODE[cfg.actuators.kind],
        wheels=wheel_params(cfg),
        faults=sim_faults.compile_faults(
            cfg, tracker, [s.name for s in stars],
            lambda name: sky.star_direction_inertial(name, cfg.mission.date_utc),
            lambda name: sky.star(name).magnitude),
        orbit=environment.build(cfg, track, s0, sdot, step, tracker),
    )


def plant_params(cfg) -> plant.RigidBodyParams:
    """The plant's mass properties from the scenario ``cfg``.

    The vehicle's tensor; on the wheel vehicle less the wheels' spin inertia
    about their axes, which the wheels carry as their momentum.
    """
    if cfg.actuators.kind == "wheels":
        return plant.gyrostat_params(cfg.vehicle.inertia_kg_m2,
                                     wheels.spin_inertia_tensor_kg_m2(wheel_params(cfg)))
    return plant.make_params(cfg.vehicle.inertia_kg_m2)


def wheel_params(cfg) -> wheels.WheelParams:
    """The reaction-wheel array from scenario ``cfg``'s [wheels] section.

    The control amplifiers' volts become a body torque at the describing gain
    of modulator and jets in their linear region, couple torque / ``full_on_v``
    [N m/V] per axis: the wheel vehicle's attitude loops then have the jet
    vehicle's gain, bandwidth and damping (within the jets' linear range,
    +-``full_on_v``), and the dither's feed-forward (:func:`dither_params`,
    the inverse gain) reaches the wheels as the torque ``J_est a(t)`` itself.
    """
    couple_n_m = 2.0 * np.asarray(cfg.jets.thrust_n, dtype=float) \
        * np.asarray(cfg.jets.moment_arm_m, dtype=float)
    w = cfg.wheels
    return wheels.make_params(
        w.axes, w.max_torque_n_m, w.max_momentum_n_m_s, w.inertia_kg_m2,
        couple_n_m / float(cfg.pwpf.full_on_v), w.unload_fraction, w.unload_end_fraction,
        couple_n_m, max(1, clock.frames_for(clock.clock(cfg.mission.frame_s),
                                            cfg.jets.min_on_time_s)),
        allocation=w.allocation)


def dither_params(cfg) -> dither.DitherParams:
    """Dither generator and feed-forward from scenario ``cfg``'s [dither] section."""
    d = cfg.dither
    amp = np.array(d.amplitude_urad, dtype=float) * 1e-6 * units.RAD2ARCSEC
    omega = 2.0 * np.pi / np.array(d.period_s, dtype=float)
    j_est = np.array(cfg.vehicle.inertia_kg_m2, dtype=float) * float(d.inertia_estimate_scale)
    torque = 2.0 * np.asarray(cfg.jets.thrust_n, dtype=float) * np.asarray(cfg.jets.moment_arm_m)
    # Describing gain of modulator + jets in the linear region: mean torque =
    # full torque x V / full_on_v, so V per N m = full_on_v / full torque.
    v_per_nm = float(cfg.pwpf.full_on_v) / torque if d.feedforward else np.zeros(3)
    return dither.DitherParams(amp, omega, j_est, v_per_nm)


def ejection_state(cfg) -> sim_state.State:
    """Mission state at ejection: attitude and tip-off rates from the mission seed.

    ``cfg`` is the scenario (its ``mission``, ``ejection``, ``jets`` and
    ``faults``).
    """
    rng = np.random.default_rng([int(cfg.mission.seed), 0])
    att = cfg.ejection.attitude
    q0 = quaternion.random_unit(rng) if isinstance(att, str) else np.asarray(att, dtype=float)
    w0 = rng.uniform(-1.0, 1.0, 3) * cfg.ejection.tipoff_rate_max_deg_s * units.DEG2RAD
    state = sim_state.new_state(q0, w0, cfg.jets.propellant_kg)
    sim_faults.arm(state.fault_state, cfg.faults, clock.clock(cfg.mission.frame_s))
    return state


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


def target_name(spec) -> str:
    """A target's name: the star's, or its RA and Dec [deg].

    ``spec`` is a target as :func:`target_specs` gives one.
    """
    if "star" in spec:
        return spec["star"]
    return f"RA {spec['ra_deg']:g} deg, Dec {spec['dec_deg']:+g} deg"


def target_inertial(cfg, index=0) -> np.ndarray:
    """Unit vector (inertial axes) to target ``index`` (from 0) of scenario ``cfg``."""
    spec = target_specs(cfg)[index]
    if "star" in spec:
        return sky.star_direction_inertial(spec["star"], cfg.mission.date_utc)
    return sky.radec_to_unit(spec["ra_deg"], spec["dec_deg"])


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


def reference_star_inertial(cfg) -> np.ndarray:
    """Unit vector to the planned reference star ``star_tracker.reference_star``.

    The programmed angles are computed for it; the tracker locks the first
    star of its magnitude window that it finds in its slit, which is this one
    only if the window and the date make it so (or its cone-angle check,
    ``star_tracker.cone_angle_check_deg``, refuses the others). ``cfg`` is the
    scenario (the star and the mission date).
    """
    return sky.star_direction_inertial(cfg.star_tracker.reference_star, cfg.mission.date_utc)


def reference_cone_deg(cfg) -> float:
    """Cone angle [deg] of the planned reference star on the mission date.

    Its place along the tracker's slit with the roll axis on the Sun: 90 deg
    less its angle from the Sun at the mission's start
    (:func:`allsky.hardware.star_tracker.cone_angle_deg`; the Sun moves about
    1 deg a day, 0.02 deg in a mission of 30 minutes). ``cfg`` is the scenario.
    """
    sun = sky.sun_direction_inertial(cfg.mission.date_utc)
    cos = xmath.dot3(sun, reference_star_inertial(cfg))
    return star_tracker.cone_angle_deg(math.degrees(xmath.acos(max(-1.0, min(1.0, cos)))))


def gate_stars(cfg):
    """``(directions, magnitudes)`` of every catalog star, whose light the bright gate counts.

    One entry per star (its variant names are one), inside the magnitude
    window or not, at the mission date; none without a gate
    (``star_tracker.bright_gate`` false).
    """
    if not cfg.star_tracker.bright_gate:
        return np.zeros((0, 3)), np.zeros(0)
    stars = [sky.star(n, cfg.mission.date_utc) for n in sky.star_names()]
    return (np.array([sky.radec_to_unit(s.ra_deg, s.dec_deg) for s in stars]).reshape(-1, 3),
            np.array([s.magnitude for s in stars]))


def tracker_star_names(cfg) -> list:
    """Names of the stars the tracker can lock, in the order of ``Params.tracker``.

    ``cfg`` is the scenario: its magnitude window, date and wrong-star faults.
    """
    lo, hi = cfg.star_tracker.magnitude_window
    names = [s.name for s in sky.stars_in_magnitude_window(lo, hi, cfg.mission.date_utc)]
    # A wrong star (a fault) is tracked after the window's own (allsky.sim.faults).
    return names + [s for s in sim_faults.wrong_stars(cfg.faults) if s not in names]


class Mission:
    """One flight of the all-sky pointing system, mode by mode.

    Parameters
    ----------
    cfg : allsky.config.Scenario
        The validated scenario to fly.
    telemetry : bool
        Record telemetry (False: none, a faster flight).
    state : allsky.sim.state.State, optional
        The state to fly on from (default: the ejection state of ``cfg``).
    next_mode : int
        Index in the plan of the next mode to fly.
    history : dict, optional
        A snapshot's history (:meth:`snapshot`): its plan, timeline, journal
        and records; None for a new mission.
    plan : tuple of str
        The modes to fly (default the legacy Modes 1 to 6-2), completed with
        the holds and the further targets the scenario asks for
        (:func:`allsky.sequencer.modes.mission_plan`); a restored mission
        flies the plan of its ``history``.
    """

    def __init__(self, cfg, telemetry=True, state=None, next_mode=0, history=None,
                 plan=LEGACY_PLAN):
        self.cfg = cfg
        # A restored mission flies the plan it saved; a new one gets the hold on target after
        # each 6-2 when the scenario asks for one (target.hold_s > 0), and the way to each
        # further target of target.sequence (sequencer.between_targets).
        if history is not None and "plan" in history:
            self.plan = tuple(history["plan"])
        else:
            self.plan = modes.mission_plan(plan, cfg)
        if any(name not in modes.BY_NAME for name in self.plan):
            raise ValueError(f"unknown mode in plan {self.plan}")
        if history is None:  # a fault must start in a mode the plan flies (exit 2, not silence)
            fault_config.check_plan(cfg.faults, self.plan)
        moves = sum(name in modes.BETWEEN_TARGETS for name in self.plan)
        if moves >= modes.target_count(cfg) and moves:
            raise ValueError(f"plan {self.plan} moves to {moves} next targets; the scenario "
                             f"has {modes.target_count(cfg)}")
        self.dither_estimates = None
        self.dither_record = None
        self.params = build_params(cfg)
        #: [frames] per telemetry row when a leg records (the scenario's)
        self._telemetry_every = self.params.telemetry_every
        self._telemetry = bool(telemetry)
        if not telemetry:
            self.params = self.params._replace(telemetry_every=0)
        self.state = ejection_state(cfg) if state is None else state
        #: the one writer of the hardware between legs (:class:`allsky.sim.board.Board`)
        self.board = board.Board(self.state, lambda: self.params.electronics, self.note,
                                 cfg.electronics.vfc_pulse_weight_arcsec)
        #: the state as read-only views (what the sequencer reads)
        self.view = self.board.view
        self.next_mode = next_mode
        h = history or {}
        self.timeline = [ModeRecord(*r) for r in h.get("timeline", [])]
        self.leg_count = int(h.get("leg_count", 0))
        self.counted_arcsec = dict(h.get("counted_arcsec", {}))
        self.status = h.get("status", "running")
        self.abort_reason = h.get("abort_reason")
        self.programmed_roll_deg = h.get("programmed_roll_deg")
        self.programmed_yaw_deg = h.get("programmed_yaw_deg")
        #: [deg] the turn from the target held to the one flown (between_targets = "direct")
        self.turn_roll_deg = h.get("turn_roll_deg")
        self.turn_yaw_deg = h.get("turn_yaw_deg")
        #: The Sun [inertial] the first target's angles were computed for: the reference
        #: attitude every target's angles are measured from when flown one from the other
        self.reference_sun_inertial = h.get("reference_sun_inertial")
        #: The body axes CPU 22 holds after the turns from target to target ("direct")
        self.held_axes = h.get("held_axes")
        #: Measurements of the hold on target (master_sequencer.measure_hold); None if not flown.
        self.hold = h.get("hold")
        #: One record per target begun (:func:`new_target_record`); the last is being flown.
        self.target_log = [dict(r) for r in h.get("targets", [])] or [
            new_target_record(cfg, 0, 0.0)]
        self.settle_s = float(cfg.sequencer.settle_time_s)
        self.pulse_weight_arcsec = float(cfg.electronics.vfc_pulse_weight_arcsec)
        self.apply_calibration = bool(cfg.calibration.apply)
        self._tlm = []
        #: the telemetry row of the last frame flown (the end of the record, when the flight
        #: ends between two decimated rows); None before the first leg
        self._last_row = None
        #: the telemetry of the leg in flight, slice by slice (:meth:`telemetry`)
        self._leg_tlm = []
        #: a ground command's words once it has ended the mode being flown (:meth:`replan`)
        self._interrupt = None
        #: the scenario was amended inside a leg (:meth:`amend`): the leg takes its parameters
        self._amended = False
        #: the star tracker 105 last held, by name, when a new magnitude window left it out
        self._locked_before = h.get("locked_star_name")
        #: [frame] the frame by which the mode being flown must end (its timeout)
        self._mode_deadline = None
        self._allowed_s = None
        #: the frame the mode being flown started in
        self._mode_start = None
        self._mode = None
        self._hooks = NO_HOOKS
        #: What happened, in order (:class:`allsky.sim.journal.Journal`).
        self.journal = journal.Journal(h.get("events"))
        self._decoder = self._new_decoder()
        #: True while :meth:`run_mode` flies a mode
        self._in_mode = False
        self.state.target_inertial[:] = self.target_direction()

    def _new_decoder(self) -> journal.Decoder:
        """What the frame loop's journal rows name, for the scenario flown."""
        cfg, trk = self.cfg, self.params.tracker
        return journal.Decoder(
            tracker_star_names(cfg), cfg.as_dict().get("faults", []), fault_config.describe,
            self.params.electronics.drift_lsb_arcsec_s / units.DEG_H2ARCSEC_S, self.params.clock,
            trk.reference_cone_rad * units.RAD2DEG, float(cfg.star_tracker.cone_angle_check_deg),
            trk.bright_gate_mag if math.isfinite(trk.bright_gate_mag) else None)

    # -- the seam: what master sequencer 20's steps use (sequencer.host.Host) -----
    def now_s(self) -> float:
        """Mission time [s]: the start of the frame the flight stands at (allsky.clock)."""
        return clock.time_s(self.params.clock, self.state.frame[0])

    @property
    def frame(self) -> int:
        """The mission clock: the frame the flight stands at (frames flown since ejection)."""
        return int(self.state.frame[0])

    @property
    def mode_start_s(self):
        """[s] when the mode being flown started (None before the first)."""
        return None if self._mode_start is None else clock.time_s(self.params.clock,
                                                                  self._mode_start)

    def note(self, kind, **fields) -> dict:
        """Write an entry of ``kind`` into the journal, at the mission time, in this mode.

        ``**fields`` are the entry's fields (:data:`allsky.vocabulary.EVENT_KINDS`).
        """
        return self.journal.note(self.now_s(), self._mode, kind, **fields)

    def leg(self, what, program, watch, mask=0, signal=0, blank_s=0.0, hold_s=None,
            on_timeout=None, record_rows=0, carry_settle=False):
        """Run the frame loop until ``what`` happens; raise ModeAbort if it does not.

        Returns the dither record (``record_rows`` rows at most) of the leg.
        ``carry_settle``: the settle time goes on from the previous leg's.

        Parameters
        ----------
        what : str
            What the leg waits for, in words (journal, abort reasons).
        program : int
            What the computer runs: a ``PROGRAM_*`` of :mod:`allsky.sequencer.legs`.
        watch : int
            What ends the leg: a ``WATCH_*`` of :mod:`allsky.sequencer.legs`.
        mask : int
            Bits of the ``SIG_*`` signals that must settle.
        signal : int
            The ``SIG_*`` signal watched for a hand-over.
        blank_s : float
            [s] the watched signal is ignored this long after the leg starts.
        hold_s : float, optional
            [s] settle time, or the leg's length for an elapsed watch
            (default: ``sequencer.settle_time_s``).
        on_timeout : str, optional
            The abort reason if the mode's deadline passes first (default:
            ``what`` not achieved).
        """
        ck = self.params.clock
        if hold_s is None:
            hold_s = self.settle_s
        seed = int(np.random.SeedSequence([int(self.cfg.mission.seed), 1,
                                           self.leg_count]).generate_state(1)[0])
        self.leg_count += 1
        leg = legs.Leg(seed, MODE_CODE[self._mode], program, watch, mask, signal,
                       clock.frames_within(ck, blank_s), clock.frames_for(ck, hold_s),
                       max(self._mode_deadline - self.frame, 0), carry_settle=int(carry_settle))
        params = self.params
        hooks = self._hooks
        if hooks.before_leg is not None:
            record = hooks.before_leg(self, self._mode, what)
            if record is not None:
                params = params._replace(telemetry_every=(self._telemetry_every if record
                                                          else 0))
        every = params.telemetry_every
        # A slice's rows at most: the leg's rows are moved out after each slice (_run_leg).
        # and one more: the row of the frame each slice ends on (:meth:`_keep_last_row`)
        rows = min(leg.timeout_frames // every + 3, SLICE_FRAMES // every + 3) if every else 0
        buf = np.empty((rows, len(COLUMNS)))
        filled = np.zeros(1, dtype=np.int64)
        rec = np.empty((record_rows, frame_loop.N_REC))
        rec_filled = np.zeros(1, dtype=np.int64)
        code = self._run_leg(params, leg, what, buf, filled, rec, rec_filled)
        rows_flown = self._end_leg_telemetry(every)
        if hooks.after_leg is not None:
            hooks.after_leg(self, self._mode, what, rows_flown)
        if code == legs.EXIT_DONE:
            return rec[: rec_filled[0]]
        if code == legs.EXIT_TIMEOUT:
            raise ms.ModeAbort(f"Mode {self._mode}: {on_timeout or what + ' not achieved'}"
                               f" within the mode timeout of {self._allowed_s:g} s", "timeout")
        raise ms.ModeAbort(f"Mode {self._mode}: {EXIT_TEXT[code]} while waiting for: {what}",
                           EXIT_TEXT[code])

    def extra_leg(self, mode, allowed_s, what, program, watch, **kwargs):
        """A leg outside the plan, flown as part of ``mode`` within ``allowed_s`` [s].

        For a study that flies one more leg after the plan (the dither held
        on target, :func:`allsky.sequencer.dither_mode.target_hold_dither`);
        the mode and its deadline are the mission's again afterwards.
        ``what``, ``program``, ``watch`` and ``**kwargs`` are :meth:`leg`'s.
        """
        saved = self._mode, self._mode_deadline, self._allowed_s
        self._mode = mode
        self._mode_deadline = self.frame + clock.frames_for(self.params.clock, allowed_s)
        self._allowed_s = float(allowed_s)
        try:
            return self.leg(what, program, watch, **kwargs)
        finally:
            self._mode, self._mode_deadline, self._allowed_s = saved

    def track_excursion(self, on=True):
        """Measure the largest rotation from the attitude held now (``on``), or stop.

        The frame loop keeps the largest angle [rad] in
        ``State.max_excursion_rad``; a measurement of the simulation, not
        the vehicle's hardware.
        """
        self.state.excursion_ref_q[:] = self.state.x[0:4] if on else 0.0

    def extend_mode(self, seconds):
        """Move the mode's deadline on by ``seconds`` [s] (from now, if it has passed).

        A recovery of the master sequencer does so (``sequencer.recovery``).
        """
        ck = self.params.clock
        self._mode_deadline = max(self._mode_deadline, self.frame) + clock.frames_for(ck, seconds)
        self._allowed_s = clock.time_s(ck, self._mode_deadline - self._mode_start)

    def _run_leg(self, params, leg, what, buf, filled, rec, rec_filled):
        """The frame loop over one leg, in slices, pausing for ``on_pause`` if asked.

        The compiled loop returns to Python at least every :data:`SLICE_FRAMES`
        frames, so that a signal (Ctrl-C) is honoured and ``on_slice`` (the
        progress line) hears of the mission time; a paused leg resumes bit for
        bit, so slicing does not change the flight. After each slice the rows
        recorded are moved out of ``buf`` (:meth:`telemetry` sees them). At a
        pause ``on_pause`` may amend the scenario (:meth:`amend`: the leg flies
        on with its parameters) or end the mode (:meth:`replan`: the leg ends
        here with :class:`~allsky.sequencer.master_sequencer.ModeInterrupted`).
        If the flight is interrupted (KeyboardInterrupt, or an exception of a
        hook), the telemetry of the part of the leg flown is kept before the
        exception goes on.
        """
        hooks = self._hooks
        every = hooks.pause_every_s if hooks.on_pause is not None else None
        asked = hooks.pause_at if hooks.on_pause is not None else None
        ck = params.clock
        try:
            while True:
                step_at = self._next_pause(ck, every, asked)
                while step_at <= self.frame:  # due before this leg flies a frame
                    params = self._pause(hooks, what, params)
                    step_at = self._next_pause(ck, every, asked)
                leg = leg._replace(pause_at_frame=min(step_at, self.frame + SLICE_FRAMES))
                if len(buf):
                    buf[-1, TIME] = np.nan  # not written until the slice ends
                code, _ = frame_loop.run_leg(params, self.state, leg, buf, filled, rec,
                                             rec_filled)
                self._drain_journal()
                self._slice_telemetry(buf, filled)
                if len(buf) and not np.isnan(buf[-1, TIME]):
                    self._last_row = buf[-1].copy()
                if code != legs.EXIT_PAUSE:
                    return code
                leg = leg._replace(resume=1)
                if hooks.on_slice is not None:
                    hooks.on_slice(self, what)
                if self.frame >= step_at:
                    params = self._pause(hooks, what, params)
        except BaseException:
            self._slice_telemetry(buf, filled)
            raise

    def _next_pause(self, ck, every, asked) -> int:
        """The frame of the next call of ``on_pause`` (clock ``ck``; NEVER: none).

        ``every`` [s]: at each multiple of it in mission time; ``asked``: the
        mission time ``asked(self)`` gives. Either lands on a frame by the
        clock's rule (:func:`allsky.clock.frame_at`).
        """
        step_at = clock.NEVER
        if every:
            k = math.floor(clock.decimal(self.now_s()) / clock.decimal(every)) + 1
            step_at = clock.frame_at(ck, k * clock.decimal(every))
        if asked is not None:
            step_at = min(step_at, clock.frame_at(ck, asked(self)))
        return step_at

    def _pause(self, hooks, what, params):
        """Call ``on_pause`` at this frame; returns the parameters the leg flies on with.

        A ground command may end the mode here (ModeInterrupted) or amend the
        scenario (the leg flies on with the new parameters).
        """
        hooks.on_pause(self, what)
        if self._interrupt is not None:
            raise ms.ModeInterrupted(self._interrupt)
        if self._amended:  # a ground command changed the scenario
            self._amended = False
            return self.params._replace(telemetry_every=params.telemetry_every)
        return params

    def _slice_telemetry(self, buf, filled):
        """Move the rows a slice recorded into the leg's telemetry."""
        if filled[0]:
            self._leg_tlm.append(buf[: filled[0]].copy())
            filled[0] = 0

    def _end_leg_telemetry(self, every):
        """The leg's rows, kept as one piece of :meth:`telemetry`; returns them."""
        rows = (np.vstack(self._leg_tlm) if self._leg_tlm
                else np.empty((0, len(COLUMNS))))
        self._leg_tlm = []
        if every:
            self._tlm.append(rows)
        return rows

    def _drain_journal(self):
        """Move what the frame loop journaled into the journal (and the orbit's entries)."""
        s = self.state
        before = len(self.journal.events)
        if s.journal_n[0] or s.journal_n[1]:
            self.journal.drain(s.journal, s.journal_n, self._mode, self._decoder)
        if self.params.orbit.n > 0 and self._orbit_journal():
            # the slice's entries in the order of time (the loop's, then the orbit's, stably)
            ev = self.journal.events
            ev[before:] = sorted(ev[before:], key=lambda e: e["t_s"])

    def _orbit_journal(self) -> bool:
        """Journal the eclipses and occultations of the frames flown since the last call.

        They depend on the orbit and the date only, not on the attitude: they
        are found from the orbit's samples, interpolated as the frame loop
        interpolates them (:mod:`allsky.vehicle.environment`), frame by frame.
        Returns whether any entry was written.
        """
        o = self.params.orbit
        first, last = getattr(self, "_orbit_frame", 0), self.frame
        if last <= first:
            return False
        self._orbit_frame = last
        ck = self.params.clock
        f = environment.sunlit_series(o, first, last)
        phase = np.where(f >= 1.0, 0, np.where(f <= 0.0, 2, 1))
        prev = getattr(self, "_orbit_phase", 0)
        wrote = False
        names = ("sunlit", "penumbra", "umbra")
        for k in np.nonzero(np.diff(np.concatenate([[prev], phase])))[0]:
            self.journal.note(clock.time_s(ck, first + int(k)), self._mode, "eclipse",
                              phase=names[phase[k]], active=bool(phase[k] != 0),
                              sunlit_fraction=float(f[k]))
            wrote = True
        self._orbit_phase = int(phase[-1])
        bodies = [*tracker_star_names(self.cfg)[:o.stars_inertial.shape[0]], "target"]
        dirs = np.ascontiguousarray(np.vstack([o.stars_inertial,
                                               np.asarray(self.state.target_inertial)[None]]))
        hidden = environment.occulted_series(o, dirs, first, last)
        seen = getattr(self, "_orbit_hidden", np.zeros(len(bodies), dtype=bool))
        steps = np.diff(np.vstack([seen[None, :], hidden]).astype(np.int8), axis=0)
        for k, j in zip(*np.nonzero(steps)):
            self.journal.note(clock.time_s(ck, first + int(k)), self._mode, "occultation",
                              body=bodies[j], active=bool(steps[k, j] > 0))
            wrote = True
        self._orbit_hidden = hidden[-1].copy()
        return wrote

    # -- running ---------------------------------------------------------------
    @property
    def finished(self) -> bool:
        """True once the mission is complete or aborted."""
        return self.status != "running"

    @property
    def current_mode(self):
        """The mode being flown (or last flown), by name; None before the first."""
        return self._mode

    def run_mode(self, hooks=None) -> ModeRecord:
        """Run the next mode; returns its timeline record.

        ``hooks`` (:class:`Hooks`) are called while the mode flies; they do
        not change the flight.
        """
        if self.finished:
            raise RuntimeError(f"mission already {self.status}")
        name = self.plan[self.next_mode]
        self._mode = name
        start = self.frame
        self._mode_deadline = start + clock.frames_for(self.params.clock,
                                                       self.mode_timeout_s(name))
        #: [s] the time the mode is allowed (a recovery extends it), for abort reasons
        self._allowed_s = self.mode_timeout_s(name)
        self._mode_start = start
        self._hooks = hooks or NO_HOOKS
        self._in_mode = True
        self.note("mode_start", title=modes.MODE_TITLE[name],
                  target=self.target_log[-1]["name"],
                  waits_for=ms.next_wait(modes.BY_NAME[name].steps))
        sim_faults.on_mode_start(self.state.fault_state, self.cfg.faults, name, start)
        ended = False
        try:
            exit_text = ms.run_mode(self, name)
        except ms.ModeAbort as e:
            # The faults of the last frame flown (the flight stands after it).
            reason = str(e) + sim_faults.blame(self.state.fault_state, self.cfg.faults,
                                               self.params.clock, self.frame - 1)
            exit_text = f"aborted: {reason}"
            self.status = "aborted"
            self.abort_reason = reason
        except ms.ModeInterrupted as e:
            exit_text = f"ended by ground command: {e}"
            ended = True
        finally:
            self._hooks = NO_HOOKS
            self._interrupt = None
            self._in_mode = False
            if self._leg_tlm:  # the part of a leg flown before an exception ended it
                self._end_leg_telemetry(True)
        self.note("mode_end", exit=exit_text,
                  status="aborted" if self.status == "aborted" else "ended" if ended
                  else "done")
        if self.status == "aborted":
            self.note("abort", reason=self.abort_reason)
        rec = ModeRecord(name, clock.time_s(self.params.clock, start), self.now_s(), exit_text)
        self.timeline.append(rec)
        if self.status == "running" and name == modes.TARGET_MODES[-1] and not ended:
            self.target_log[-1].update(self.on_target())
        self.next_mode += 1
        if self.status == "running" and self.next_mode == len(self.plan):
            self.status = "complete"
        return rec

    def mode_timeout_s(self, name) -> float:
        """Time allowed to mode ``name`` [s] (:func:`allsky.sequencer.modes.timeout_s`)."""
        return modes.timeout_s(self.cfg, name)

    def run(self, hooks=None):
        """Run the remaining modes; returns the summary dictionary.

        ``hooks`` (:class:`Hooks`, optional) are called as the modes fly.
        """
        while not self.finished:
            self.run_mode(hooks)
        return self.summary()

    def on_target(self) -> dict:
        """The truth where Mode 6-2 declares the vehicle on target, and CPU 22's errors.

        Keys: ``pointing_error_arcsec`` (true), ``body_rate_deg_s`` (true,
        per axis), ``computed_error_arcsec`` (CPU 22's roll, pitch and yaw
        errors, what the sequencer judged by).
        """
        return {"pointing_error_arcsec": self.pointing_error_arcsec(),
                "body_rate_deg_s": journal.rate_deg_s(self.state.x[4:7]),
                "computed_error_arcsec": dict(zip(AXES, map(float, self.state.cpu[3:6])))}

    def program_target(self):
        """Ground computation of the programmed angles that register 24 will hold.

        The Sun holds pitch and yaw through Mode 6-1, so the frame the yaw of
        6-2 starts from is the reference attitude of the Sun *at the end of
        6-1*; the angles are computed for the Sun predicted at that time
        (roll at the commanded rate plus a settle allowance), two passes.
        """
        star, target = reference_star_inertial(self.cfg), self.target_direction()
        if self.cfg.sequencer.between_targets == "direct" \
                and self.reference_sun_inertial is not None:
            # Flown from target to target on the gyros: every target's angles from the
            # reference attitude the first one was flown from.
            sun = np.asarray(self.reference_sun_inertial, dtype=float)
            self.programmed_roll_deg, self.programmed_yaw_deg = \
                targeting.programmed_angles_deg(sun, star, target)
            return
        t0 = self.now_s()
        rate_deg_s = float(self.cfg.electronics.rate_command_deg_s)
        roll = 0.0
        for _ in range(2):
            t = t0 + abs(roll) / rate_deg_s + SETTLE_ALLOWANCE_S
            sun = self.params.sun0_inertial + self.params.sun_rate_inertial * t
            if self.params.orbit.n > 0:  # the ground knows the orbit: the vehicle's Sun
                sun = environment.sun_seen(self.params.orbit,
                                           clock.frame_at(self.params.clock, t))
            roll, yaw = targeting.programmed_angles_deg(sun, star, target)
        self.programmed_roll_deg, self.programmed_yaw_deg = roll, yaw
        if self.cfg.sequencer.between_targets == "direct":
            self.reference_sun_inertial = [float(x) for x in sun]

    # -- targets ---------------------------------------------------------------
    @property
    def target_index(self) -> int:
        """Index (from 0) of the target being flown in ``target.sequence``."""
        return len(self.target_log) - 1

    def target_direction(self) -> np.ndarray:
        """Unit vector to the target being flown."""
        return target_inertial(self.cfg, self.target_index)

    def next_target(self):
        """Close the record of the target flown and begin the next one's.

        Its programmed angles and hold go into its record and are cleared,
        so that Mode 6-1 computes the next target's angles.
        """
        now = self.now_s()
        self.target_log[-1] = {**self.targets()[-1], "end_s": now}
        self.target_log.append(new_target_record(self.cfg, len(self.target_log), now))
        self.programmed_roll_deg = self.programmed_yaw_deg = None
        self.turn_roll_deg = self.turn_yaw_deg = None
        self.hold = None
        self.state.target_inertial[:] = self.target_direction()

    def targets(self) -> list:
        """The record of every target begun (:func:`new_target_record`), in flight order.

        The last one's is completed with what the mission holds now; its
        ``end_s`` is the mission time once the mission is finished.
        """
        out = [dict(r) for r in self.target_log]
        cur = out[-1]
        hold = self.hold if self.hold is not None and "hold_s" in self.hold else None
        cur.update(programmed_roll_deg=self.programmed_roll_deg,
                   programmed_yaw_deg=self.programmed_yaw_deg, hold=hold,
                   hold_end_pointing_error_arcsec=(hold["end_pointing_error_arcsec"]
                                                   if hold else None),
                   locked_star=self.locked_star())
        if self.turn_roll_deg is not None:  # flown from the target before, on the gyros
            cur.update(turn_roll_deg=self.turn_roll_deg, turn_yaw_deg=self.turn_yaw_deg)
        if self.finished:
            cur["end_s"] = self.now_s()
        return out

    # -- ground commands (allsky.sim.commands) ----------------------------------
    @property
    def mode_in_flight(self):
        """Index in ``plan`` of the mode being flown; None between modes."""
        return self.next_mode if self._in_mode else None

    def amend(self, cfg, retarget=False) -> None:
        """Fly on with scenario ``cfg`` from this frame boundary (a ground command).

        What a command changes of the scenario mid-flight: a fault added (its
        ``start_s`` onset armed) or ended (its ``duration_s``), star tracker
        105's magnitude window and bright gate, the targets. The frame loop's
        parameters are built again (:func:`build_params`, as for a scenario
        that had the change from the start); a leg in flight goes on with
        them. The tracker's memory is carried over by star name; a star it
        held that the new window does not pass is lost, and the journal says
        so. With ``retarget`` the target being flown becomes the new
        scenario's at its index (``target.sequence``): a target whose Mode 6
        has not begun.
        """
        old_names = tracker_star_names(self.cfg)
        gate_before = self.params.tracker.bright_gate_mag
        self.cfg = cfg
        params = build_params(cfg)
        self.params = params if self._telemetry else params._replace(telemetry_every=0)
        self._amended = True
        sim_faults.arm(self.state.fault_state, cfg.faults, params.clock)
        new_names = tracker_star_names(cfg)
        if new_names != old_names:
            self._carry_tracker(old_names, new_names)
        if self.params.tracker.bright_gate_mag != gate_before:
            self.state.tracker_lock[star_tracker.GATE] = 0.0
        self._decoder = self._new_decoder()
        if retarget:
            start = self.target_log[-1]["start_s"]
            self.target_log[-1] = new_target_record(cfg, self.target_index, start)
            self.state.target_inertial[:] = self.target_direction()

    def held_object(self):
        """Name of the object star tracker 105 holds now: a star, "stray light", or None."""
        held = int(self.state.tracker_lock[star_tracker.HELD])
        if held == star_tracker.FALSE_TARGET:
            return "stray light"
        return tracker_star_names(self.cfg)[held] if held >= 0 else None

    def step_on(self) -> None:
        """Star tracker 105 lets go of what it holds and ignores it until it leaves the slit.

        The ground's ``step_on`` (:mod:`allsky.sim.commands`): the object is
        remembered as the cone-angle check remembers a star it refused
        (:func:`allsky.hardware.star_tracker.refuse_now`), so the search
        passes it by; the journal's ``star_lock`` tells the lock's end.
        """
        lock = self.state.tracker_lock
        held = lock[star_tracker.HELD]
        _python(star_tracker.refuse_now)(lock, held, 0.0)
        lock[star_tracker.NEW_REFUSAL] = star_tracker.NONE  # the ground's, not the check's
        lock[star_tracker.HELD] = star_tracker.NONE

    def _carry_tracker(self, old_names, new_names) -> None:
        """Star tracker 105's memory, from the star list ``old_names`` to ``new_names``."""
        s = self.state
        lock = s.tracker_lock

        def index(k):
            k = int(k)
            if k < 0 or k >= len(old_names):  # nothing, or a glint
                return k
            return new_names.index(old_names[k]) if old_names[k] in new_names \
                else star_tracker.NONE

        held = int(lock[star_tracker.HELD])
        if 0 <= held < len(old_names) and old_names[held] not in new_names:
            star_in_use = _python(sensors_in_use)(s.switches, self.params.routing)[1]
            self.note("star_lock", star=None, previous=old_names[held], cone_angle_deg=None,
                      in_use=bool(star_in_use))
        slots = (star_tracker.HELD, star_tracker.NEW_REFUSAL, star_tracker.DROPPED,
                 star_tracker.NEW_DROP, *range(star_tracker.REFUSED,
                                               star_tracker.REFUSED + star_tracker.N_REFUSED))
        for slot in slots:
            lock[slot] = index(lock[slot])
        if int(lock[star_tracker.HELD]) == star_tracker.FALSE_TARGET:
            # A glint held is judged again against the new window from the next frame.
            lock[star_tracker.HELD] = star_tracker.NONE
        seen = s.journal_seen[journal.SEEN_STAR]
        s.journal_seen[journal.SEEN_STAR] = -1.0 if index(seen) == star_tracker.NONE \
            else index(seen)
        k = int(s.locked_star[0])
        if k >= 0:
            if index(k) < 0:
                self._locked_before = old_names[k]
            s.locked_star[0] = index(k)

    def replan(self, plan, end_mode=False, reason="") -> None:
        """Fly ``plan`` from the next mode on; with ``end_mode`` end the mode being flown.

        A ground command's change of the plan (:mod:`allsky.sequencer.ground`):
        ``plan`` is the whole plan, the modes flown and the one being flown
        as they are. With ``end_mode`` the mode being flown ends at this
        frame boundary, ``reason`` in its exit (its ``on_command`` steps
        flown), and the plan goes on after it. A finished mission (complete
        or aborted) flies again: its status is running and the abort reason
        cleared (the journal and the timeline keep the abort).

        Raises
        ------
        ValueError
            ``plan`` changes a mode flown, or names a mode not in the table.
        """
        plan = tuple(plan)
        kept = self.next_mode + (1 if self._in_mode else 0)
        if plan[:kept] != tuple(self.plan[:kept]) or any(n not in modes.BY_NAME for n in plan):
            raise ValueError(f"plan {plan} does not keep the modes flown {self.plan[:kept]}")
        self.plan = plan
        if end_mode and self._in_mode:
            self._interrupt = reason or "ended"
        if self.finished and self.next_mode < len(plan):
            self.status = "running"
            self.abort_reason = None

    # -- results ---------------------------------------------------------------
    def telemetry(self, start_row=0) -> np.ndarray:
        """The decimated telemetry recorded so far (this process), one row per record.

        Mid-leg (a hook's view) the rows of the leg in flight are included;
        ``start_row``: the rows from that one on (a live view's next rows).
        """
        pieces, skip = [], int(start_row)
        every = [*self._tlm, *self._leg_tlm]
        last = self._last_row
        if self.finished and last is not None and self._telemetry:
            tail = next((p[-1, TIME] for p in reversed(every) if len(p)), -np.inf)
            if last[TIME] > tail:  # the flight ended off the grid: its last frame ends it
                every.append(last[None, :])
        for piece in every:
            if skip >= len(piece):
                skip -= len(piece)
                continue
            pieces.append(piece[skip:])
            skip = 0
        if not pieces:
            return np.empty((0, len(COLUMNS)))
        return np.vstack(pieces)

    def orbit_telemetry(self, start_row=0):
        """The orbit's columns beside :meth:`telemetry`'s rows (from ``start_row``).

        None without an orbit.

        Columns :data:`allsky.vehicle.environment.ORBIT_COLUMNS`: time [s],
        the Sun's visible fraction, the eclipse flag, the Earth's angle from
        +x and from the tracker's boresight [deg]
        (:func:`allsky.vehicle.environment.orbit_telemetry`).
        """
        if self.params.orbit.n == 0:
            return None
        return environment.orbit_telemetry(self.params.orbit, self.params.clock,
                                           self.telemetry(start_row))

    def pointing_error_arcsec(self) -> float:
        """True angle between the roll axis and the target being flown."""
        x_body = quaternion.dcm_body_from_inertial(self.state.x[0:4])[0]
        return sky.separation_deg(x_body, self.target_direction()) * units.DEG2ARCSEC

    def locked_star(self):
        """Name of the star tracker 105 last held while in use; None before a lock."""
        k = int(self.state.locked_star[0])
        return tracker_star_names(self.cfg)[k] if k >= 0 else self._locked_before

    def calibration(self) -> dict:
        """What the mission stored: the drift counted and applied, and register 23.

        ``drift_deg_h`` is what drift counters 13/15/17 counted,
        ``drift_applied_deg_h`` what drift DACs 7/9/11 apply from it: the
        same unless the count is beyond a DAC's full scale
        (:meth:`drift_dac_clipped`).
        """
        el = self.params.electronics
        lsb = el.drift_lsb_arcsec_s / units.DEG_H2ARCSEC_S
        counted = [float(d * el.drift_lsb_arcsec_s) for d in self.state.drift_counters]
        applied = [float(_python(dac)(int(d), el.drift_dac_bits, lsb))
                   for d in self.state.drift_counters]
        out = {"drift_deg_h": dict(zip(AXES, counted)),
               "drift_applied_deg_h": dict(zip(AXES, applied))}
        out.update(wr.computed_as_dict(self.state.word23))
        return out

    def drift_dac_clipped(self) -> dict:
        """Per axis: is the drift count beyond its drift DAC's full scale (7, 9, 11)?"""
        bits = self.params.electronics.drift_dac_bits
        return {axis: int(_python(dac)(int(d), bits, 1)) != int(d)
                for axis, d in zip(AXES, self.state.drift_counters)}

    def end(self) -> dict:
        """The truth at the end of the flight (so far): time, target, error, rates, gas.

        Keys: ``t_s`` [s], ``target`` (the last target begun), ``mode`` (the
        last mode flown), ``true_pointing_error_arcsec``, ``body_rate_deg_s``
        (roll, pitch, yaw), ``propellant_kg`` (used since ejection) and
        ``propellant_remaining_kg``.
        """
        return {"t_s": self.now_s(), "target": self.target_log[-1]["name"],
                "mode": self._mode,
                "true_pointing_error_arcsec": float(self.pointing_error_arcsec()),
                "body_rate_deg_s": journal.rate_deg_s(self.state.x[4:7]),
                "propellant_kg": float(self.cfg.jets.propellant_kg
                                       - self.state.propellant_kg[0]),
                "propellant_remaining_kg": float(self.state.propellant_kg[0])}

    def summary(self) -> dict:
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
        """
        done = [r.mode for r in self.timeline]
        records = self.targets()
        first = records[0]
        if len(records) == 1:
            pointing = self.pointing_error_arcsec() if self.status == "complete" else None
        else:  # the first target's flight has ended
            pointing = (first["hold_end_pointing_error_arcsec"] if first["hold"] is not None
                        else first["pointing_error_arcsec"])
        target = {"programmed_roll_deg": first["programmed_roll_deg"],
                  "programmed_yaw_deg": first["programmed_yaw_deg"],
                  "pointing_error_arcsec": pointing}
        target.update(target_specs(self.cfg)[0])
        calibration = self.calibration() if ("5" in done or "dither" in done) else None
        out = {
            "status": self.status,
            "abort_reason": self.abort_reason,
            "modes": [{"mode": r.mode, "start_s": r.start_s, "end_s": r.end_s, "exit": r.exit}
                      for r in self.timeline],
            "calibration": calibration,
            "truth": gyro.perfect_calibration(self.params.gyro,
                                              self.params.vfc.integrator_drift_arcsec_s),
            "calibration_applied": self.apply_calibration,
            "target": target,
            "propellant_kg": float(self.cfg.jets.propellant_kg - self.state.propellant_kg[0]),
            "mission_time_s": self.now_s(),
            "seed": int(self.cfg.mission.seed),
            "reference_star": self.cfg.star_tracker.reference_star,
            "locked_star": self.locked_star(),
            "counter_overflow": {
                name: bool(f) for name, f in zip(
                    ("counter14", "counter16", "counter18", "drift13", "drift15", "drift17"),
                    self.state.overflow)},
            "drift_dac_clipped": self.drift_dac_clipped(),
            "end": self.end(),
        }
        if first["hold"] is not None:
            out["hold"] = first["hold"]
        if self.cfg.faults:
            out["faults"] = [{**f, "onset_s": (clock.time_s(self.params.clock, int(onset))
                                               if onset >= 0.0 else None)}
                             for f, onset in zip(self.cfg.as_dict()["faults"],
                                                 self.state.fault_state[sim_faults.ONSET])]
        out["targets"] = records
        if self.cfg.actuators.kind == "wheels":
            out["wheels"] = self.wheel_summary()
        if self.params.orbit.n > 0:
            out["orbit"] = self.orbit_summary()
        out["warnings"] = results.warnings(out, self.journal, fault_config.describe,
                                           self.params.sequencer.settle_threshold_arcsec)
        braking = flight_warning(self.cfg, self.state.propellant_kg[0])
        if braking is not None:  # the scenario's, before any time: first
            out["warnings"].insert(0, braking)
        out["events"] = [dict(e) for e in self.journal.events]
        return out

    def orbit_summary(self) -> dict:
        """The orbit's part of the summary (a mission in orbit only).

        ``sunlit_fraction`` of the Sun's disk at the end; ``sunlit_margin_s``,
        the time from the end of the flight to the next orbit sunset (the
        onset of the penumbra; 0 in the shadow, None past the orbit's
        samples); ``eclipsed_s`` and ``occulted``, the time spent in the
        shadow and the bodies the Earth hid while flying; ``torques``, each
        environment torque's ``peak_n_m`` and ``impulse_n_m_s`` (its
        magnitude integrated over the flight), or None where it is off.
        """
        o = self.params.orbit
        ck = self.params.clock
        end = self.frame
        horizon = (o.n - 1) * o.step_frames
        ahead = environment.sunlit_series(o, end, max(end, horizon))
        dark = np.nonzero(ahead < 1.0)[0]
        margin = None if dark.size == 0 else clock.time_s(ck, int(dark[0]))
        flown = environment.sunlit_series(o, 0, end)
        keys = {"gravity_gradient": self.cfg.orbit.gravity_gradient,
                "aerodynamic": self.cfg.orbit.aerodynamic,
                "solar_pressure": self.cfg.orbit.solar_pressure}
        torques = {name: ({"peak_n_m": float(o.peak[environment.PEAK, i]),
                           "impulse_n_m_s": float(o.peak[environment.IMPULSE, i])}
                          if on else None) for i, (name, on) in enumerate(keys.items())}
        occulted = sorted({e["body"] for e in self.journal.of_kind("occultation")
                           if e["active"]})
        return {"kind": self.cfg.orbit.kind,
                "sunlit_fraction": float(ahead[0]) if ahead.size else None,
                "sunlit_margin_s": margin,
                "eclipsed_s": clock.time_s(ck, int(np.count_nonzero(flown < 1.0))),
                "occulted": occulted,
                "torques": torques}

    def wheel_summary(self) -> dict:
        """The reaction wheels at the end: momenta, the largest fraction of a limit held."""
        n = len(self.cfg.wheels.axes)
        h = self.state.wheel_h[:n]
        return {"momentum_n_m_s": [float(x) for x in h],
                "speed_rad_s": [float(x) for x in wheels.wheel_speeds_rad_s(
                    self.params.wheels, h, self.state.x[4:7])],
                "peak_momentum_fraction": float(self.state.wheel_peak_fraction[0]),
                "unloading_propellant_kg": float(self.cfg.jets.propellant_kg
                                                 - self.state.propellant_kg[0])}

    # -- snapshot / resume ---------------------------------------------------------
    def snapshot(self):
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
        """
        history = {"format": STATE_FORMAT, "next_mode": self.next_mode, "plan": list(self.plan),
                   "timeline": [list(r) for r in self.timeline], "leg_count": self.leg_count,
                   "counted_arcsec": self.counted_arcsec, "status": self.status,
                   "abort_reason": self.abort_reason,
                   "programmed_roll_deg": self.programmed_roll_deg,
                   "programmed_yaw_deg": self.programmed_yaw_deg,
                   "scenario": self.cfg.as_dict(),
                   "events": [dict(e) for e in self.journal.events]}
        if self.hold is not None:
            history["hold"] = self.hold
        for key in ("turn_roll_deg", "turn_yaw_deg", "reference_sun_inertial", "held_axes"):
            if getattr(self, key) is not None:
                history[key] = getattr(self, key)
        if self._locked_before is not None:
            history["locked_star_name"] = self._locked_before
        if len(self.target_log) > 1 or self.cfg.target.sequence is not None:
            history["targets"] = [dict(r) for r in self.target_log]
        arrays = {k: v.copy() for k, v in self.state._asdict().items()}
        return history, arrays

    @classmethod
    def from_snapshot(cls, history, arrays, telemetry=True):
        """Resume a mission from a :meth:`snapshot` (its own scenario is restored).

        ``history`` and ``arrays`` are the snapshot's two parts; ``telemetry``
        as for :class:`Mission`.

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
        arrays = {**newer_state_arrays(), **arrays}
        lock = np.asarray(arrays["tracker_lock"], dtype=float)
        if lock.shape[0] < star_tracker.N_LOCK:  # entries added since: as a new lock's
            arrays["tracker_lock"] = np.concatenate([lock, star_tracker.new_lock()[lock.shape[0]:]])
        state = sim_state.State(**{k: np.array(arrays[k], copy=True)
                                   for k in sim_state.State._fields})
        cfg = scenario_from_dict(history["scenario"])
        return cls(cfg, telemetry=telemetry, state=state, next_mode=history["next_mode"],
                   history=history)


def newer_state_arrays() -> dict:
    """State arrays added since files of :data:`STATE_FORMAT` were first written.

    Each with the value a file saved before it stands for: ``locked_star``
    -1 (which star the tracker held was not recorded); ``tracker_lock``
    nothing held (the tracker searches at the next frame, and finds the star
    it held if that is still in its slit); ``fault_state`` no onset known (a
    mission of those days had no faults); the wheels' arrays zero (it flew
    the jets).
    """
    blank = sim_state.new_state(np.array([1.0, 0.0, 0.0, 0.0]), np.zeros(3), 0.0)
    return {k: getattr(blank, k) for k in ("locked_star", "tracker_lock", "fault_state",
                                           "wheel_h", "wheel_unload", "wheel_peak_fraction")}


def run_mission(cfg, telemetry=True) -> Mission:
    """Fly a whole mission (Modes 1 to 6-2, holds, every target) and return it.

    ``cfg`` is the validated scenario; ``telemetry`` False records none.
    """
    m = Mission(cfg, telemetry=telemetry)
    m.run()
    return m
