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
from allsky.sequencer import dither, legs, modes
from allsky.sequencer import master_sequencer as ms
from allsky.sim import board, frame_loop, journal, record, sky_rows
from allsky.sim import faults as sim_faults
from allsky.sim import state as sim_state
from allsky.sim.record import (  # noqa: F401 - the mission module's names, kept
    STATE_FORMAT,
    ModeRecord,
    new_target_record,
    target_name,
    target_specs,
    tracker_star_names,
)
from allsky.sim.telemetry import COLUMNS, INDEX
from allsky.vehicle import environment, orbit, plant, quaternion, sky, wheels

#: The telemetry's time column.
TIME = INDEX["time"]

EXIT_TEXT = {
    legs.EXIT_PROPELLANT: "propellant exhausted",
    legs.EXIT_SUN_LOST: "Sun lost",
    legs.EXIT_STAR_LOST: "star lost",
}
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


class Hooks(NamedTuple):
    """What a front end or a study asks to hear while a mission flies (all optional).

    Passed to :meth:`Mission.run_mode` and :meth:`Mission.run`, never set on
    the mission: the flight is the same with or without them.

    Examples
    --------
    >>> import allsky
    >>> m = allsky.Mission(allsky.load_scenario())
    >>> legs = []
    >>> hooks = allsky.Hooks(after_leg=lambda m, mode, leg, rows: legs.append((mode, leg)))
    >>> m.run_mode(hooks).mode
    '1'
    >>> legs
    [('1', 'sun acquired and settled')]
    >>> times_s = []                                # [s] every 50 s of mission time
    >>> m.run_mode(allsky.Hooks(pause_every_s=50.0,
    ...                         on_pause=lambda m, leg: times_s.append(m.now_s()))).mode
    '2'
    >>> times_s
    [200.0, 250.0]
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
    rows = sky_rows.sky_rows(cfg)  # the window's stars, then the moving bodies flown
    st = cfg.star_tracker
    tracker = star_tracker.make_params(
        st.fov_long_half_deg * units.DEG2RAD, st.fov_narrow_half_deg * units.DEG2RAD,
        float(st.noise_arcsec), rows.directions, rows.magnitudes, (lo, hi),
        reference_cone_deg(cfg) * units.DEG2RAD, st.cone_angle_check_deg * units.DEG2RAD,
        bool(st.bright_gate), rows.gate_directions, rows.gate_magnitudes)
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
            cfg, tracker, rows.names,
            lambda name: sky.star_direction_inertial(name, cfg.mission.date_utc),
            lambda name: sky.star(name).magnitude),
        orbit=environment.build(cfg, track, s0, sdot, step, tracker,
                                *_body_motion(rows, cfg, track, step, dt)),
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


def target_inertial(cfg, index=0) -> np.ndarray:
    """Unit vector (inertial axes) to target ``index`` (from 0) of scenario ``cfg``."""
    spec = target_specs(cfg)[index]
    if "star" in spec:
        return sky.star_direction_inertial(spec["star"], cfg.mission.date_utc)
    return sky.radec_to_unit(spec["ra_deg"], spec["dec_deg"])


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


def _body_motion(rows, cfg, track, step_frames, frame_s):
    """``(table, body_rows, gate_rows)`` of the moving bodies in orbit (:mod:`allsky.sim.sky_rows`)."""
    if track is None:
        return np.zeros((0, 0, 3)), rows.body_rows, rows.gate_rows
    return (sky_rows.body_table(rows, cfg, track, step_frames * frame_s), rows.body_rows,
            rows.gate_rows)


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

    Examples
    --------
    >>> import allsky
    >>> m = allsky.Mission(allsky.load_scenario())
    >>> m.plan
    ('1', '2', '3', '4', '5', '6-1', '6-2')
    >>> record = m.run_mode()           # Mode 1: Sun orientation
    >>> record.mode, record.end_s       # [s]
    ('1', 187.3)
    >>> summary = m.run()               # the rest: Modes 2 to 6-2
    >>> m.status, round(summary["end"]["true_pointing_error_arcsec"], 1)
    ('complete', 7.6)
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
        record.restore(self, h)  # what a snapshot's history holds (the inverse of snapshot)
        self.settle_s = float(cfg.sequencer.settle_time_s)
        self.pulse_weight_arcsec = float(cfg.electronics.vfc_pulse_weight_arcsec)
        self.apply_calibration = bool(cfg.calibration.apply)
        #: the telemetry recorded so far, leg by leg (:class:`allsky.sim.record.TelemetryRecord`)
        self._rows = record.TelemetryRecord(len(COLUMNS))
        #: the eclipses and occultations journaled so far (a mission in orbit)
        self._orbit_journal = record.OrbitJournal()
        #: a ground command's words once it has ended the mode being flown (:meth:`replan`)
        self._interrupt = None
        #: the scenario was amended inside a leg (:meth:`amend`): the leg takes its parameters
        self._amended = False
        #: [frame] the frame by which the mode being flown must end (its timeout)
        self._mode_deadline = None
        self._allowed_s = None
        #: the frame the mode being flown started in
        self._mode_start = None
        self._mode = None
        self._hooks = NO_HOOKS
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

        The leg of :meth:`allsky.sequencer.host.Host.leg`, whose parameters
        (``what``, ``program``, ``watch``, ``mask``, ``signal``, ``blank_s``,
        ``hold_s``, ``on_timeout``, ``record_rows``, ``carry_settle``) it
        takes; ``hold_s`` None is ``sequencer.settle_time_s``. Returns the
        leg's dither record (``record_rows`` rows at most).
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
        # and one more: the row of the frame each slice ends on (TelemetryRecord.slice)
        rows = min(leg.timeout_frames // every + 3, SLICE_FRAMES // every + 3) if every else 0
        buf = np.empty((rows, len(COLUMNS)))
        filled = np.zeros(1, dtype=np.int64)
        rec = np.empty((record_rows, frame_loop.N_REC))
        rec_filled = np.zeros(1, dtype=np.int64)
        code = self._run_leg(params, leg, what, buf, filled, rec, rec_filled)
        rows_flown = self._rows.end_leg(every)
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
                self._rows.slice(buf, filled)
                if code != legs.EXIT_PAUSE:
                    return code
                leg = leg._replace(resume=1)
                if hooks.on_slice is not None:
                    hooks.on_slice(self, what)
                if self.frame >= step_at:
                    params = self._pause(hooks, what, params)
        except BaseException:
            self._rows.slice(buf, filled)
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

    def _drain_journal(self):
        """Move what the frame loop journaled into the journal (and the orbit's entries)."""
        s = self.state
        before = len(self.journal.events)
        if s.journal_n[0] or s.journal_n[1]:
            self.journal.drain(s.journal, s.journal_n, self._mode, self._decoder)
        if self.params.orbit.n > 0 and self._orbit_journal.note(self):
            # the slice's entries in the order of time (the loop's, then the orbit's, stably)
            ev = self.journal.events
            ev[before:] = sorted(ev[before:], key=lambda e: e["t_s"])

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
            self._rows.end_leg(True)  # the part of a leg flown before an exception ended it
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
        """Truth where Mode 6-2 judged it on target: :func:`allsky.sim.record.on_target`."""
        return record.on_target(self)

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
        """Every target begun, in flight order (:func:`allsky.sim.record.targets`)."""
        return record.targets(self)

    # -- ground commands (allsky.sim.commands) ----------------------------------
    @property
    def mode_in_flight(self):
        """Index in ``plan`` of the mode being flown; None between modes."""
        return self.next_mode if self._in_mode else None

    def fly_on_with(self, cfg) -> None:
        """Fly on with scenario ``cfg`` from this frame boundary, parameters rebuilt.

        For :func:`allsky.sim.commands.amend`: a leg in flight goes on with them.
        """
        self.cfg = cfg
        params = build_params(cfg)
        self.params = params if self._telemetry else params._replace(telemetry_every=0)
        self._amended = True
        self._decoder = self._new_decoder()

    def interrupt(self, reason) -> None:
        """End the mode being flown at this frame boundary, ``reason`` in its exit."""
        if self._in_mode:
            self._interrupt = reason or "ended"

    # -- results ---------------------------------------------------------------
    def telemetry(self, start_row=0) -> np.ndarray:
        """The decimated telemetry recorded so far (this process), one row per record.

        Mid-leg (a hook's view) the rows of the leg in flight are included;
        ``start_row``: the rows from that one on (a live view's next rows).
        """
        return self._rows.rows(start_row, self.finished and self._telemetry)

    def orbit_telemetry(self, start_row=0):
        """The orbit's columns beside :meth:`telemetry`'s rows (from ``start_row``).

        None without an orbit.

        Columns :data:`allsky.vehicle.environment.ORBIT_COLUMNS`: time [s],
        the Sun's visible fraction, the eclipse flag, the Earth's angle from
        +x and from the tracker's boresight [deg], the glare flag
        (:func:`allsky.vehicle.environment.orbit_telemetry`).
        """
        if self.params.orbit.n == 0:
            return None
        ck = self.params.clock
        return environment.orbit_telemetry(self.params.orbit, ck, self.telemetry(start_row),
                                           record.glare_edges(self.journal, ck))

    def pointing_error_arcsec(self) -> float:
        """True angle between the roll axis and the target being flown."""
        x_body = quaternion.dcm_body_from_inertial(self.state.x[0:4])[0]
        return sky.separation_deg(x_body, self.target_direction()) * units.DEG2ARCSEC

    def locked_star(self):
        """Name of the star tracker 105 last held while in use; None before a lock."""
        k = int(self.state.locked_star[0])
        return tracker_star_names(self.cfg)[k] if k >= 0 else self.locked_before

    def calibration(self) -> dict:
        """Drifts counted and applied, register 23: :func:`allsky.sim.record.calibration`."""
        return record.calibration(self)

    def drift_dac_clipped(self) -> dict:
        """Drift counts past their DACs: :func:`allsky.sim.record.drift_dac_clipped`."""
        return record.drift_dac_clipped(self)

    def end(self) -> dict:
        """The truth at the end of the flight so far (:func:`allsky.sim.record.end`)."""
        return record.end(self)

    def summary(self) -> dict:
        """The ``--json`` summary, a stable contract (:func:`allsky.sim.record.summary`)."""
        return record.summary(self)

    def orbit_summary(self) -> dict:
        """The orbit's part of the summary (:func:`allsky.sim.record.orbit_summary`)."""
        return record.orbit_summary(self)

    def wheel_summary(self) -> dict:
        """The reaction wheels at the end (:func:`allsky.sim.record.wheel_summary`)."""
        return record.wheel_summary(self)

    # -- snapshot / resume ---------------------------------------------------------
    def snapshot(self):
        """This mode boundary, as data to resume from (:func:`allsky.sim.record.snapshot`)."""
        return record.snapshot(self)

    @classmethod
    def from_snapshot(cls, history, arrays, telemetry=True):
        """Resume a mission from a :meth:`snapshot` (its own scenario is restored).

        ``history`` and ``arrays`` are the snapshot's two parts; ``telemetry``
        as for :class:`Mission`. Raises as :func:`allsky.sim.record.resume_args`
        does (another format, a missing array).
        """
        cfg, state, next_mode, history = record.resume_args(history, arrays,
                                                            newer_state_arrays())
        return cls(cfg, telemetry=telemetry, state=state, next_mode=next_mode, history=history)


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

    Examples
    --------
    >>> import allsky
    >>> m = allsky.run_mission(allsky.load_scenario(), telemetry=False)
    >>> m.status, [record.mode for record in m.timeline]
    ('complete', ['1', '2', '3', '4', '5', '6-1', '6-2'])
    """
    m = Mission(cfg, telemetry=telemetry)
    m.run()
    return m
