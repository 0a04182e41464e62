"""Rigid-body rotational dynamics of instrument vehicle 100 (the plant).

State ``x = [q_w, q_x, q_y, q_z, wx, wy, wz]``: the inertial->body quaternion
and the body rate [rad/s] in body axes; input: body torque [N m].

    J dw/dt = tau - w x (J w)          (Euler's equations, full inertia tensor)
    dq/dt   = 0.5 * q (x) [0, w]       (quaternion kinematics)

The simulation core integrates these with classical fourth-order Runge-Kutta
at the fixed frame, torque held over the frame (the jets are on/off valves
commanded once a frame). Alongside, it integrates the body-axis angle
increment ``int w dt`` [rad] over the frame, which is what a strapped-down
gyro's pulse train measures. :mod:`allsky.vehicle.plant_control` builds the same
equations as a python-control ``nlsys`` for analysis.

On the reaction-wheel vehicle the body carries wheels (a gyrostat,
:func:`rk4_step_gyrostat`): ``I dw/dt = tau - A u - w x (I w + A h)`` with
the wheel momenta ``h`` and motor torques ``u = dh/dt``
(:mod:`allsky.vehicle.wheels`).
"""

from typing import NamedTuple

import numpy as np

from allsky import xmath
from allsky.jit import njit, njit_stage

N_STATE = 7
# Integrated vector: plant state plus the 3 angle increments of the frame.
N_INTEGRATED = 10


class RigidBodyParams(NamedTuple):
    """Mass properties of the vehicle."""

    inertia_kg_m2: np.ndarray  #: [kg m^2] 3x3 symmetric positive-definite tensor, body axes
    inertia_inv_1_kg_m2: np.ndarray  #: [1/(kg m^2)] its inverse


def make_params(inertia_kg_m2) -> RigidBodyParams:
    """Build :class:`RigidBodyParams` from a 3x3 inertia tensor [kg m^2].

    ``inertia_kg_m2`` is the vehicle's tensor in body axes (9 numbers, or 3x3).
    """
    j = np.array(inertia_kg_m2, dtype=float).reshape(3, 3)
    return RigidBodyParams(j, xmath.inv(j))


@njit
def _rates(j, ji, qw, qx, qy, qz, wx, wy, wz, tx, ty, tz):
    """Quaternion and body-rate derivatives ``(dqw, dqx, dqy, dqz, dwx, dwy, dwz)``."""
    dqw = 0.5 * (-qx * wx - qy * wy - qz * wz)
    dqx = 0.5 * (qw * wx + qy * wz - qz * wy)
    dqy = 0.5 * (qw * wy - qx * wz + qz * wx)
    dqz = 0.5 * (qw * wz + qx * wy - qy * wx)
    hx = j[0, 0] * wx + j[0, 1] * wy + j[0, 2] * wz
    hy = j[1, 0] * wx + j[1, 1] * wy + j[1, 2] * wz
    hz = j[2, 0] * wx + j[2, 1] * wy + j[2, 2] * wz
    mx = tx - (wy * hz - wz * hy)
    my = ty - (wz * hx - wx * hz)
    mz = tz - (wx * hy - wy * hx)
    return (dqw, dqx, dqy, dqz,
            ji[0, 0] * mx + ji[0, 1] * my + ji[0, 2] * mz,
            ji[1, 0] * mx + ji[1, 1] * my + ji[1, 2] * mz,
            ji[2, 0] * mx + ji[2, 1] * my + ji[2, 2] * mz)


@njit
def derivatives(p, y, torque_n_m, dy):
    """Time derivative of the integrated vector ``y`` (10 elements) into ``dy``.

    ``y[7:10]`` are the frame's body-angle increments; their derivative is the
    body rate itself.

    Parameters
    ----------
    p : RigidBodyParams
        Mass properties of the vehicle.
    y : array of 10 float
        Quaternion (inertial to body), body rate [rad/s], angle increments [rad].
    torque_n_m : array of 3 float
        [N m] external torque on the body, body axes (the jets').
    dy : array of 10 float
        Written: the derivative of ``y``.
    """
    d = _rates(p.inertia_kg_m2, p.inertia_inv_1_kg_m2, y[0], y[1], y[2], y[3], y[4], y[5],
               y[6], torque_n_m[0], torque_n_m[1], torque_n_m[2])
    for i in range(N_STATE):
        dy[i] = d[i]
    dy[7] = y[4]
    dy[8] = y[5]
    dy[9] = y[6]


@njit_stage
def _rk4_finish(x, dtheta_rad, dt_s, s, a, b, c, d, bw, cw):
    """RK4's last stage and weighted sum: state ``s`` (q, w) and stage derivatives into ``x``.

    ``a`` to ``d`` are the four stages' derivatives of (q, w), ``bw``/``cw``
    the rates at stages b and c (the angle increments' derivatives). The
    quaternion is renormalised; the angle increments start at 0.
    """
    qw, qx, qy, qz, wx, wy, wz = s
    a0, a1, a2, a3, a4, a5, a6 = a
    b0, b1, b2, b3, b4, b5, b6 = b
    c0, c1, c2, c3, c4, c5, c6 = c
    d0, d1, d2, d3, d4, d5, d6 = d
    bx, by, bz = bw
    cx, cy, cz = cw
    dx, dy, dz = wx + dt_s * c4, wy + dt_s * c5, wz + dt_s * c6
    k = dt_s / 6.0
    qw = qw + k * (a0 + 2.0 * b0 + 2.0 * c0 + d0)
    qx = qx + k * (a1 + 2.0 * b1 + 2.0 * c1 + d1)
    qy = qy + k * (a2 + 2.0 * b2 + 2.0 * c2 + d2)
    qz = qz + k * (a3 + 2.0 * b3 + 2.0 * c3 + d3)
    n = np.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
    x[0] = qw / n
    x[1] = qx / n
    x[2] = qy / n
    x[3] = qz / n
    x[4] = wx + k * (a4 + 2.0 * b4 + 2.0 * c4 + d4)
    x[5] = wy + k * (a5 + 2.0 * b5 + 2.0 * c5 + d5)
    x[6] = wz + k * (a6 + 2.0 * b6 + 2.0 * c6 + d6)
    # The angle increments start at 0 and their derivative at each stage is its w.
    dtheta_rad[0] = 0.0 + k * (wx + 2.0 * bx + 2.0 * cx + dx)
    dtheta_rad[1] = 0.0 + k * (wy + 2.0 * by + 2.0 * cy + dy)
    dtheta_rad[2] = 0.0 + k * (wz + 2.0 * bz + 2.0 * cz + dz)


@njit_stage
def rk4_step(p, x, torque_n_m, dt_s, dtheta_rad):
    """Advance the plant state ``x`` (7) by ``dt_s`` in place.

    ``dtheta_rad`` (3) receives the body-angle increment over the step. The
    stages live in local variables (registers), not arrays: no allocation,
    and the compiler need not assume that a store to one stage changes another.
    The quaternion is renormalised after the step (the RK4 truncation error
    otherwise drifts its norm by ~1e-16 per step).

    Parameters
    ----------
    p : RigidBodyParams
        Mass properties of the vehicle.
    x : array of 7 float
        The plant state: inertial-to-body quaternion, body rate [rad/s].
    torque_n_m : array of 3 float
        [N m] external torque, body axes, held over the step.
    dt_s : float
        [s] step length (one frame).
    dtheta_rad : array of 3 float
        [rad] written: the body-angle increment the gyros see.
    """
    j = p.inertia_kg_m2
    ji = p.inertia_inv_1_kg_m2
    tx, ty, tz = torque_n_m[0], torque_n_m[1], torque_n_m[2]
    qw, qx, qy, qz = x[0], x[1], x[2], x[3]
    wx, wy, wz = x[4], x[5], x[6]
    h = 0.5 * dt_s
    # Stage k: derivatives at the stage point; the angle increments' derivative is w.
    a0, a1, a2, a3, a4, a5, a6 = _rates(j, ji, qw, qx, qy, qz, wx, wy, wz, tx, ty, tz)
    b0, b1, b2, b3, b4, b5, b6 = _rates(
        j, ji, qw + h * a0, qx + h * a1, qy + h * a2, qz + h * a3,
        wx + h * a4, wy + h * a5, wz + h * a6, tx, ty, tz)
    bx, by, bz = wx + h * a4, wy + h * a5, wz + h * a6
    c0, c1, c2, c3, c4, c5, c6 = _rates(
        j, ji, qw + h * b0, qx + h * b1, qy + h * b2, qz + h * b3,
        wx + h * b4, wy + h * b5, wz + h * b6, tx, ty, tz)
    cx, cy, cz = wx + h * b4, wy + h * b5, wz + h * b6
    d0, d1, d2, d3, d4, d5, d6 = _rates(
        j, ji, qw + dt_s * c0, qx + dt_s * c1, qy + dt_s * c2, qz + dt_s * c3,
        wx + dt_s * c4, wy + dt_s * c5, wz + dt_s * c6, tx, ty, tz)
    _rk4_finish(x, dtheta_rad, dt_s, (qw, qx, qy, qz, wx, wy, wz),
                (a0, a1, a2, a3, a4, a5, a6), (b0, b1, b2, b3, b4, b5, b6),
                (c0, c1, c2, c3, c4, c5, c6), (d0, d1, d2, d3, d4, d5, d6), (bx, by, bz),
                (cx, cy, cz))


# ---------------------------------------------------------------------------
# The gyrostat: the body with reaction wheels (allsky.vehicle.wheels)
# ---------------------------------------------------------------------------
#
# With wheel momenta h (each wheel's absolute angular momentum about its spin
# axis g_i, the columns of A) and motor torques u = dh/dt:
#
#     I dw/dt = tau - A u - w x (I w + A h)
#
# where I is the vehicle's inertia less the wheels' spin inertia about their
# axes (the wheels' axial momentum is all in h). The compiled step takes the
# wheels as two body-axis vectors, their momentum A h at the start of the frame
# and its rate A u, held over the frame like the jet torque: the plant itself
# does not depend on how many wheels there are.


def gyrostat_params(inertia_kg_m2, wheel_spin_inertia_kg_m2) -> RigidBodyParams:
    """:class:`RigidBodyParams` of the body that carries the wheels.

    Its tensor is the vehicle's less the wheels' spin inertia about their
    axes, ``sum_i J_i g_i g_i^T`` [kg m^2].

    Parameters
    ----------
    inertia_kg_m2 : array_like
        [kg m^2] the whole vehicle's 3x3 tensor, wheels included, body axes.
    wheel_spin_inertia_kg_m2 : array_like
        [kg m^2] 3x3 tensor of the wheels' spin inertia about their axes
        (``allsky.vehicle.wheels.spin_inertia_tensor_kg_m2``).
    """
    return make_params(np.asarray(inertia_kg_m2, dtype=float).reshape(3, 3)
                       - np.asarray(wheel_spin_inertia_kg_m2, dtype=float))


@njit
def _rates_gyrostat(j, ji, qw, qx, qy, qz, wx, wy, wz, tx, ty, tz, hx, hy, hz):
    """As :func:`_rates`, with the wheels' momentum ``h`` (body axes) in the gyroscopic term.

    ``t`` is the net torque on the body: external less the wheels' reaction.
    """
    dqw = 0.5 * (-qx * wx - qy * wy - qz * wz)
    dqx = 0.5 * (qw * wx + qy * wz - qz * wy)
    dqy = 0.5 * (qw * wy - qx * wz + qz * wx)
    dqz = 0.5 * (qw * wz + qx * wy - qy * wx)
    lx = j[0, 0] * wx + j[0, 1] * wy + j[0, 2] * wz + hx
    ly = j[1, 0] * wx + j[1, 1] * wy + j[1, 2] * wz + hy
    lz = j[2, 0] * wx + j[2, 1] * wy + j[2, 2] * wz + hz
    mx = tx - (wy * lz - wz * ly)
    my = ty - (wz * lx - wx * lz)
    mz = tz - (wx * ly - wy * lx)
    return (dqw, dqx, dqy, dqz,
            ji[0, 0] * mx + ji[0, 1] * my + ji[0, 2] * mz,
            ji[1, 0] * mx + ji[1, 1] * my + ji[1, 2] * mz,
            ji[2, 0] * mx + ji[2, 1] * my + ji[2, 2] * mz)


@njit
def gyrostat_derivatives(p, y, torque_n_m, wheel_momentum_body_n_m_s, wheel_torque_body_n_m,
                         dy):
    """Time derivative of ``y`` (10 elements, as :func:`derivatives`) with the wheels.

    ``wheel_momentum_body_n_m_s`` is ``A h`` [N m s] and
    ``wheel_torque_body_n_m`` its rate ``A u`` [N m], both in body axes;
    ``p`` the body's :class:`RigidBodyParams` (:func:`gyrostat_params`),
    ``torque_n_m`` [N m] the external torque in body axes, and ``dy`` (10)
    receives the derivative.
    """
    d = _rates_gyrostat(p.inertia_kg_m2, p.inertia_inv_1_kg_m2, y[0], y[1], y[2], y[3], y[4],
                        y[5], y[6], torque_n_m[0] - wheel_torque_body_n_m[0],
                        torque_n_m[1] - wheel_torque_body_n_m[1],
                        torque_n_m[2] - wheel_torque_body_n_m[2],
                        wheel_momentum_body_n_m_s[0], wheel_momentum_body_n_m_s[1],
                        wheel_momentum_body_n_m_s[2])
    for i in range(N_STATE):
        dy[i] = d[i]
    dy[7] = y[4]
    dy[8] = y[5]
    dy[9] = y[6]


@njit_stage
def rk4_step_gyrostat(p, x, torque_n_m, hw_n_m_s, hw_dot_n_m, dt_s, dtheta_rad):
    """Advance the state ``x`` (7) of the body carrying wheels by ``dt_s`` in place.

    As :func:`rk4_step`; the wheels' momentum in body axes is ``hw_n_m_s``
    (``A h``) at the start of the step and changes at ``hw_dot_n_m``
    (``A u``, the motor torques held over the step), which the body feels
    as the torque ``-hw_dot_n_m``. The wheel momenta themselves advance
    exactly, ``h + u dt``, outside (a constant rate needs no stages).

    ``p`` is the body's :class:`RigidBodyParams` (:func:`gyrostat_params`),
    ``torque_n_m`` [N m] the external torque in body axes (the jets'), and
    ``dtheta_rad`` (3) receives the body-angle increment [rad] of the step.
    """
    j = p.inertia_kg_m2
    ji = p.inertia_inv_1_kg_m2
    tx = torque_n_m[0] - hw_dot_n_m[0]
    ty = torque_n_m[1] - hw_dot_n_m[1]
    tz = torque_n_m[2] - hw_dot_n_m[2]
    h0x, h0y, h0z = hw_n_m_s[0], hw_n_m_s[1], hw_n_m_s[2]
    rx, ry, rz = hw_dot_n_m[0], hw_dot_n_m[1], hw_dot_n_m[2]
    qw, qx, qy, qz = x[0], x[1], x[2], x[3]
    wx, wy, wz = x[4], x[5], x[6]
    h = 0.5 * dt_s
    a0, a1, a2, a3, a4, a5, a6 = _rates_gyrostat(j, ji, qw, qx, qy, qz, wx, wy, wz, tx, ty, tz,
                                                 h0x, h0y, h0z)
    mx, my, mz = h0x + h * rx, h0y + h * ry, h0z + h * rz  # wheel momentum at mid-step
    b0, b1, b2, b3, b4, b5, b6 = _rates_gyrostat(
        j, ji, qw + h * a0, qx + h * a1, qy + h * a2, qz + h * a3,
        wx + h * a4, wy + h * a5, wz + h * a6, tx, ty, tz, mx, my, mz)
    bx, by, bz = wx + h * a4, wy + h * a5, wz + h * a6
    c0, c1, c2, c3, c4, c5, c6 = _rates_gyrostat(
        j, ji, qw + h * b0, qx + h * b1, qy + h * b2, qz + h * b3,
        wx + h * b4, wy + h * b5, wz + h * b6, tx, ty, tz, mx, my, mz)
    cx, cy, cz = wx + h * b4, wy + h * b5, wz + h * b6
    d0, d1, d2, d3, d4, d5, d6 = _rates_gyrostat(
        j, ji, qw + dt_s * c0, qx + dt_s * c1, qy + dt_s * c2, qz + dt_s * c3,
        wx + dt_s * c4, wy + dt_s * c5, wz + dt_s * c6, tx, ty, tz,
        h0x + dt_s * rx, h0y + dt_s * ry, h0z + dt_s * rz)
    _rk4_finish(x, dtheta_rad, dt_s, (qw, qx, qy, qz, wx, wy, wz),
                (a0, a1, a2, a3, a4, a5, a6), (b0, b1, b2, b3, b4, b5, b6),
                (c0, c1, c2, c3, c4, c5, c6), (d0, d1, d2, d3, d4, d5, d6), (bx, by, bz),
                (cx, cy, cz))


def gyrostat_momentum_inertial(p: RigidBodyParams, x, wheel_momentum_body_n_m_s) -> np.ndarray:
    """Angular momentum [N m s] of body and wheels in inertial axes.

    Conserved without external torque. ``p`` is the body's
    :class:`RigidBodyParams` (:func:`gyrostat_params`), ``x`` the plant state
    (quaternion, body rate [rad/s]), ``wheel_momentum_body_n_m_s`` the wheels'
    momentum ``A h`` [N m s] in body axes.
    """
    from allsky.vehicle.quaternion import dcm_body_from_inertial

    h_body = xmath.matmul(p.inertia_kg_m2, np.asarray(x[4:7])) + np.asarray(wheel_momentum_body_n_m_s)
    return xmath.matmul(dcm_body_from_inertial(np.asarray(x[0:4])).T, h_body)


def gyrostat_energy_j(p: RigidBodyParams, x, h_n_m_s, wheel_inertia_kg_m2) -> float:
    """Kinetic energy [J] of body and wheels: ``w.I w / 2 + sum_i h_i^2 / (2 J_i)``.

    Without external torque it changes only by the motors' work.

    Parameters
    ----------
    p : RigidBodyParams
        The body carrying the wheels (:func:`gyrostat_params`).
    x : array of 7 float
        The plant state: quaternion, body rate [rad/s].
    h_n_m_s : array_like
        [N m s] each wheel's momentum about its axis.
    wheel_inertia_kg_m2 : array_like
        [kg m^2] each wheel's spin inertia.
    """
    w = np.asarray(x[4:7])
    h = np.asarray(h_n_m_s, dtype=float)
    return 0.5 * xmath.dot(w, xmath.matmul(p.inertia_kg_m2, w)) + 0.5 * float(np.sum(h * h
                                                                      / wheel_inertia_kg_m2))


def angular_momentum_inertial(p: RigidBodyParams, x) -> np.ndarray:
    """Angular momentum [N m s] in inertial axes (conserved without torque).

    ``p`` holds the vehicle's inertia; ``x`` is the plant state (quaternion,
    body rate [rad/s]).
    """
    from allsky.vehicle.quaternion import dcm_body_from_inertial

    h_body = xmath.matmul(p.inertia_kg_m2, np.asarray(x[4:7]))
    return xmath.matmul(dcm_body_from_inertial(np.asarray(x[0:4])).T, h_body)


def kinetic_energy_j(p: RigidBodyParams, x) -> float:
    """Rotational kinetic energy [J] (conserved without torque).

    ``p`` holds the vehicle's inertia; ``x`` is the plant state (quaternion,
    body rate [rad/s]).
    """
    w = np.asarray(x[4:7])
    return 0.5 * xmath.dot(w, xmath.matmul(p.inertia_kg_m2, w))
