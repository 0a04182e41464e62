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

:func:`gyrostat_nlsys` is the vehicle carrying reaction wheels, with the
wheel momenta as further states and the motor torques as further inputs,
on :func:`allsky.vehicle.plant.gyrostat_derivatives`.

The ``nlsys`` does not renormalise the quaternion (an ODE has no such step);
:func:`allsky.vehicle.plant.rk4_step` does after each step, a change of the order of
its truncation error.

:func:`linearize` is the plant of the loop analysis
(:mod:`allsky.studies.analysis`, ``allsky analyze``): the ``nlsys``
linearised at attitude hold, with small body-axis angles in place of the
quaternion.
"""

import control
import numpy as np

from allsky.vehicle.plant import (
    N_INTEGRATED,
    N_STATE,
    derivatives,
    gyrostat_derivatives,
    make_params,
)

STATE_NAMES = ("q_w", "q_x", "q_y", "q_z", "w_x", "w_y", "w_z")
INPUT_NAMES = ("tau_x", "tau_y", "tau_z")
#: States (and outputs) of :func:`linearize`: small body-axis angles [rad], body rates [rad/s].
ANGLE_NAMES = ("phi_x", "phi_y", "phi_z")
RATE_NAMES = ("w_x", "w_y", "w_z")
LINEAR_STATE_NAMES = ANGLE_NAMES + RATE_NAMES


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


def gyrostat_nlsys(inertia_kg_m2, wheel_axes, name="vehicle") -> control.NonlinearIOSystem:
    """The vehicle with reaction wheels (a gyrostat) as a continuous-time ``nlsys``.

    Its right-hand side is :func:`allsky.vehicle.plant.gyrostat_derivatives`,
    the compiled plant's, with ``dh_i/dt = u_i``::

        I dw/dt = tau - A u - w x (I w + A h)

    Parameters
    ----------
    inertia_kg_m2 : array_like, shape (3, 3)
        [kg m^2] The body's inertia tensor less the wheels' spin inertia
        about their axes (:func:`allsky.vehicle.plant.gyrostat_params`).
    wheel_axes : array_like, shape (n, 3)
        Unit spin axes, body axes, one row per wheel (the columns of ``A``).
    name : str, optional
        Name of the system.

    Returns
    -------
    control.NonlinearIOSystem
        States ``q_w .. q_z, w_x .. w_z`` and the wheel momenta ``h_0 ..``
        [N m s]; inputs ``tau_x, tau_y, tau_z`` [N m] (external) and the
        motor torques ``u_0 ..`` [N m]; outputs equal to the states.
    """
    p = make_params(inertia_kg_m2)
    a = np.asarray(wheel_axes, dtype=float).reshape(-1, 3).T
    n = a.shape[1]
    wheels = [f"h_{i}" for i in range(n)]
    motors = [f"u_{i}" for i in range(n)]

    def updfcn(t, x, u, params):
        x = np.asarray(x, dtype=float)
        u = np.asarray(u, dtype=float)
        y = np.zeros(N_INTEGRATED)
        y[:N_STATE] = x[:N_STATE]
        dy = np.empty(N_INTEGRATED)
        gyrostat_derivatives(p, y, u[:3], a @ x[N_STATE:], a @ u[3:], dy)
        return np.concatenate([dy[:N_STATE], u[3:]])

    def outfcn(t, x, u, params):
        return np.array(x, dtype=float)

    states = list(STATE_NAMES) + wheels
    return control.nlsys(updfcn, outfcn, states=states, inputs=list(INPUT_NAMES) + motors,
                         outputs=states, name=name)


def operating_point() -> control.OperatingPoint:
    """The linearisation point: identity attitude, zero body rate, zero torque.

    Returns
    -------
    control.OperatingPoint
        ``states = [1, 0, 0, 0, 0, 0, 0]``, ``inputs = [0, 0, 0]`` [N m]. It is
        an equilibrium of :func:`vehicle_nlsys` for every inertia tensor.
    """
    return control.OperatingPoint(np.array([1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]), np.zeros(3))


def linearize(inertia_kg_m2, name="vehicle") -> control.StateSpace:
    """The vehicle linearised about :func:`operating_point` (small angles, body rates).

    :func:`control.linearize` of :func:`vehicle_nlsys` (forward differences
    of :func:`allsky.vehicle.plant.derivatives`), then two steps that the
    quaternion state needs:

    * **q_w is dropped.** At the identity ``dq_w/dt = -0.5 q_vec . w`` is
      second order and no state depends on ``q_w``: its row and column of
      the Jacobian are zero, an uncontrollable pole at zero that would sit in
      every closed loop. The attitude has three degrees of freedom.
    * **Small angles are twice the quaternion's vector part.** Near identity
      ``q_vec = sin(phi/2) * axis ~ phi/2``, so the states become
      ``phi = 2 q_vec`` [rad], rotations about the body axes, the angles a
      sensor measures. The change of variables is exact in floating point
      (a factor of two).

    What remains is ``dphi/dt = w``, ``dw/dt = J^-1 tau``: with a diagonal
    tensor three double integrators ``1/(J_ii s^2)``; products of inertia
    couple the axes through ``J^-1``. The gyroscopic term ``w x (J w)`` is
    quadratic in the rate and vanishes at rest; the forward difference
    (step 1e-6) leaves ``step * J^-1 (e_j x J e_j)`` of it, 2e-8 1/s
    for the default tensor and exactly zero for a diagonal one.

    Parameters
    ----------
    inertia_kg_m2 : array_like, shape (3, 3)
        [kg m^2] Inertia tensor, body axes.
    name : str, optional
        Name of the linear system (prefix of its signals in an interconnection).

    Returns
    -------
    control.StateSpace
        States and outputs ``phi_x, phi_y, phi_z`` [rad] and ``w_x, w_y, w_z``
        [rad/s] (:data:`LINEAR_STATE_NAMES`); inputs ``tau_x, tau_y, tau_z``
        [N m].
    """
    full = control.linearize(vehicle_nlsys(inertia_kg_m2), operating_point())
    # z = T x[1:]: q_vec -> phi = 2 q_vec, w unchanged.
    t = np.diag([2.0, 2.0, 2.0, 1.0, 1.0, 1.0])
    t_inv = np.diag([0.5, 0.5, 0.5, 1.0, 1.0, 1.0])
    a = t @ full.A[1:, 1:] @ t_inv
    b = t @ full.B[1:, :]
    n = len(LINEAR_STATE_NAMES)
    return control.ss(a, b, np.eye(n), np.zeros((n, len(INPUT_NAMES))),
                      states=list(LINEAR_STATE_NAMES), inputs=list(INPUT_NAMES),
                      outputs=list(LINEAR_STATE_NAMES), name=name)
