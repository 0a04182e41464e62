"""Linear stability margins of the emulator's attitude loops, per axis.

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

import math

import control
import numpy as np

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
    cfg : allsky.config.Scenario
        A validated scenario (:func:`allsky.config.load_scenario`).

    Returns
    -------
    dict
        Plain numbers, torque per axis ``2 * thrust_n * moment_arm_m`` [N m]
        (as :func:`allsky.jets.make_params`).
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
