"""Attitude quaternion helpers.

Convention: ``q = [w, x, y, z]`` (scalar first) rotates inertial coordinates
into body coordinates, ``v_body = dcm_body_from_inertial(q) @ v_inertial``.
Kinematics: ``dq/dt = 0.5 * q (x) [0, omega_body]`` with ``omega_body`` the body
rate in rad/s expressed in body axes.
"""

import math

import numpy as np

from allsky import xmath
from allsky.jit import njit, njit_alloc


@njit_alloc
def dcm_body_from_inertial(q):
    """Direction-cosine matrix (body from inertial) of unit quaternion ``q``.

    ``q`` is ``[w, x, y, z]``, the module's convention.
    """
    w, x, y, z = q[0], q[1], q[2], q[3]
    c = np.empty((3, 3))
    c[0, 0] = w * w + x * x - y * y - z * z
    c[0, 1] = 2.0 * (x * y + w * z)
    c[0, 2] = 2.0 * (x * z - w * y)
    c[1, 0] = 2.0 * (x * y - w * z)
    c[1, 1] = w * w - x * x + y * y - z * z
    c[1, 2] = 2.0 * (y * z + w * x)
    c[2, 0] = 2.0 * (x * z + w * y)
    c[2, 1] = 2.0 * (y * z - w * x)
    c[2, 2] = w * w - x * x - y * y + z * z
    return c


@njit
def rotate_to_body(q, v_inertial, out_body):
    """Write ``dcm_body_from_inertial(q) @ v_inertial`` into ``out_body``.

    ``q`` is a unit quaternion ``[w, x, y, z]``, ``v_inertial`` a (3,) vector
    in inertial axes and ``out_body`` the (3,) array that receives it in body
    axes, in any unit. Nothing is allocated.
    """
    w, x, y, z = q[0], q[1], q[2], q[3]
    a, b, c = v_inertial[0], v_inertial[1], v_inertial[2]
    out_body[0] = (w * w + x * x - y * y - z * z) * a + 2.0 * (x * y + w * z) * b \
        + 2.0 * (x * z - w * y) * c
    out_body[1] = 2.0 * (x * y - w * z) * a + (w * w - x * x + y * y - z * z) * b \
        + 2.0 * (y * z + w * x) * c
    out_body[2] = 2.0 * (x * z + w * y) * a + 2.0 * (y * z - w * x) * b \
        + (w * w - x * x - y * y + z * z) * c


@njit_alloc
def body_axis_inertial(q, axis):
    """Inertial components of body axis ``axis`` (0=x roll, 1=y pitch, 2=z yaw).

    ``q`` is the attitude, a unit quaternion ``[w, x, y, z]``.
    """
    c = dcm_body_from_inertial(q)
    return c[axis, :].copy()


def from_axis_angle(axis, angle_rad):
    """Quaternion of a frame rotated by ``angle_rad`` about ``axis`` (right hand)."""
    axis = np.asarray(axis, dtype=float)
    axis = axis / xmath.norm3(axis)
    h = 0.5 * angle_rad
    return np.array([xmath.cos(h), *(xmath.sin(h) * axis)])


def multiply(p, q):
    """Hamilton product ``p (x) q`` of quaternions ``p``, ``q``, each ``[w, x, y, z]``."""
    pw, px, py, pz = p
    qw, qx, qy, qz = q
    return np.array([
        pw * qw - px * qx - py * qy - pz * qz,
        pw * qx + px * qw + py * qz - pz * qy,
        pw * qy - px * qz + py * qw + pz * qx,
        pw * qz + px * qy - py * qx + pz * qw,
    ])


def from_dcm(c):
    """Unit quaternion ``[w, x, y, z]`` (w >= 0) of a body-from-inertial DCM.

    ``c`` is the (3, 3) rotation matrix. Shepperd's method.
    """
    c = np.asarray(c, dtype=float)
    tr = np.trace(c)
    k = np.argmax([tr, c[0, 0], c[1, 1], c[2, 2]])
    if k == 0:
        w = 0.5 * math.sqrt(1.0 + tr)
        q = np.array([w, (c[1, 2] - c[2, 1]) / (4 * w), (c[2, 0] - c[0, 2]) / (4 * w),
                      (c[0, 1] - c[1, 0]) / (4 * w)])
    elif k == 1:
        x = 0.5 * math.sqrt(1.0 + 2 * c[0, 0] - tr)
        q = np.array([(c[1, 2] - c[2, 1]) / (4 * x), x, (c[0, 1] + c[1, 0]) / (4 * x),
                      (c[0, 2] + c[2, 0]) / (4 * x)])
    elif k == 2:
        y = 0.5 * math.sqrt(1.0 + 2 * c[1, 1] - tr)
        q = np.array([(c[2, 0] - c[0, 2]) / (4 * y), (c[0, 1] + c[1, 0]) / (4 * y), y,
                      (c[1, 2] + c[2, 1]) / (4 * y)])
    else:
        z = 0.5 * math.sqrt(1.0 + 2 * c[2, 2] - tr)
        q = np.array([(c[0, 1] - c[1, 0]) / (4 * z), (c[0, 2] + c[2, 0]) / (4 * z),
                      (c[1, 2] + c[2, 1]) / (4 * z), z])
    if q[0] < 0:
        q = -q
    return q / math.sqrt(xmath.dot(q, q))


def random_unit(rng):
    """Quaternion uniform over the rotation group, from numpy Generator ``rng``.

    Shoemake's (1992) construction from three uniform deviates.
    """
    u1, u2, u3 = rng.random(3)
    a, b = math.sqrt(1 - u1), math.sqrt(u1)
    q = np.array([a * xmath.sin(2 * math.pi * u2), a * xmath.cos(2 * math.pi * u2),
                  b * xmath.sin(2 * math.pi * u3), b * xmath.cos(2 * math.pi * u3)])
    return q if q[0] >= 0 else -q
