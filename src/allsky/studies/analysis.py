"""Linear analysis of the attitude loops, for ``allsky analyze``.

Two parts: the per-axis stability margins of the position and rate loops
(:func:`loop_margins`), and the static characteristic of the PWPF
modulators 34/35/36, analytic and simulated (:func:`pwpf_static_characteristic`).
:func:`analyze` gives both for a scenario as plain data;
:mod:`allsky.apps.analyze` prints, writes and draws them.

Loop margins
------------

The plant is the vehicle's own python-control model: the ``nlsys`` of
:mod:`allsky.vehicle.plant_control`, linearised at attitude hold (identity
attitude, zero rate, zero torque) by :func:`allsky.vehicle.plant_control.linearize`,
which replaces the quaternion by small body-axis angles ``phi = 2 q_vec``
and drops ``q_w``. Its inputs are the body torques ``tau_x, tau_y, tau_z``
[N m], its outputs the angles ``phi_x, phi_y, phi_z`` [rad] and the body
rates ``w_x, w_y, w_z`` [rad/s]; the full inertia tensor couples the axes.

Each axis closes its loop through three blocks, interconnected by signal
name (:func:`control.interconnect`), roll shown:

=====================  ===============================================  ===========
Block                  Model                                            Signals
=====================  ===============================================  ===========
control amplifier 31   ``u_x = -RAD2ARCSEC (Kp phi_x + Kd w_x)``:       phi_x, w_x
                       position gain and the gyro rate (damping) path   -> u_x [V]
PWPF modulator 34 and  ``K_a / (tau s + 1)``: the describing gain       u_x ->
jets 39                ``K_a = torque_n_m / full_on_v`` [N m/V] and     torque_x [N m]
                       the filter's lag ``tau = pwpf.time_constant_s``
frame                  one frame ``T = frame_s`` of sampling and hold,  torque_x ->
                       a Pade approximant (:func:`control.pade`)        tau_x [N m]
=====================  ===============================================  ===========

The rate-command loop of roll (S16/S18) and yaw (S17/S19) opens the
position inputs of its amplifier: only the rate path ``-RAD2ARCSEC Kd w``
remains on that axis.

**Where the loop is cut.** One axis's loop is cut at the vehicle's torque
input: a torque ``tau_i`` is injected, the axis's frame block returns
``tau_i_cut``, and ``L_i(s) = -tau_i_cut / tau_i`` (negative feedback closes
it). The other two axes stay closed, because that is what the vehicle has:
in the holds all three loops are closed, and during a rate command (Modes 2,
4, 5, 6) the other two axes hold position. Through the products of inertia a
torque on axis ``i`` moves the others, whose loops push back on ``i``; with
them open the loop would see only the effective inertia ``1/(J^-1)_ii``.
For a diagonal tensor both cuts give the textbook loop
``C(s) K_a lag delay / (J_ii s^2)`` exactly. With the default tensor the
coupling moves the margins by under 0.01 dB and 0.01 deg
(docs/design.md).

The interconnection carries all 18 states (6 per axis). States that the cut
input cannot reach, or that cannot reach the cut output, are dropped by
their pattern of structural zeros (:func:`_reachable_and_observable`, no
tolerance involved): with a diagonal tensor this leaves the axis's own 6
states (5 for a rate loop, whose angle is not fed back), so the margins
equal the per-axis closed forms to rounding; with products of inertia all
18 (17) remain.

Assumptions, with their limits (see also docs/assumptions.md):

* **Describing gain.** A PWPF modulator with a constant input ``e`` between
  its dead zone (``K e < U_on``) and its saturation (``K (e - U_m) >= U_off``)
  keeps the valve open a fraction ``~ e / U_m`` of the time (Wie, *Space
  Vehicle Dynamics and Control*, 2nd ed., sec. 7.4), so the average torque is
  ``torque_n_m * e / full_on_v``. With the default gains this linear region
  is only a few arcsec of position error wide: beyond it the jets saturate
  and the loop is a bang-bang (phase-plane) loop whose behaviour these
  margins do not describe. They describe fine pointing.
* **Lag.** The filter's own time constant stands for the modulator's lag.
  While the modulator pulses, its filter stays between ``U_off`` and
  ``U_on`` and the fed-back ``U_m`` makes the duty cycle follow ``e``
  faster than ``tau``, so the margins probably err on the safe side (not
  measured here).
* **Delay.** One frame: a measurement taken at the start of a frame acts,
  through a torque held over the frame, about half a frame late on average,
  and the gyro's rate is the average over the previous frame (another half).
* **Attitude hold.** The linearisation point has zero rate: the gyroscopic
  coupling ``w x (J w)`` of a turning vehicle is left out. At the 1.5 deg/s
  of a rate command its Jacobian is at most ``0.026 rad/s * (J_zz - J_xx) /
  J_yy ~ 0.02 1/s``, about 1e-3 of the crossover frequency. The
  amplifiers' slow integral (``T_i`` = 10 s) is left out too: it acts two
  decades below the crossover.
"""

import math

import control
import numpy as np

from allsky.hardware import pwpf
from allsky.hardware.pwpf import pwpf_step
from allsky.jit import njit_alloc
from allsky.units import RAD2ARCSEC
from allsky.vehicle.plant_control import ANGLE_NAMES, INPUT_NAMES, RATE_NAMES, linearize
from allsky.vocabulary import AXES

#: Axes with a rate-command loop and the switches that make it (SPEC.md / patent Fig. 1).
RATE_LOOP_AXES = {"roll": "S16/S18", "yaw": "S17/S19"}
#: Patent numerals of each axis's control amplifier, PWPF modulator and jets.
AMPLIFIERS, MODULATORS, JETS = (31, 32, 33), (34, 35, 36), (39, 40, 41)
#: Order of the one-frame delay's Pade approximant; its phase error at the
#: default crossover (~17 rad/s, 0.01 s frame: wT ~ 0.17) is negligible.
PADE_ORDER = 3
#: Suffix of the torque an axis's loop returns where it is cut.
CUT_SUFFIX = "_cut"


def _static(gain, inputs, outputs, name):
    """A static gain (no states) as a named ``StateSpace``."""
    d = np.atleast_2d(np.asarray(gain, dtype=float))
    return control.ss(np.zeros((0, 0)), np.zeros((0, d.shape[1])), np.zeros((d.shape[0], 0)), d,
                      inputs=inputs, outputs=outputs, name=name)


def axis_path(axis, torque_n_m, full_on_v, pwpf_time_constant_s, position_gain_v_per_arcsec,
              rate_gain_v_per_arcsec_s, frame_s, rate_commanded=False, cut=False) -> list:
    """One axis's control amplifier, modulator and jets, and frame, as named systems.

    Parameters
    ----------
    axis : int
        0 roll, 1 pitch, 2 yaw.
    torque_n_m : float
        [N m] Torque of the axis's jet couple, ``2 F r``.
    full_on_v : float
        [V] The modulator's fed-back full-on voltage ``U_m``.
    pwpf_time_constant_s : float
        [s] The modulator filter's time constant; 0 leaves the lag out.
    position_gain_v_per_arcsec : float
        [V/arcsec] Control amplifier position gain ``Kp``.
    rate_gain_v_per_arcsec_s : float
        [V/(arcsec/s)] Control amplifier rate gain ``Kd``.
    frame_s : float
        [s] Frame; 0 leaves the delay out.
    rate_commanded : bool, optional
        The position inputs are open (S16/S18, S17/S19 closed): the
        amplifier reads the rate alone.
    cut : bool, optional
        Name the torque this path returns ``tau_i_cut`` instead of the
        vehicle's input ``tau_i``, so that an interconnection leaves the loop
        open there.

    Returns
    -------
    list of control.StateSpace
        Amplifier (``phi_i``, ``w_i`` [rad, rad/s] -> ``u_i`` [V]), modulator
        and jets (``u_i`` -> ``torque_i`` [N m]) and frame (``torque_i`` ->
        ``tau_i`` [N m]).
    """
    c = "xyz"[axis]
    phi, w, u, torque = ANGLE_NAMES[axis], RATE_NAMES[axis], f"u_{c}", f"torque_{c}"
    tau = INPUT_NAMES[axis] + (CUT_SUFFIX if cut else "")
    kd_v_per_rad_s = rate_gain_v_per_arcsec_s * RAD2ARCSEC
    if rate_commanded:
        amplifier = _static([[-kd_v_per_rad_s]], [w], [u], f"control_amplifier_{AMPLIFIERS[axis]}")
    else:
        amplifier = _static([[-position_gain_v_per_arcsec * RAD2ARCSEC, -kd_v_per_rad_s]],
                            [phi, w], [u], f"control_amplifier_{AMPLIFIERS[axis]}")
    gain_n_m_per_v = torque_n_m / full_on_v
    modulator_name = f"modulator_{MODULATORS[axis]}_jets_{JETS[axis]}"
    if pwpf_time_constant_s > 0.0:
        modulator = control.ss(control.tf([gain_n_m_per_v], [pwpf_time_constant_s, 1.0]),
                               inputs=[u], outputs=[torque], name=modulator_name)
    else:
        modulator = _static([[gain_n_m_per_v]], [u], [torque], modulator_name)
    if frame_s > 0.0:
        frame = control.ss(control.tf(*control.pade(frame_s, PADE_ORDER)), inputs=[torque],
                           outputs=[tau], name=f"frame_{c}")
    else:
        frame = _static([[1.0]], [torque], [tau], f"frame_{c}")
    return [amplifier, modulator, frame]


def _reachable_and_observable(sys: control.StateSpace) -> control.StateSpace:
    """``sys`` without the states its input cannot reach or that cannot reach its output.

    Read from the non-zero pattern of A, B and C: state ``j`` drives state
    ``k`` when ``A[k, j] != 0``. A structural zero is an exact zero, so the
    reduction needs no tolerance and changes no transfer function.
    """
    a, b, c = sys.A, sys.B, sys.C
    drives = a != 0.0

    def closure(seed, step):
        found = seed.copy()
        while True:
            grown = found | step(found)
            if np.array_equal(grown, found):
                return found
            found = grown

    reached = closure(b.any(axis=1), lambda s: drives[:, s].any(axis=1))
    seen = closure(c.any(axis=0), lambda s: drives[s, :].any(axis=0))
    keep = np.flatnonzero(reached & seen)
    return control.ss(a[np.ix_(keep, keep)], b[keep, :], c[:, keep], sys.D,
                      states=[sys.state_labels[k] for k in keep], inputs=sys.input_labels,
                      outputs=sys.output_labels, name=sys.name)


def loop_transfer(inertia_kg_m2, torque_n_m, full_on_v, pwpf_time_constant_s,
                  position_gain_v_per_arcsec, rate_gain_v_per_arcsec_s, frame_s, axis,
                  rate_commanded=False, vehicle=None) -> control.StateSpace:
    """Loop transfer function L(s) of one axis, cut at its torque input.

    The other axes' loops stay closed.

    Parameters
    ----------
    inertia_kg_m2 : array_like, shape (3, 3)
        [kg m^2] Full inertia tensor, body axes (roll, pitch, yaw).
    torque_n_m : array_like, shape (3,)
        [N m] Jet couple torque per axis.
    full_on_v : float
        [V] PWPF full-on voltage ``U_m``.
    pwpf_time_constant_s : float
        [s] PWPF filter time constant (0: no lag).
    position_gain_v_per_arcsec : array_like, shape (3,)
        [V/arcsec] Control amplifier position gains.
    rate_gain_v_per_arcsec_s : array_like, shape (3,)
        [V/(arcsec/s)] Control amplifier rate gains.
    frame_s : float
        [s] Frame (0: no delay).
    axis : int
        The axis whose loop is cut: 0 roll, 1 pitch, 2 yaw.
    rate_commanded : bool, optional
        Cut the axis's rate-command loop (position inputs open) instead of
        its position loop. The other axes hold position either way.
    vehicle : control.StateSpace, optional
        :func:`allsky.vehicle.plant_control.linearize` of ``inertia_kg_m2``,
        if already built.

    Returns
    -------
    control.StateSpace
        SISO, dimensionless: input the injected torque ``tau_i`` [N m],
        output the torque the loop returns, sign reversed, so that
        ``1 + L`` is the return difference. Only the states that take part
        (:func:`_reachable_and_observable`).
    """
    vehicle = linearize(inertia_kg_m2) if vehicle is None else vehicle
    torque = np.broadcast_to(np.asarray(torque_n_m, dtype=float), (3,))
    kp = np.broadcast_to(np.asarray(position_gain_v_per_arcsec, dtype=float), (3,))
    kd = np.broadcast_to(np.asarray(rate_gain_v_per_arcsec_s, dtype=float), (3,))
    systems = [vehicle]
    for i in range(3):
        systems += axis_path(i, torque[i], full_on_v, pwpf_time_constant_s, kp[i], kd[i],
                             frame_s, rate_commanded=rate_commanded and i == axis,
                             cut=i == axis)
    cut_in = INPUT_NAMES[axis]
    loop = control.interconnect(
        systems, inplist=[cut_in], outlist=["-" + cut_in + CUT_SUFFIX], inputs=[cut_in],
        outputs=[cut_in + CUT_SUFFIX], name=f"{'rate' if rate_commanded else 'position'} "
                                             f"{AXES[axis]}",
        ignore_outputs=[ANGLE_NAMES[axis]] if rate_commanded else None)
    return _reachable_and_observable(loop)


def axis_loops(inertia_kg_m2, torque_n_m, full_on_v, pwpf_time_constant_s,
               position_gain_v_per_arcsec, rate_gain_v_per_arcsec_s, frame_s) -> dict:
    """Every loop of :func:`loop_transfer`, as ``{name: L(s)}``.

    Names run from ``"position roll"`` to ``"rate yaw"``: the position loops
    of the three axes first, then the rate-command loops of
    :data:`RATE_LOOP_AXES`.

    Parameters
    ----------
    inertia_kg_m2 : array_like, shape (3, 3)
        [kg m^2] Full inertia tensor, body axes (roll, pitch, yaw).
    torque_n_m : array_like, shape (3,)
        [N m] Jet couple torque per axis.
    full_on_v : float
        [V] PWPF full-on voltage ``U_m``.
    pwpf_time_constant_s : float
        [s] PWPF filter time constant (0: no lag).
    position_gain_v_per_arcsec : array_like, shape (3,)
        [V/arcsec] Control amplifier position gains.
    rate_gain_v_per_arcsec_s : array_like, shape (3,)
        [V/(arcsec/s)] Control amplifier rate gains.
    frame_s : float
        [s] Frame (0: no delay).
    """
    args = (inertia_kg_m2, torque_n_m, full_on_v, pwpf_time_constant_s,
            position_gain_v_per_arcsec, rate_gain_v_per_arcsec_s, frame_s)
    vehicle = linearize(inertia_kg_m2)
    loops = {f"position {a}": loop_transfer(*args, i, vehicle=vehicle)
             for i, a in enumerate(AXES)}
    loops.update({f"rate {a}": loop_transfer(*args, i, rate_commanded=True, vehicle=vehicle)
                  for i, a in enumerate(AXES) if a in RATE_LOOP_AXES})
    return loops


def _margins(loop):
    """Margins of a loop transfer function as a dict of plain floats."""
    gm, pm, _, w_pc, w_gc, _ = control.stability_margins(loop)
    closed = control.feedback(loop, 1)
    return {
        "gain_margin_db": 20.0 * math.log10(gm) if np.isfinite(gm) and gm > 0 else math.inf,
        "phase_margin_deg": float(pm),
        "crossover_rad_s": float(w_gc),
        "phase_crossover_rad_s": float(w_pc) if np.isfinite(w_pc) else math.nan,
        "bandwidth_rad_s": float(control.bandwidth(closed)),
        "stable": bool(np.all(np.real(closed.poles()) < 0.0)),
    }


def loop_margins(inertia_kg_m2, torque_n_m, full_on_v, pwpf_time_constant_s,
                 position_gain_v_per_arcsec, rate_gain_v_per_arcsec_s, frame_s) -> dict:
    """Gain and phase margins, crossover and bandwidth of every axis's loops.

    Each loop is cut at its axis's torque input with the other axes closed
    (:func:`loop_transfer`).

    Parameters
    ----------
    inertia_kg_m2 : array_like, shape (3, 3)
        [kg m^2] Full inertia tensor, body axes (roll, pitch, yaw).
    torque_n_m : array_like, shape (3,)
        [N m] Jet couple torque per axis, ``2 * thrust_n * moment_arm_m``.
    full_on_v : float
        [V] PWPF full-on voltage ``U_m``.
    pwpf_time_constant_s : float
        [s] PWPF filter time constant (0: no lag).
    position_gain_v_per_arcsec : array_like, shape (3,)
        [V/arcsec] Control amplifier position gains.
    rate_gain_v_per_arcsec_s : array_like, shape (3,)
        [V/(arcsec/s)] Control amplifier rate gains.
    frame_s : float
        [s] Frame (0: no delay).

    Returns
    -------
    dict
        ``{"position": {axis: m}, "rate": {axis: m}}`` with ``axis`` in
        :data:`AXES` (rate: roll and yaw only, see :data:`RATE_LOOP_AXES`), and
        each ``m`` a dict of ``gain_margin_db`` (inf when the phase never
        crosses -180 deg), ``phase_margin_deg``, ``crossover_rad_s`` (gain
        crossover), ``phase_crossover_rad_s`` (nan if none),
        ``bandwidth_rad_s`` (closed loop, -3 dB) and ``stable`` (every pole
        of the closed loop's states in the left half-plane). Position
        entries also carry, to show how much the axes couple,
        ``inertia_kg_m2`` (``J_ii``), ``effective_inertia_kg_m2``
        (``1/(J^-1)_ii``, what the axis sees with the other axes open) and
        ``coupling_ratio`` (``max_j!=i |(J^-1)_ij| / (J^-1)_ii``, the angular
        acceleration of axis ``i`` per unit torque on axis ``j``, relative to
        its own).
    """
    j = np.asarray(inertia_kg_m2, dtype=float).reshape(3, 3)
    j_inv = np.linalg.inv(j)
    loops = axis_loops(j, torque_n_m, full_on_v, pwpf_time_constant_s,
                       position_gain_v_per_arcsec, rate_gain_v_per_arcsec_s, frame_s)
    out = {"position": {}, "rate": {}}
    for name, loop in loops.items():
        kind, axis = name.split()
        m = _margins(loop)
        if kind == "position":
            i = AXES.index(axis)
            m["inertia_kg_m2"] = float(j[i, i])
            m["effective_inertia_kg_m2"] = float(1.0 / j_inv[i, i])
            m["coupling_ratio"] = float(max(abs(j_inv[i, k]) for k in range(3) if k != i)
                                        / j_inv[i, i])
        out[kind][axis] = m
    return out


def scenario_loop_arguments(cfg) -> dict:
    """Keyword arguments of :func:`loop_margins` taken from a loaded scenario.

    Parameters
    ----------
    cfg : allsky.config.scenario.Scenario
        A validated scenario (:func:`allsky.config.scenario.load_scenario`).

    Returns
    -------
    dict
        Plain numbers, torque per axis ``2 * thrust_n * moment_arm_m`` [N m]
        (as :func:`allsky.hardware.jets.make_params`).
    """
    return {
        "inertia_kg_m2": np.asarray(cfg.vehicle.inertia_kg_m2, dtype=float),
        "torque_n_m": 2.0 * np.asarray(cfg.jets.thrust_n, dtype=float)
        * np.asarray(cfg.jets.moment_arm_m, dtype=float),
        "full_on_v": float(cfg.pwpf.full_on_v),
        "pwpf_time_constant_s": float(cfg.pwpf.time_constant_s),
        "position_gain_v_per_arcsec": np.asarray(cfg.control.position_gain_v_per_arcsec, dtype=float),
        "rate_gain_v_per_arcsec_s": np.asarray(cfg.control.rate_gain_v_per_arcsec_s, dtype=float),
        "frame_s": float(cfg.mission.frame_s),
    }


# -- PWPF static characteristic ------------------------------------------------

#: Where the static characteristic is sampled, as fractions of the way from the
#: dead-zone edge U_on/K (0) to saturation U_m + U_off/K (1).
PWPF_FRACTIONS = (-1.0, -0.5, -0.1, *np.round(np.linspace(0.02, 0.98, 25), 4), 1.05, 1.2)
#: [-] Simulation step of the "fine" simulated curve, as a fraction of the frame.
FINE_STEP_FRACTION = 0.01
#: Cycles simulated per input (at least), and the cap on simulated time [s].
PWPF_CYCLES = 25
PWPF_MAX_SIM_S = 60.0


def pwpf_duty_cycle(filter_gain, time_constant_s, on_threshold_v, off_threshold_v, full_on_v,
                    input_v) -> float:
    """Duty cycle of a continuous-time PWPF modulator for a constant input.

    Derivation (Wie, *Space Vehicle Dynamics and Control*, 2nd ed., sec. 7.4,
    worked here for the modulator of :mod:`allsky.hardware.pwpf`). With filter gain
    ``K``, time constant ``tau``, on/off thresholds ``U_on > U_off`` and
    fed-back full-on value ``U_m``, the filter obeys, for ``e > 0`` and
    valve state ``y`` in {0, 1}::

        tau df/dt = K (e - U_m y) - f

    so between switchings ``f`` relaxes exponentially towards its end value
    ``f_inf`` (``K e`` with the valve shut, ``K (e - U_m)`` with it open)::

        f(t) = f_inf + (f(0) - f_inf) exp(-t / tau)

    In the limit cycle the valve opens when ``f`` rises to ``U_on`` and shuts
    when it falls to ``U_off``. Solving ``f(T) = threshold``:

    * off phase, ``U_off -> U_on`` towards ``K e``:
      ``T_off = tau ln((K e - U_off) / (K e - U_on))``, finite only if
      ``K e > U_on`` (else the dead zone: never fires);
    * on phase, ``U_on -> U_off`` towards ``K (e - U_m)``:
      ``T_on = tau ln((U_on - K (e - U_m)) / (U_off - K (e - U_m)))``, finite
      only if ``K (e - U_m) < U_off`` (else saturation: always open);
    * duty cycle ``D = T_on / (T_on + T_off)``, pulse frequency
      ``1 / (T_on + T_off)``.

    Check, and the link to the describing gain: ``f`` is periodic, so the
    cycle mean of ``df/dt`` is zero and ``K (e - U_m D) = f_mean`` with
    ``U_off < f_mean < U_on``. Hence ``D = (K e - f_mean) / (K U_m)``, that is
    the linear ``e / U_m`` lowered by between ``U_off / (K U_m)`` and
    ``U_on / (K U_m)``. Near the dead-zone edge the shortest pulse is
    ``T_on ~ tau (U_on - U_off) / (K U_m)``.

    Parameters
    ----------
    filter_gain : float
        [-] ``K``.
    time_constant_s : float
        [s] ``tau``.
    on_threshold_v, off_threshold_v : float
        [V] ``U_on``, ``U_off``.
    full_on_v : float
        [V] ``U_m``.
    input_v : float
        [V] Constant input ``e``; the characteristic is odd in ``e``.

    Returns
    -------
    float
        Duty cycle in [0, 1]: 0 in the dead zone, 1 in saturation.
    """
    t_on, t_off = pwpf.static_on_off_times_s(filter_gain, time_constant_s, on_threshold_v,
                                             off_threshold_v, full_on_v, abs(input_v))
    if t_on == 0.0:
        return 0.0
    if math.isinf(t_on):
        return 1.0
    return t_on / (t_on + t_off)


@njit_alloc
def _valve_trace(p, input_v, n_steps):
    """Valve commands of modulator 0 over ``n_steps`` steps, from rest, constant input."""
    filter_v = np.zeros(3)
    out = np.zeros(3, dtype=np.int64)
    on_frames = np.zeros(3, dtype=np.int64)
    y = np.empty(n_steps, dtype=np.int64)
    for i in range(n_steps):
        y[i] = pwpf_step(p, 0, input_v, filter_v, out, on_frames)
    return y



def simulated_duty_cycle(params: pwpf.PwpfParams, input_v, step_s, duration_s) -> float:
    """Duty cycle of the simulated modulator for a constant input.

    The modulator is :func:`allsky.hardware.pwpf.pwpf_step`.

    The modulator starts from rest; the duty cycle is the fraction of steps
    the valve is open over the whole cycles between the second and the last
    switch-on (the first cycle starts from rest). With fewer than three
    switch-ons it is the fraction over the second half of the run (0 in the
    dead zone, 1 in saturation).

    Parameters
    ----------
    params : allsky.hardware.pwpf.PwpfParams
        Modulator parameters for the step ``step_s`` (:func:`allsky.hardware.pwpf.make_params`).
    input_v : float
        [V] Constant input.
    step_s : float
        [s] Simulation step (the ``frame_s`` the parameters were made for).
    duration_s : float
        [s] Simulated time.
    """
    y = _valve_trace(params, float(input_v), max(2, round(duration_s / step_s)))
    on = y != 0
    starts = np.flatnonzero(on[1:] & ~on[:-1]) + 1
    if starts.size >= 3:
        return float(np.mean(on[starts[1]:starts[-1]]))
    return float(np.mean(on[on.size // 2:]))


def pwpf_static_characteristic(filter_gain, time_constant_s, on_threshold_v, off_threshold_v,
                               full_on_v, min_on_time_s, frame_s, inputs_v=None) -> dict:
    """PWPF static characteristic: analytic, simulated fine, simulated at the frame.

    Parameters
    ----------
    filter_gain, time_constant_s, on_threshold_v, off_threshold_v, full_on_v : float
        As :func:`pwpf_duty_cycle` ([-], [s], [V], [V], [V]).
    min_on_time_s : float
        [s] Valve minimum on-time, applied in the simulation at the frame.
    frame_s : float
        [s] Mission frame. The "fine" simulation steps ``frame_s *
        FINE_STEP_FRACTION`` with a minimum on-time of one step, to show
        the discrete modulator converging on the continuous formulas; the
        "frame" simulation is the modulator as flown.
    inputs_v : sequence of float, optional
        [V] Inputs; default :data:`PWPF_FRACTIONS` of the linear region.

    Returns
    -------
    dict
        The parameters; ``dead_zone_v`` (``U_on/K``) and ``saturation_v``
        (``U_m + U_off/K``); per input: ``input_v``, ``t_on_s``, ``t_off_s``
        (analytic, None where infinite), ``duty_analytic``,
        ``duty_simulated_fine``, ``duty_simulated_frame``; and
        ``max_error_fine``, ``max_error_frame``: the largest absolute duty
        difference from the analytic curve over the inputs.
    """
    k, tau, u_on, u_off, u_m = (float(filter_gain), float(time_constant_s),
                                float(on_threshold_v), float(off_threshold_v), float(full_on_v))
    dead, sat = u_on / k, u_m + u_off / k
    if inputs_v is None:
        inputs_v = [dead + f * (sat - dead) if f >= 0 else (1.0 + f) * dead
                    for f in PWPF_FRACTIONS]
    fine_s = frame_s * FINE_STEP_FRACTION
    p_fine = pwpf.make_params(k, tau, u_on, u_off, u_m, fine_s, fine_s)
    p_frame = pwpf.make_params(k, tau, u_on, u_off, u_m, min_on_time_s, frame_s)
    out = {"filter_gain": k, "time_constant_s": tau, "on_threshold_v": u_on,
           "off_threshold_v": u_off, "full_on_v": u_m, "min_on_time_s": float(min_on_time_s),
           "frame_s": float(frame_s), "fine_step_s": fine_s, "dead_zone_v": dead,
           "saturation_v": sat, "input_v": [], "t_on_s": [], "t_off_s": [],
           "duty_analytic": [], "duty_simulated_fine": [], "duty_simulated_frame": []}
    for e in inputs_v:
        t_on, t_off = pwpf.static_on_off_times_s(k, tau, u_on, u_off, u_m, abs(e))
        period = t_on + t_off
        duration = min(max(PWPF_CYCLES * period, 2.0), PWPF_MAX_SIM_S) \
            if math.isfinite(period) else 2.0
        out["input_v"].append(float(e))
        out["t_on_s"].append(t_on if math.isfinite(t_on) else None)
        out["t_off_s"].append(t_off if math.isfinite(t_off) else None)
        out["duty_analytic"].append(pwpf_duty_cycle(k, tau, u_on, u_off, u_m, e))
        out["duty_simulated_fine"].append(simulated_duty_cycle(p_fine, e, fine_s, duration))
        out["duty_simulated_frame"].append(
            simulated_duty_cycle(p_frame, e, frame_s, PWPF_MAX_SIM_S))
    a = np.array(out["duty_analytic"])
    out["max_error_fine"] = float(np.max(np.abs(np.array(out["duty_simulated_fine"]) - a)))
    out["max_error_frame"] = float(np.max(np.abs(np.array(out["duty_simulated_frame"]) - a)))
    return out


def scenario_pwpf_arguments(cfg) -> dict:
    """Keyword arguments of :func:`pwpf_static_characteristic` from scenario ``cfg``."""
    return {"filter_gain": cfg.pwpf.filter_gain, "time_constant_s": cfg.pwpf.time_constant_s,
            "on_threshold_v": cfg.pwpf.on_threshold_v,
            "off_threshold_v": cfg.pwpf.off_threshold_v, "full_on_v": cfg.pwpf.full_on_v,
            "min_on_time_s": cfg.jets.min_on_time_s, "frame_s": cfg.mission.frame_s}


# -- a scenario's analysis ------------------------------------------------------

def scenario_loops(cfg) -> dict:
    """Loop transfer functions of scenario ``cfg``: :func:`axis_loops` of its values."""
    return axis_loops(**scenario_loop_arguments(cfg))


def frequency_responses(loops: dict, omega_rad_s) -> dict:
    """``{name: (omega, |L(j omega)|, phase)}`` of each loop, phase unwrapped.

    ``loops`` are ``{name: L(s)}`` (:func:`axis_loops`), evaluated at the
    angular frequencies ``omega_rad_s`` [rad/s]. Units: omega [rad/s],
    ``|L(j omega)|`` [-], phase [deg].
    """
    w = np.asarray(omega_rad_s, dtype=float)
    out = {}
    for name, loop in loops.items():
        r = control.frequency_response(loop, w)
        out[name] = (w, np.abs(r.complex).ravel(),
                     np.degrees(np.unwrap(np.angle(r.complex).ravel())))
    return out


def analyze(cfg) -> dict:
    """Loop margins and PWPF static characteristic of a scenario (``allsky analyze``).

    ``cfg`` is the loaded scenario.

    Returns
    -------
    dict
        ``{"margins": loop_margins(...), "pwpf": pwpf_static_characteristic(...)}``.
    """
    return {"margins": loop_margins(**scenario_loop_arguments(cfg)),
            "pwpf": pwpf_static_characteristic(**scenario_pwpf_arguments(cfg))}
