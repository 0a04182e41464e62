"""Rigid-body rotational dynamics of the vehicle (the plant).

State ``x = [q_w, q_x, q_y, q_z, wx, wy, wz]``: the inertial->body quaternion
and the body rate [rad/s] in body axes; input: body torque [N m].

    J dw/dt = tau - w x (J w)          (Euler's equations, full inertia tensor)
    dq/dt   = 0.5 * q (x) [0, w]       (quaternion kinematics)

The simulation core integrates these with classical fourth-order Runge-Kutta
at the fixed frame, torque held over the frame (the jets are on/off valves
commanded once a frame). Alongside, it integrates the body-axis angle
increment ``int w dt`` [rad] over the frame, which is what a strapped-down
gyro's pulse train measures. :mod:`allsky.plant_control` builds the same
equations as a python-control ``nlsys`` for analysis.
"""

from typing import NamedTuple

import numpy as np

from allsky.jit import njit

N_STATE = 7
# Integrated vector: plant state plus the 3 angle increments of the frame.
N_INTEGRATED = 10


class RigidBodyParams(NamedTuple):
    """Mass properties of the vehicle."""

    inertia_kg_m2: np.ndarray  #: [kg m^2] 3x3 symmetric positive-definite tensor, body axes
    inertia_inv_1_kg_m2: np.ndarray  #: [1/(kg m^2)] its inverse


def make_params(inertia_kg_m2) -> RigidBodyParams:
    """Build :class:`RigidBodyParams` from a 3x3 inertia tensor [kg m^2]."""
    j = np.array(inertia_kg_m2, dtype=float).reshape(3, 3)
    return RigidBodyParams(j, np.linalg.inv(j))


@njit
def derivatives(p, y, torque_n_m, dy):
    """Time derivative of the integrated vector ``y`` (10 elements) into ``dy``.

    ``y[7:10]`` are the frame's body-angle increments; their derivative is the
    body rate itself.
    """
    j = p.inertia_kg_m2
    ji = p.inertia_inv_1_kg_m2
    qw, qx, qy, qz = y[0], y[1], y[2], y[3]
    wx, wy, wz = y[4], y[5], y[6]
    dy[0] = 0.5 * (-qx * wx - qy * wy - qz * wz)
    dy[1] = 0.5 * (qw * wx + qy * wz - qz * wy)
    dy[2] = 0.5 * (qw * wy - qx * wz + qz * wx)
    dy[3] = 0.5 * (qw * wz + qx * wy - qy * wx)
    hx = j[0, 0] * wx + j[0, 1] * wy + j[0, 2] * wz
    hy = j[1, 0] * wx + j[1, 1] * wy + j[1, 2] * wz
    hz = j[2, 0] * wx + j[2, 1] * wy + j[2, 2] * wz
    mx = torque_n_m[0] - (wy * hz - wz * hy)
    my = torque_n_m[1] - (wz * hx - wx * hz)
    mz = torque_n_m[2] - (wx * hy - wy * hx)
    dy[4] = ji[0, 0] * mx + ji[0, 1] * my + ji[0, 2] * mz
    dy[5] = ji[1, 0] * mx + ji[1, 1] * my + ji[1, 2] * mz
    dy[6] = ji[2, 0] * mx + ji[2, 1] * my + ji[2, 2] * mz
    dy[7] = wx
    dy[8] = wy
    dy[9] = wz


@njit
def rk4_step(p, x, torque_n_m, dt_s, dtheta_rad, work):
    """Advance the plant state ``x`` (7) by ``dt_s`` in place.

    ``dtheta_rad`` (3) receives the body-angle increment over the step.
    ``work`` is a preallocated (6, 10) scratch array: no allocation here.
    The quaternion is renormalised after the step (the RK4 truncation error
    otherwise drifts its norm by ~1e-16 per step).
    """
    y = work[0]
    k1, k2, k3, k4, tmp = work[1], work[2], work[3], work[4], work[5]
    for i in range(N_STATE):
        y[i] = x[i]
    y[7] = 0.0
    y[8] = 0.0
    y[9] = 0.0
    derivatives(p, y, torque_n_m, k1)
    for i in range(N_INTEGRATED):
        tmp[i] = y[i] + 0.5 * dt_s * k1[i]
    derivatives(p, tmp, torque_n_m, k2)
    for i in range(N_INTEGRATED):
        tmp[i] = y[i] + 0.5 * dt_s * k2[i]
    derivatives(p, tmp, torque_n_m, k3)
    for i in range(N_INTEGRATED):
        tmp[i] = y[i] + dt_s * k3[i]
    derivatives(p, tmp, torque_n_m, k4)
    for i in range(N_INTEGRATED):
        y[i] = y[i] + dt_s / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
    n = np.sqrt(y[0] * y[0] + y[1] * y[1] + y[2] * y[2] + y[3] * y[3])
    for i in range(4):
        x[i] = y[i] / n
    for i in range(4, N_STATE):
        x[i] = y[i]
    dtheta_rad[0] = y[7]
    dtheta_rad[1] = y[8]
    dtheta_rad[2] = y[9]


def angular_momentum_inertial(p: RigidBodyParams, x) -> np.ndarray:
    """Angular momentum [N m s] in inertial axes (conserved without torque)."""
    from allsky.quaternion import dcm_body_from_inertial

    h_body = p.inertia_kg_m2 @ np.asarray(x[4:7])
    return dcm_body_from_inertial(np.asarray(x[0:4])).T @ h_body


def kinetic_energy_j(p: RigidBodyParams, x) -> float:
    """Rotational kinetic energy [J] (conserved without torque)."""
    w = np.asarray(x[4:7])
    return 0.5 * float(w @ p.inertia_kg_m2 @ w)
