"""The vehicle's rigid-body rotation as a python-control ``nlsys``, for analysis.

The same plant as :mod:`allsky.vehicle.plant`, the same equations and the same
quaternion convention (``q = [w, x, y, z]`` inertial->body, scalar first)::

    J dw/dt = tau - w x (J w)          (Euler's equations, full inertia tensor)
    dq/dt   = 0.5 * q (x) [0, w]       (quaternion kinematics)

The right-hand side *is* :func:`allsky.vehicle.plant.derivatives`: one set of
equations in one place, so what python-control analyses and what the
compiled simulation core integrates cannot drift apart.

=========  ==========================  =========
Signal     Names                       Unit
=========  ==========================  =========
states     q_w, q_x, q_y, q_z          [-]
           w_x, w_y, w_z               [rad/s], body axes
inputs     tau_x, tau_y, tau_z         [N m], body axes
outputs    the states, same names      as above
=========  ==========================  =========

The ``nlsys`` does not renormalise the quaternion (an ODE has no such step);
:func:`allsky.vehicle.plant.rk4_step` does after each step, a change of the order of
its truncation error.
"""

import control
import numpy as np

from allsky.vehicle.plant import N_INTEGRATED, N_STATE, derivatives, make_params

STATE_NAMES = ("q_w", "q_x", "q_y", "q_z", "w_x", "w_y", "w_z")
INPUT_NAMES = ("tau_x", "tau_y", "tau_z")


def vehicle_nlsys(inertia_kg_m2, name="vehicle") -> control.NonlinearIOSystem:
    """Rigid-body rotational dynamics of the vehicle as a continuous-time ``nlsys``.

    Parameters
    ----------
    inertia_kg_m2 : array_like, shape (3, 3)
        [kg m^2] Inertia tensor about the centre of mass, body axes, with its
        products of inertia.
    name : str, optional
        Name of the system (prefix of its signals in an interconnection).

    Returns
    -------
    control.NonlinearIOSystem
        States ``q_w, q_x, q_y, q_z, w_x, w_y, w_z``; inputs
        ``tau_x, tau_y, tau_z`` [N m]; outputs equal to the states, same names.
    """
    p = make_params(inertia_kg_m2)

    def updfcn(t, x, u, params):
        # plant.derivatives integrates 3 extra gyro-angle states; feed zeros.
        y = np.zeros(N_INTEGRATED)
        y[:N_STATE] = x
        dy = np.empty(N_INTEGRATED)
        derivatives(p, y, np.asarray(u, dtype=float), dy)
        return dy[:N_STATE]

    def outfcn(t, x, u, params):
        return np.array(x, dtype=float)

    return control.nlsys(updfcn, outfcn, states=list(STATE_NAMES), inputs=list(INPUT_NAMES),
                         outputs=list(STATE_NAMES), name=name)


def operating_point() -> control.OperatingPoint:
    """The linearisation point: identity attitude, zero body rate, zero torque.

    Returns
    -------
    control.OperatingPoint
        ``states = [1, 0, 0, 0, 0, 0, 0]``, ``inputs = [0, 0, 0]`` [N m]. It is
        an equilibrium of :func:`vehicle_nlsys` for every inertia tensor.
    """
    return control.OperatingPoint(np.array([1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]), np.zeros(3))


def linearize(inertia_kg_m2, name="vehicle_linearized") -> control.StateSpace:
    """The vehicle linearised about :func:`operating_point`, as a ``StateSpace``.

    At the identity attitude with zero rate the Jacobian is exact and simple:
    the gyroscopic term ``w x (J w)`` is quadratic in the rate and drops out,
    and ``dq_w/dt = -0.5 q_vec . w`` is second order, so::

        d q_vec / dt = 0.5 w             d q_w / dt = 0
        d w / dt     = J^-1 tau

    **Small angles are twice the quaternion's vector part**: near identity
    ``q_vec = sin(phi/2) * axis ~ phi/2``, so the body-axis angles [rad] are
    ``2 * (q_x, q_y, q_z)`` and each axis is ``angle_i = (J^-1 tau)_i / s^2``,
    a double integrator ``1/(J_ii s^2)`` for a diagonal tensor. ``q_w`` is a
    decoupled pole at zero (neither controllable nor moved by torque).

    The matrices are written analytically rather than by finite differences
    (:func:`control.linearize` of :func:`vehicle_nlsys` agrees to the
    difference step's order; tests/test_plant_control.py checks it).

    Parameters
    ----------
    inertia_kg_m2 : array_like, shape (3, 3)
        [kg m^2] Inertia tensor, body axes.
    name : str, optional
        Name of the linear system.

    Returns
    -------
    control.StateSpace
        7 states, 3 inputs [N m], 7 outputs (the states), signal names as in
        :func:`vehicle_nlsys`.
    """
    p = make_params(inertia_kg_m2)
    a = np.zeros((N_STATE, N_STATE))
    a[1:4, 4:7] = 0.5 * np.eye(3)
    b = np.zeros((N_STATE, 3))
    b[4:7, :] = p.inertia_inv_1_kg_m2
    return control.ss(a, b, np.eye(N_STATE), np.zeros((N_STATE, 3)), states=list(STATE_NAMES),
                      inputs=list(INPUT_NAMES), outputs=list(STATE_NAMES), name=name)
