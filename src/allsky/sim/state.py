"""The mission state and the frame loop's parameters.

:class:`Params` is everything the frame loop reads, built once per mission
from the scenario (:func:`allsky.sim.mission.build_params`); :class:`State`
is everything it changes, as preallocated numpy arrays mutated in place,
so that a mission can be saved and resumed between legs.
"""

from typing import NamedTuple

import numpy as np

from allsky.clock import ClockParams
from allsky.computer.cpu import N_WORK
from allsky.computer.word_registers import N_PROGRAMMED, neutral_computed
from allsky.config.faults import MAX_FAULTS
from allsky.config.schema import WHEELS_MAX
from allsky.hardware.control_amp import ControlParams
from allsky.hardware.gyro import GyroParams
from allsky.hardware.jets import JetParams
from allsky.hardware.pwpf import PwpfParams
from allsky.hardware.star_tracker import StarTrackerParams, new_lock
from allsky.hardware.sun_acquisition import SunAcquisitionParams
from allsky.hardware.sun_sensor import SunSensorParams
from allsky.hardware.switch_bank import new_bank
from allsky.hardware.vfc import VfcParams
from allsky.hardware.wiring import Routing
from allsky.sequencer.dither import DitherParams
from allsky.sequencer.legs import N_CLOCK
from allsky.sim import journal
from allsky.sim.faults import FaultParams, new_fault_state
from allsky.vehicle.environment import OrbitParams
from allsky.vehicle.plant import RigidBodyParams
from allsky.vehicle.wheels import WheelParams


class ElectronicsParams(NamedTuple):
    """Word lengths and scalings of the counters, DACs, registers and rate commands."""

    counter_bits: int  #: [bit] up/down counters 14, 16, 18
    drift_counter_bits: int  #: [bit] drift counters 13, 15, 17
    overflow_mode: int  #: updown_counter.WRAP or SATURATE
    drift_dac_bits: int  #: [bit] drift DACs 7, 9, 11
    drift_lsb_arcsec_s: float  #: [arcsec/s per count] pulse weight / drift interval
    register_bits: int  #: [bit] registers 25-27 and DACs 28-30
    register_lsb_arcsec: float  #: [arcsec]
    rate_command_arcsec_s: float  #: [arcsec/s] rate-command modules 120, 128
    computer_step_frames: int  #: [frames] per S7/S8 step


class SequencerParams(NamedTuple):
    """Thresholds of master sequencer 20's watch."""

    settle_threshold_arcsec: float  #: [arcsec] "settled" error bound (50")
    handover_arcsec: float  #: [arcsec] hand-over threshold (7200")
    #: [frames] Sun/star absence tolerated while in use: lost after more frames than this
    #: (``sequencer.sensor_loss_s``, :func:`allsky.clock.frames_within`)
    sensor_loss_frames: int


class Params(NamedTuple):
    """Everything the frame loop reads; built once per mission.

    Built by :func:`allsky.sim.mission.build_params` from the scenario.
    """

    frame_s: float  #: [s] the frame step, ``clock.num / clock.den``
    clock: ClockParams  #: the frame length as a fraction: times are computed from frames
    telemetry_every: int  #: [frames] per telemetry row (0 = none)
    sun0_inertial: np.ndarray  #: [-] Sun direction at t = 0
    sun_rate_inertial: np.ndarray  #: [1/s] its time derivative (the Sun's ~1 deg/day motion)
    plant: RigidBodyParams  #: vehicle 100's mass properties (less the wheels' spin inertia)
    gyro: GyroParams  #: rate gyros 1, 2, 3
    sun: SunSensorParams  #: sun sensor 104 and the coarse sun eyes
    tracker: StarTrackerParams  #: star tracker 105, with the stars its window passes
    vfc: VfcParams  #: converters 8, 10, 12
    electronics: ElectronicsParams  #: word lengths and scalings of counters, DACs, registers
    control: ControlParams  #: control amplifiers 31, 32, 33
    pwpf: PwpfParams  #: modulators 34, 35, 36
    jets: JetParams  #: jets 39, 40, 41 and their feed from tank 108
    mode1: SunAcquisitionParams  #: the Mode 1 sun-acquisition controller
    sequencer: SequencerParams  #: thresholds of master sequencer 20's watch
    dither: DitherParams  #: dither generator and feed-forward (comparison mode)
    dither_sample_frames: int  #: [frames] per sample of the dither record
    routing: Routing  #: the switch wiring as index arrays (allsky.hardware.wiring.ROUTING)
    #: what turns the amplifiers' output into torque: allsky.vehicle.wheels.ACTUATOR_JETS
    #: (modulators 34-36, jets 39-41) or ACTUATOR_WHEELS, one constant for the mission
    actuator: int
    wheels: WheelParams  #: the reaction-wheel array (read only when actuator is the wheels)
    faults: FaultParams  #: the scenario's faults (allsky.sim.faults; n = 0: none)
    #: the orbit's samples (allsky.vehicle.environment; n = 0: none, kind = "none")
    orbit: OrbitParams


class State(NamedTuple):
    """The whole mission state, as arrays (mutated in place by the loop)."""

    #: (1,) int64 the mission clock: frames since ejection (the time is
    #: :func:`allsky.clock.time_s` of it, computed, never summed)
    frame: np.ndarray
    x: np.ndarray  #: (7,) plant state [q_w, q_x, q_y, q_z, w (rad/s)]
    dtheta_rad: np.ndarray  #: (3,) body-angle increment of the last frame
    gyro_rw_arcsec_s: np.ndarray  #: (3,) gyro rate-random-walk state
    vfc_residue_pulses: np.ndarray  #: (3,) fractional pulses carried by converters 8/10/12
    counters: np.ndarray  #: (3,) int64 up/down counters 14, 16, 18 [pulses]
    drift_counters: np.ndarray  #: (3,) int64 drift counters 13, 15, 17 [pulses]
    overflow: np.ndarray  #: (6,) int64 latched overflow flags (14,16,18,13,15,17)
    registers: np.ndarray  #: (3,) int64 storage registers 25, 26, 27 [LSB]
    switches: np.ndarray  #: (20,) uint8 switch bank S1-S19 (see switch_bank)
    rate_sign: np.ndarray  #: (2,) int64 direction of rate-command modules 120, 128
    amp_integral_arcsec: np.ndarray  #: (3,) control-amplifier integrals
    pwpf_filter_v: np.ndarray  #: (3,) modulator filter states
    pwpf_out: np.ndarray  #: (3,) int64 valve commands -1/0/+1
    pwpf_on_frames: np.ndarray  #: (3,) int64 frames since each valve opened
    propellant_kg: np.ndarray  #: (1,)
    cpu: np.ndarray  #: (N_WORK,) CPU 22 working store
    word23: np.ndarray  #: (6,) computed word register 23
    word24: np.ndarray  #: (2,) programmed word register 24 [arcsec]
    excursion_ref_q: np.ndarray  #: (4,) attitude the mission wants; [0,0,0,0] = not tracked
    max_excursion_rad: np.ndarray  #: (1,) largest rotation away from it so far
    leg_clock: np.ndarray  #: (N_CLOCK,) int64 [frames] progress of the current leg (CLOCK_*)
    rng: np.ndarray  #: (1,) uint64 state of the noise generator (allsky.gauss)
    #: (1,) int64 star tracker 105 last held while in use: index in
    #: ``Params.tracker.stars_inertial``; -1 = none yet
    locked_star: np.ndarray
    #: (star_tracker.N_LOCK,) star tracker 105's memory: the target it holds, the stars its
    #: cone-angle check refused, the bright gate (allsky.hardware.star_tracker)
    tracker_lock: np.ndarray
    #: (3, MAX_FAULTS) onsets [s] and memories of the faults (allsky.sim.faults)
    fault_state: np.ndarray
    #: (WHEELS_MAX,) [N m s] momentum of each reaction wheel about its axis (the first
    #: ``len(wheels.axes)`` are used; zero on the jet vehicle)
    wheel_h: np.ndarray
    #: (4,) int64 momentum unloader: [unloading 0/1, frames fired per body axis]
    wheel_unload: np.ndarray
    wheel_peak_fraction: np.ndarray  #: (1,) largest ``|h_i| / limit_i`` of any wheel so far
    #: (3,) [-] unit vector to the target being flown (the true error's reference)
    target_inertial: np.ndarray
    #: (3,) [s] time each axis's modulator 34-36 has held a valve open since ejection
    jet_on_s: np.ndarray
    #: (journal.ROWS, journal.WIDTH) what the frame loop saw happen, not yet drained
    #: into the mission's journal (allsky.sim.journal)
    journal: np.ndarray
    #: (2,) int64 rows of ``journal`` filled, and rows lost to a full buffer
    journal_n: np.ndarray
    #: what the frame loop last saw, to note changes (allsky.sim.journal.SEEN_*)
    journal_seen: np.ndarray


def new_state(q0, rate0_rad_s, propellant_kg) -> State:
    """A fresh state at ejection: everything zero, switches open, neutral registers.

    Parameters
    ----------
    q0 : array_like
        [-] attitude quaternion, inertial to body, scalar first.
    rate0_rad_s : array_like
        [rad/s] body rate (the tip-off rates), body axes.
    propellant_kg : float
        [kg] propellant in tank 108.
    """
    x = np.zeros(7)
    x[0:4] = q0
    x[4:7] = rate0_rad_s
    return State(
        frame=np.zeros(1, dtype=np.int64), x=x, dtheta_rad=np.zeros(3),
        gyro_rw_arcsec_s=np.zeros(3), vfc_residue_pulses=np.zeros(3),
        counters=np.zeros(3, dtype=np.int64), drift_counters=np.zeros(3, dtype=np.int64),
        overflow=np.zeros(6, dtype=np.int64), registers=np.zeros(3, dtype=np.int64),
        switches=new_bank(), rate_sign=np.ones(2, dtype=np.int64),
        amp_integral_arcsec=np.zeros(3), pwpf_filter_v=np.zeros(3), pwpf_out=np.zeros(3, dtype=np.int64),
        pwpf_on_frames=np.zeros(3, dtype=np.int64),
        propellant_kg=np.array([float(propellant_kg)]), cpu=np.zeros(N_WORK),
        word23=neutral_computed(), word24=np.zeros(N_PROGRAMMED),
        excursion_ref_q=np.zeros(4), max_excursion_rad=np.zeros(1), leg_clock=np.zeros(N_CLOCK, dtype=np.int64),
        rng=np.ones(1, dtype=np.uint64), locked_star=np.full(1, -1, dtype=np.int64),
        tracker_lock=new_lock(),
        fault_state=new_fault_state(),
        wheel_h=np.zeros(WHEELS_MAX), wheel_unload=np.zeros(4, dtype=np.int64),
        wheel_peak_fraction=np.zeros(1), target_inertial=np.array([1.0, 0.0, 0.0]),
        jet_on_s=np.zeros(3), **_journal_arrays(),
    )


def _journal_arrays() -> dict:
    buf, n, seen = journal.new_buffer(WHEELS_MAX, MAX_FAULTS)
    return {"journal": buf, "journal_n": n, "journal_seen": seen}
