"""Linear analysis of the attitude loops, and ``allsky analyze``.

Two parts: the per-axis stability margins of the position and rate loops
(:func:`loop_margins`), and the static characteristic of the PWPF
modulators 34/35/36, analytic and simulated (:func:`pwpf_static_characteristic`).
:func:`analyze` gives both for a scenario.

Loop margins
------------

Each axis's position loop (control amplifier 31/32/33 -> PWPF modulator
34/35/36 -> jet couple 39/40/41 -> vehicle -> sensor) is cut at the plant
input and approximated by the linear loop transfer function::

    L(s) = C(s) * K_a * 1/(tau s + 1) * e^{-T s} * 1/(J_ii s^2)

=================  ==================================================  =====
Factor             Model                                               Unit
=================  ==================================================  =====
C(s)               ``RAD2ARCSEC * (Kp + Kd s)``: amplifier's position  V/rad
                   gain plus its rate (damping) path
K_a                ``torque_n_m / full_on_v``: the describing gain of  N m/V
                   modulator + jets, average torque per volt
1/(tau s + 1)      the PWPF filter's lag, ``tau = pwpf.time_constant_s``  -
e^{-T s}           one frame ``T = frame_s`` of sampling and hold,        -
                   as a Pade approximant (:func:`control.pade`)
1/(J_ii s^2)       the plant, diagonal inertia element                 rad/(N m s^2)
=================  ==================================================  =====

The rate-command loop of roll (S16/S18) and yaw (S17/S19) opens the position
inputs and closes the rate path alone: ``L(s) = RAD2ARCSEC Kd K_a lag delay
/ (J_ii s)``.

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
* **Diagonal inertia.** Each axis sees ``1/J_ii``; the products of inertia
  couple axes. :func:`loop_margins` reports, per axis, the coupling ratio
  ``max_j!=i |(J^-1)_ij| / (J^-1)_ii`` (the angular acceleration of axis
  ``i`` per unit torque on axis ``j``, relative to its own) and the effective
  inertia ``1 / (J^-1)_ii`` next to ``J_ii``.
"""

import json
import math
from pathlib import Path

import control
import numpy as np

from allsky.hardware import pwpf
from allsky.hardware.pwpf import pwpf_step
from allsky.jit import njit_alloc
from allsky.units import RAD2ARCSEC

AXES = ("roll", "pitch", "yaw")
#: Axes with a rate-command loop and the switches that make it (SPEC.md / patent Fig. 1).
RATE_LOOP_AXES = {"roll": "S16/S18", "yaw": "S17/S19"}
#: Order of the one-frame delay's Pade approximant; its phase error at the
#: default crossover (~17 rad/s, 0.01 s frame: wT ~ 0.17) is negligible.
PADE_ORDER = 3


def _actuator_and_sensor(torque_n_m, full_on_v, pwpf_time_constant_s, frame_s):
    """Describing gain [N m/V] x PWPF lag x one-frame delay, as a transfer function."""
    g = control.tf([torque_n_m / full_on_v], [1.0])
    if pwpf_time_constant_s > 0.0:
        g = g * control.tf([1.0], [pwpf_time_constant_s, 1.0])
    if frame_s > 0.0:
        num, den = control.pade(frame_s, PADE_ORDER)
        g = g * control.tf(num, den)
    return g


def position_loop(inertia_axis_kg_m2, torque_n_m, full_on_v, pwpf_time_constant_s,
                  position_gain_v_per_arcsec, rate_gain_v_per_arcsec_s, frame_s):
    """Loop transfer function L(s) of one axis's position loop, cut at the plant input.

    Parameters
    ----------
    inertia_axis_kg_m2 : float
        [kg m^2] Diagonal inertia element of the axis.
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

    Returns
    -------
    control.TransferFunction
        L(s), dimensionless (attitude in, attitude out).
    """
    c = control.tf([rate_gain_v_per_arcsec_s * RAD2ARCSEC, position_gain_v_per_arcsec * RAD2ARCSEC],
                   [1.0])
    plant = control.tf([1.0], [inertia_axis_kg_m2, 0.0, 0.0])
    return c * _actuator_and_sensor(torque_n_m, full_on_v, pwpf_time_constant_s, frame_s) * plant


def rate_loop(inertia_axis_kg_m2, torque_n_m, full_on_v, pwpf_time_constant_s,
              rate_gain_v_per_arcsec_s, frame_s):
    """Loop transfer function of a rate-commanded axis (position inputs open).

    Parameters are those of :func:`position_loop`. Returns L(s) from body
    rate to body rate, ``RAD2ARCSEC Kd K_a lag delay / (J_ii s)``.
    """
    c = control.tf([rate_gain_v_per_arcsec_s * RAD2ARCSEC], [1.0])
    plant = control.tf([1.0], [inertia_axis_kg_m2, 0.0])
    return c * _actuator_and_sensor(torque_n_m, full_on_v, pwpf_time_constant_s, frame_s) * plant


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
        ``bandwidth_rad_s`` (closed loop, -3 dB) and ``stable``. Position
        entries also carry ``inertia_kg_m2`` (J_ii used),
        ``effective_inertia_kg_m2`` (``1/(J^-1)_ii``) and
        ``coupling_ratio`` (``max_j!=i |(J^-1)_ij| / (J^-1)_ii``).
    """
    j = np.asarray(inertia_kg_m2, dtype=float).reshape(3, 3)
    j_inv = np.linalg.inv(j)
    torque = np.broadcast_to(np.asarray(torque_n_m, dtype=float), (3,))
    kp = np.broadcast_to(np.asarray(position_gain_v_per_arcsec, dtype=float), (3,))
    kd = np.broadcast_to(np.asarray(rate_gain_v_per_arcsec_s, dtype=float), (3,))
    out = {"position": {}, "rate": {}}
    for i, axis in enumerate(AXES):
        m = _margins(position_loop(j[i, i], torque[i], full_on_v, pwpf_time_constant_s, kp[i],
                                   kd[i], frame_s))
        m["inertia_kg_m2"] = float(j[i, i])
        m["effective_inertia_kg_m2"] = float(1.0 / j_inv[i, i])
        m["coupling_ratio"] = float(max(abs(j_inv[i, k]) for k in range(3) if k != i)
                                    / j_inv[i, i])
        out["position"][axis] = m
        if axis in RATE_LOOP_AXES:
            out["rate"][axis] = _margins(rate_loop(j[i, i], torque[i], full_on_v,
                                                   pwpf_time_constant_s, kd[i], frame_s))
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


def format_margins(margins: dict) -> str:
    """The result of :func:`loop_margins` as a small fixed-width text table."""
    head = (f"{'loop':<19}{'GM [dB]':>9}{'PM [deg]':>10}{'w_gc [rad/s]':>14}"
            f"{'w_pc [rad/s]':>14}{'BW [rad/s]':>12}{'coupling':>10}")
    lines = [head, "-" * len(head)]
    for kind, label in (("position", "position"), ("rate", "rate")):
        for axis, m in margins[kind].items():
            name = f"{axis} {label}" if kind == "position" else \
                f"{axis} rate {RATE_LOOP_AXES.get(axis, '')}".rstrip()
            coupling = f"{m['coupling_ratio']:>10.2%}" if "coupling_ratio" in m else f"{'':>10}"
            lines.append(f"{name:<19}{m['gain_margin_db']:>9.2f}{m['phase_margin_deg']:>10.2f}"
                         f"{m['crossover_rad_s']:>14.3f}{m['phase_crossover_rad_s']:>14.3f}"
                         f"{m['bandwidth_rad_s']:>12.3f}{coupling}")
    return "\n".join(lines)


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
    """Duty cycle of the simulated modulator (:func:`allsky.hardware.pwpf.pwpf_step`), constant input.

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
    """The PWPF static characteristic: analytic, simulated fine, simulated at the frame.

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
    """Keyword arguments of :func:`pwpf_static_characteristic` from a loaded scenario."""
    return {"filter_gain": cfg.pwpf.filter_gain, "time_constant_s": cfg.pwpf.time_constant_s,
            "on_threshold_v": cfg.pwpf.on_threshold_v,
            "off_threshold_v": cfg.pwpf.off_threshold_v, "full_on_v": cfg.pwpf.full_on_v,
            "min_on_time_s": cfg.jets.min_on_time_s, "frame_s": cfg.mission.frame_s}


def format_pwpf(result: dict) -> str:
    """The result of :func:`pwpf_static_characteristic` as a fixed-width text table."""
    def ms(v):
        return f"{'inf':>9}" if v is None else f"{v * 1e3:>9.2f}"

    head = (f"{'e [mV]':>8}{'T_on [ms]':>11}{'T_off [ms]':>11}{'f [Hz]':>8}"
            f"{'duty':>8}{'sim fine':>10}{'sim frame':>11}")
    title = (f"PWPF modulators 34-36, static characteristic: K {result['filter_gain']:g}, "
             f"tau {result['time_constant_s']:g} s, U_on {result['on_threshold_v'] * 1e3:g} mV, "
             f"U_off {result['off_threshold_v'] * 1e3:g} mV, U_m {result['full_on_v'] * 1e3:g} mV")
    limits = (f"dead zone below {result['dead_zone_v'] * 1e3:.3f} mV, "
              f"saturation above {result['saturation_v'] * 1e3:.3f} mV")
    lines = [title, limits, head, "-" * len(head)]
    for i, e in enumerate(result["input_v"]):
        t_on, t_off = result["t_on_s"][i], result["t_off_s"][i]
        freq = 1.0 / (t_on + t_off) if t_on and t_off else 0.0
        lines.append(f"{e * 1e3:>8.3f}  {ms(t_on)}  {ms(t_off)}{freq:>8.2f}"
                     f"{result['duty_analytic'][i]:>8.4f}{result['duty_simulated_fine'][i]:>10.4f}"
                     f"{result['duty_simulated_frame'][i]:>11.4f}")
    lines.append(f"largest |simulated - analytic| duty: {result['max_error_fine']:.4f} at a "
                 f"{result['fine_step_s'] * 1e3:g} ms step, {result['max_error_frame']:.4f} at "
                 f"the {result['frame_s'] * 1e3:g} ms frame with the "
                 f"{result['min_on_time_s'] * 1e3:g} ms minimum on-time")
    return "\n".join(lines)


# -- the analyze command -------------------------------------------------------

def scenario_loops(cfg) -> dict:
    """The loop transfer functions of a scenario: ``{"position roll": L(s), ...}``."""
    a = scenario_loop_arguments(cfg)
    j = np.asarray(a["inertia_kg_m2"])
    loops = {}
    for i, axis in enumerate(AXES):
        loops[f"position {axis}"] = position_loop(
            j[i, i], a["torque_n_m"][i], a["full_on_v"], a["pwpf_time_constant_s"],
            a["position_gain_v_per_arcsec"][i], a["rate_gain_v_per_arcsec_s"][i], a["frame_s"])
    for i, axis in enumerate(AXES):
        if axis in RATE_LOOP_AXES:
            loops[f"rate {axis}"] = rate_loop(
                j[i, i], a["torque_n_m"][i], a["full_on_v"], a["pwpf_time_constant_s"],
                a["rate_gain_v_per_arcsec_s"][i], a["frame_s"])
    return loops


def frequency_responses(loops: dict, omega_rad_s) -> dict:
    """``{name: (omega [rad/s], |L(j omega)| [-], phase [deg], unwrapped)}`` of each loop."""
    w = np.asarray(omega_rad_s, dtype=float)
    out = {}
    for name, loop in loops.items():
        r = control.frequency_response(loop, w)
        out[name] = (w, np.abs(r.complex).ravel(),
                     np.degrees(np.unwrap(np.angle(r.complex).ravel())))
    return out


def analyze(cfg) -> dict:
    """Loop margins and PWPF static characteristic of a scenario (``allsky analyze``).

    Returns
    -------
    dict
        ``{"margins": loop_margins(...), "pwpf": pwpf_static_characteristic(...)}``.
    """
    return {"margins": loop_margins(**scenario_loop_arguments(cfg)),
            "pwpf": pwpf_static_characteristic(**scenario_pwpf_arguments(cfg))}


def format_analysis(result: dict) -> str:
    """The result of :func:`analyze` as text: the margins table, then the PWPF table."""
    return "\n".join(["Loop margins (linear, cut at the plant input)", "",
                      format_margins(result["margins"]), "", format_pwpf(result["pwpf"])])


def _finite_or_none(value):
    """JSON has no inf or nan: write them as null."""
    if isinstance(value, dict):
        return {k: _finite_or_none(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite_or_none(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def run_from_cli(cfg, args) -> int:
    """``allsky analyze``: print the tables; write --json and the --plot PNG."""
    result = analyze(cfg)
    print(format_analysis(result))
    if args.json:
        Path(args.json).write_text(json.dumps(_finite_or_none(result), indent=2) + "\n")
    if args.plot:
        from allsky.apps import plots

        # Up to the frame's Nyquist frequency pi / frame_s: beyond it the loop is not defined.
        w = np.logspace(-2, math.log10(math.pi / cfg.mission.frame_s), 400)
        fig = plots.analysis(result, frequency_responses(scenario_loops(cfg), w))
        print(f"plot: {plots.save(fig, args.plot)}")
    return 0
