"""Reaction wheels: torque distribution over the array and momentum unloading.

An array of ``n`` wheels with unit spin axes ``g_i`` (the columns of the
3 x n matrix ``A``, body axes) stores the momenta ``h_i`` [N m s] (each
wheel's absolute angular momentum about its own axis). A motor torque
``u_i`` changes it, ``dh_i/dt = u_i``, and pushes the body the other way:
the body feels ``-A u`` (the gyrostat equations,
:func:`allsky.vehicle.plant.rk4_step_gyrostat`).

Distribution (:func:`distribute`). Each body axis's command is first
limited to the array's reach along that axis (the torque envelope's extent
along it), as each jet couple saturates on its own axis: a turn commanded
far beyond the wheels' authority then does not starve the held axes of
theirs. The body torque ``tau`` is then asked of the array as the
minimum-norm solution ``u = -A+ tau``, ``A+ = A^T (A A^T)^-1``
the pseudo-inverse. Its motor torques lie in the row space of ``A``, so the
wheels never fight each other, and momentum that starts in the row space
(zero at ejection) stays there: ``h = A+ (A h)``, the wheel momenta follow
from the momentum they hold in body axes. A command that one wheel cannot
give, in torque or in the momentum room left to it over the frame, is
scaled down as a whole until every wheel can: the body torque keeps its
direction and loses magnitude (Markley & Crassidis, *Fundamentals of
Spacecraft Attitude Determination and Control*, section 7.7.1, on
direction-preserving saturation). The minimum-norm solution does not reach
every corner of the envelope (:mod:`allsky.vehicle.envelopes`): it
saturates where its most loaded wheel reaches its limit, which on the
default pyramid leaves 0.667 N m of the envelope's 0.816 N m inscribed
radius in the worst direction (its own polytope,
:func:`pseudo_inverse_envelope`).

``wheels.allocation = "direct"`` reaches the whole envelope. Its command
is limited per body axis only to the envelope's extent along that axis
(its bounding box, ``sum_i L_i abs(g_ia)``), which cuts no torque the
envelope holds and still keeps a turn commanded far beyond the wheels'
authority from starving the held axes. Whenever the minimum-norm torques
would then exceed a limit, the command is allocated where its ray leaves
the zonotope (direct allocation, Durham, J. Guidance Control Dyn. 16(4),
1993): the facet whose normal maximises the gauge ``g = n_f . tau /
h(n_f)`` is pierced; the wheels off its plane run at ``sign(n_f . g_i) g
L_i``; the rest of the torque lies in the facet's plane, and the same rule
one dimension down (the facet's zonogon, its edge of the largest gauge)
sets the in-plane wheels off that edge, the wheels along the edge sharing
what is left in proportion to their limits. The tables are built per array
by :func:`direct_tables` (no allocation in the loop), for any array: skew,
coplanar sets, parallel wheels, unequal limits. For ``g <= 1`` the torque
is delivered exactly with no wheel beyond ``g`` of its limit (the least
possible); beyond the envelope the command is scaled by ``1/g`` onto its
boundary, the largest torque along its direction. Such torques are not in
the row space of ``A``: the wheels then store momentum in the array's null
space, which turns no body but uses the wheels' momentum room. *Null-space
momentum management* returns it: every frame the wheels also get
``-(I - A+ A) h / T`` (:data:`NULL_SPACE_TIME_S`), as much of it as the
torque room left allows; it changes no body torque (``A (I - A+ A) = 0``).

Unloading (:func:`unload_valves`). Momentum that the vehicle takes up
(tip-off rates, a constant disturbance) accumulates in the wheels. Once a
wheel holds :attr:`WheelParams.unload_start_fraction` of its limit, the jets
of each body axis fire against the momentum the wheels hold about that
axis, in minimum-impulse pulses spaced so that their mean torque is
:data:`UNLOAD_TORQUE_SHARE` of the wheel array's torque reach along the
axis; the wheels are commanded to cancel each pulse (the valves are known
when the wheels are commanded), so the pulse changes the stored momentum
and, to the wheels' torque limit, not the attitude. An axis stops firing
when its stored momentum is inside a dead band small enough that every
wheel is then under :attr:`WheelParams` ``unload_end_fraction`` of its
limit; unloading ends when all three have stopped.

Actuator codes (:data:`ACTUATOR_CODE`): the frame loop turns the control
amplifiers' output into torque through the jets (PWPF modulators 34-36,
jets 39-41) or through the wheels, by a constant of the mission.
"""

import math
from typing import NamedTuple

import numpy as np

from allsky.jit import njit, njit_stage
from allsky.vehicle.envelopes import PLANE_TOL, make_envelope

#: The frame loop's actuator codes (``Params.actuator``).
ACTUATOR_JETS = 0
ACTUATOR_WHEELS = 1
#: ``actuators.kind`` -> code.
ACTUATOR_CODE = {"jets": ACTUATOR_JETS, "wheels": ACTUATOR_WHEELS}
#: ``wheels.allocation`` -> code (``WheelParams.allocation``).
ALLOCATION_PSEUDO_INVERSE = 0
ALLOCATION_DIRECT = 1
ALLOCATION_CODE = {"pseudo_inverse": ALLOCATION_PSEUDO_INVERSE, "direct": ALLOCATION_DIRECT}
#: [s] Time constant of the null-space momentum management of the direct allocation.
NULL_SPACE_TIME_S = 20.0
#: Mean torque of the unloading pulses about a body axis, as a share of the wheel array's
#: torque reach along that axis: the wheels cancel the mean with half their authority
#: left to the attitude loop.
UNLOAD_TORQUE_SHARE = 0.5
#: Smallest singular value of the axes, relative to the largest, for them to span 3-D.
SPAN_TOL = 1e-6


class WheelParams(NamedTuple):
    """The wheel array, its distribution matrix and its unloading logic."""

    axes: np.ndarray  #: (n, 3) unit spin axes, body axes, one row per wheel (A^T)
    pinv: np.ndarray  #: (n, 3) minimum-norm distribution A+ = A^T (A A^T)^-1
    max_torque_n_m: np.ndarray  #: (n,) [N m] motor torque limit per wheel
    max_momentum_n_m_s: np.ndarray  #: (n,) [N m s] momentum limit per wheel
    inertia_kg_m2: np.ndarray  #: (n,) [kg m^2] spin-axis inertia per wheel
    torque_per_volt_n_m_v: np.ndarray  #: (3,) [N m/V] amplifier output -> body torque command
    axis_reach_n_m: np.ndarray  #: (3,) [N m] the array's largest torque along body x, y, z
    axis_support_n_m: np.ndarray  #: (3,) [N m] the envelope's extent along x, y, z (its box)
    unload_start_fraction: float  #: [-] unloading starts at this fraction of a wheel's limit
    unload_deadband_n_m_s: float  #: [N m s] a body axis stops unloading inside this
    unload_pulse_frames: int  #: [frames] length of one unloading pulse (the valve minimum)
    unload_period_frames: np.ndarray  #: (3,) int64 [frames] from pulse to pulse, per axis
    allocation: int  #: :data:`ALLOCATION_CODE` of ``wheels.allocation``
    facet_gauge: np.ndarray  #: (m, 3) [1/(N m)] facet normal / offset, every torque facet
    facet_sign: np.ndarray  #: (m, n) [N m] off-plane wheels' torque per unit gauge on facet f
    facet_corner: np.ndarray  #: (m, 3) [N m] their body torque per unit gauge, A facet_sign
    edge_gauge: np.ndarray  #: (m, e, 3) [1/(N m)] in-plane edge normal / offset, per facet
    edge_sign: np.ndarray  #: (m, e, n) [N m] in-plane wheels off edge e, per unit gauge
    edge_corner: np.ndarray  #: (m, e, 3) [N m] their body torque per unit gauge
    edge_axis: np.ndarray  #: (m, e, 3) [-] unit direction of edge e (one of its axes)
    edge_share: np.ndarray  #: (m, e, n) [-] each on-edge wheel's share of the torque along it
    null_projector: np.ndarray  #: (n, n) [-] I - A+ A, onto the array's null space
    null_rate_per_s: float  #: [1/s] 1 / NULL_SPACE_TIME_S


def per_wheel(value, n: int) -> np.ndarray:
    """One number for every wheel, or one per wheel, as an (n,) float array.

    ``value`` is a scalar or ``n`` numbers; ``n`` is the number of wheels.
    """
    a = np.asarray(value, dtype=float)
    return np.full(n, float(a)) if a.ndim == 0 else a.reshape(n).copy()


def pseudo_inverse(axes) -> np.ndarray:
    """Minimum-norm distribution matrix ``A+ = A^T (A A^T)^-1``, shape (n, 3).

    ``axes`` holds one unit spin axis per row (``A^T``); they must span 3-D.
    """
    at = np.asarray(axes, dtype=float)
    return at @ np.linalg.inv(at.T @ at)


def direct_tables(axes, max_torque_n_m):
    """The direct allocation's tables of an array, one row per torque facet.

    A facet ``f`` of the torque envelope (normal ``n``, offset ``h``) gives
    the gauge row ``n / h``; the off-plane wheels' corner ``s_i = sign(n .
    g_i) L_i`` (0 for the wheels in its plane) and its torque ``A s``. The
    wheels in its plane span a zonogon (the facet itself, translated); each of
    its edges ``e`` (in-plane normal ``m``, perpendicular to one set of
    parallel in-plane axes, offset ``k = sum over the plane of L_i abs(m .
    g_i)``) gives the gauge row ``m / k``, the corner ``sign(m . g_i) L_i``
    of the in-plane wheels off the edge and its torque, the edge's unit
    direction ``d`` (one of its axes) and the share ``sign(d . g_i) L_i /
    sum L`` of each wheel along it. A torque ``tau`` whose ray leaves
    through facet ``f`` at gauge ``g``, and whose in-plane rest ``r = tau - g
    A s`` leaves the zonogon through edge ``e`` at gauge ``g2 <= g``, is
    ``A u`` with ``u = g s + g2 s_e + (d . (r - g2 A s_e)) share_e``: exact,
    and no wheel beyond ``g`` of its limit. With no three axes coplanar and
    none parallel a facet has two wheels in its plane and four edges; a
    coplanar set or parallel wheels give more, shorter rows are padded with
    zero (their gauge 0 never beats a real edge's, which is positive for one
    of each opposite pair).

    ``axes`` holds the unit spin axes, one row per wheel (body axes), and
    ``max_torque_n_m`` [N m] the motor torque limit ``L_i`` of each wheel.
    Returns the arrays of :class:`WheelParams` ``facet_gauge`` ...
    ``edge_share``, in that order.
    """
    env = make_envelope(axes, max_torque_n_m)
    g = env.axes
    lim = env.limits
    m, n = len(env.offsets), len(lim)
    edges = []  # per facet: (normal m, offset k, corner, unit direction, share)
    for f in range(m):
        normal = env.normals[f]
        plane = list(env.facet_axes[f])
        reps = []  # one axis of each set of parallel axes in the plane: the same edges
        for q in plane:
            if all(np.linalg.norm(np.cross(g[q], g[r])) > PLANE_TOL for r in reps):
                reps.append(q)
        facet_edges = []
        for q in reps:
            side = np.cross(normal, g[q])
            side /= np.linalg.norm(side)
            on = [i for i in plane if abs(side @ g[i]) <= PLANE_TOL]
            off = [i for i in plane if i not in on]
            share = np.zeros(n)
            share[on] = np.sign(g[on] @ g[q]) * lim[on] / lim[on].sum()
            for sgn in (1.0, -1.0):
                mm = sgn * side
                corner = np.zeros(n)
                corner[off] = np.sign(g[off] @ mm) * lim[off]
                offset = float(np.abs(g[plane] @ mm) @ lim[plane])
                facet_edges.append((mm / offset, corner, g[q], share))
        edges.append(facet_edges)
    e_max = max(len(e) for e in edges)
    gauge = env.normals / env.offsets[:, None]
    sign = np.sign(env.normals @ g.T) * lim
    for f in range(m):
        sign[f, list(env.facet_axes[f])] = 0.0
    corner = sign @ g
    edge_gauge, edge_corner = np.zeros((m, e_max, 3)), np.zeros((m, e_max, 3))
    edge_sign, edge_axis = np.zeros((m, e_max, n)), np.zeros((m, e_max, 3))
    edge_share = np.zeros((m, e_max, n))
    for f, facet_edges in enumerate(edges):
        for e, (row, s, d, share) in enumerate(facet_edges):
            edge_gauge[f, e], edge_sign[f, e], edge_axis[f, e] = row, s, d
            edge_corner[f, e] = s @ g
            edge_share[f, e] = share
    return gauge, sign, corner, edge_gauge, edge_sign, edge_corner, edge_axis, edge_share


def pseudo_inverse_envelope(axes, max_torque_n_m):
    """The torques the minimum-norm distribution delivers unscaled: a polytope.

    ``{tau : |(A+ tau)_i| <= L_i}``, the intersection of the slabs of every
    wheel, as (normals (2n, 3), offsets (2n,)): facet ``i`` has the normal
    of row ``i`` of ``A+`` and the offset ``L_i / |row i|``. Its inscribed
    radius is the smallest offset; the reach along a direction ``u`` is
    ``min_i L_i / |(A+ u)_i|``.

    ``axes`` holds the unit spin axes, one row per wheel (body axes), and
    ``max_torque_n_m`` [N m] the motor torque limit ``L_i``, per wheel or one
    for all.
    """
    pinv = pseudo_inverse(np.asarray(axes, dtype=float))
    lim = per_wheel(max_torque_n_m, pinv.shape[0])
    norm = np.linalg.norm(pinv, axis=1)
    normals = np.vstack((pinv / norm[:, None], -pinv / norm[:, None]))
    return normals, np.concatenate((lim / norm, lim / norm))


def make_params(axes, max_torque_n_m, max_momentum_n_m_s, inertia_kg_m2,
                torque_per_volt_n_m_v, unload_fraction, unload_end_fraction,
                jet_torque_n_m, pulse_frames, allocation="pseudo_inverse") -> WheelParams:
    """Build :class:`WheelParams`.

    Parameters
    ----------
    axes : array_like, shape (n, 3)
        Unit spin axes in body axes, spanning 3-D.
    max_torque_n_m, max_momentum_n_m_s, inertia_kg_m2 : float or array_like, shape (n,)
        [N m], [N m s], [kg m^2] per wheel, or one number for all.
    torque_per_volt_n_m_v : array_like, shape (3,)
        [N m/V] Body torque commanded per volt of control amplifier 31, 32, 33.
    unload_fraction, unload_end_fraction : float
        [-] Unloading starts when a wheel reaches the first fraction of its
        momentum limit and ends when every wheel is under the second.
    jet_torque_n_m : array_like, shape (3,)
        [N m] Couple torque of the roll, pitch and yaw jets that unload.
    pulse_frames : int
        [frames] Length of one unloading pulse (the valves' minimum on-time).
    allocation : {"pseudo_inverse", "direct"}
        Minimum-norm distribution, or direct allocation to the whole
        envelope when it saturates (module notes).
    """
    g = np.array(axes, dtype=float).reshape(-1, 3)
    n = g.shape[0]
    pinv = pseudo_inverse(g)
    torque = per_wheel(max_torque_n_m, n)
    momentum = per_wheel(max_momentum_n_m_s, n)
    # Axis dead band d: with every |H_a| <= d, |h_i| <= sum_a |A+_ia| d <= end * limit_i.
    deadband = float(unload_end_fraction) * float(np.min(momentum
                                                          / np.abs(pinv).sum(axis=1)))
    reach = make_envelope(g, torque).max_along_body_axes()
    jet = np.asarray(jet_torque_n_m, dtype=float)
    pulses = int(pulse_frames)
    period = np.array([max(pulses + 1, math.ceil(jet[a] * pulses
                                                  / (UNLOAD_TORQUE_SHARE * reach[a])))
                       for a in range(3)], dtype=np.int64)
    return WheelParams(g, pinv, torque, momentum, per_wheel(inertia_kg_m2, n),
                       np.asarray(torque_per_volt_n_m_v, dtype=float).copy(),
                       np.array(reach, dtype=float), np.abs(g).T @ torque,
                       float(unload_fraction), deadband, pulses,
                       period, ALLOCATION_CODE[allocation], *direct_tables(g, torque),
                       np.eye(n) - pinv @ g.T, 1.0 / NULL_SPACE_TIME_S)


@njit_stage
def body_vector(axes, per_wheel_values, out):
    """``out = A v``: a per-wheel quantity (momentum, torque) summed in body axes.

    ``axes`` (n, 3) holds the spin axes, one row per wheel; ``per_wheel_values``
    (n) is ``v`` (e.g. momenta [N m s] or motor torques [N m]); ``out`` (3)
    receives the sum in body axes, in the same unit.
    """
    for a in range(3):
        out[a] = 0.0
    for i in range(axes.shape[0]):
        for a in range(3):
            out[a] += axes[i, a] * per_wheel_values[i]


@njit_stage
def distribute(p, torque_body_n_m, h_n_m_s, dt_s, u_n_m):
    """Motor torques ``u_n_m`` (n) for the body torque ``torque_body_n_m`` [N m].

    The minimum-norm distribution (``wheels.allocation = "pseudo_inverse"``);
    the frame loop calls :func:`distribute_direct` for ``"direct"``.

    ``-A u`` is the body torque. Each component of the command is first
    limited to ``axis_reach_n_m``; then ``u = -A+ tau``, scaled by the largest
    factor <= 1 that keeps each ``|u_i|`` within its torque limit and each
    ``|h_i + u_i dt|`` within its momentum limit over the frame ``dt_s`` (a
    wheel past its limit may only be slowed): the body gets the (limited)
    command, or its largest part in the same direction. Returns the factor.

    ``p`` is the wheel array (:class:`WheelParams`); ``h_n_m_s`` (n) each
    wheel's momentum [N m s] at the start of the frame.
    """
    n = p.axes.shape[0]
    r = p.axis_reach_n_m
    tx = min(max(torque_body_n_m[0], -r[0]), r[0])
    ty = min(max(torque_body_n_m[1], -r[1]), r[1])
    tz = min(max(torque_body_n_m[2], -r[2]), r[2])
    scale = 1.0
    for i in range(n):
        ui = -(p.pinv[i, 0] * tx + p.pinv[i, 1] * ty + p.pinv[i, 2] * tz)
        u_n_m[i] = ui
        if abs(ui) * scale > p.max_torque_n_m[i]:
            scale = p.max_torque_n_m[i] / abs(ui)
    for i in range(n):
        ui = u_n_m[i] * scale
        if ui * h_n_m_s[i] >= 0.0 and ui != 0.0:  # speeding the wheel up
            room = max(p.max_momentum_n_m_s[i] - abs(h_n_m_s[i]), 0.0)
            if abs(ui) * dt_s > room:
                scale *= room / (abs(ui) * dt_s)
    for i in range(n):
        u_n_m[i] *= scale
    return scale


@njit_stage
def distribute_direct(p, torque_body_n_m, h_n_m_s, dt_s, u_n_m):
    """:func:`distribute` with ``wheels.allocation = "direct"``.

    Each component of the command is limited to the envelope's extent along
    its axis (``axis_support_n_m``, the envelope's box: no torque inside the
    envelope is touched); where the minimum-norm torques would then exceed a
    limit it is allocated directly on the envelope
    (:func:`direct_allocation`), delivered exactly inside the envelope and,
    beyond it, as the largest torque along its direction. The momentum room
    scales it as in :func:`distribute`, and the null-space momentum is
    managed (:func:`null_space_momentum`). Returns the scale.

    Parameters
    ----------
    p : WheelParams
        The wheel array.
    torque_body_n_m : array of 3 float
        [N m] body torque commanded, body axes.
    h_n_m_s : array of n float
        [N m s] each wheel's momentum at the start of the frame.
    dt_s : float
        [s] frame length.
    u_n_m : array of n float
        [N m] written: the motor torques.
    """
    n = p.axes.shape[0]
    r = p.axis_support_n_m
    tx = min(max(torque_body_n_m[0], -r[0]), r[0])
    ty = min(max(torque_body_n_m[1], -r[1]), r[1])
    tz = min(max(torque_body_n_m[2], -r[2]), r[2])
    scale = 1.0
    for i in range(n):
        ui = -(p.pinv[i, 0] * tx + p.pinv[i, 1] * ty + p.pinv[i, 2] * tz)
        u_n_m[i] = ui
        if abs(ui) * scale > p.max_torque_n_m[i]:
            scale = p.max_torque_n_m[i] / abs(ui)
    if scale < 1.0:
        scale = direct_allocation(p, tx, ty, tz, u_n_m)
    for i in range(n):
        ui = u_n_m[i] * scale
        if ui * h_n_m_s[i] >= 0.0 and ui != 0.0:  # speeding the wheel up
            room = max(p.max_momentum_n_m_s[i] - abs(h_n_m_s[i]), 0.0)
            if abs(ui) * dt_s > room:
                scale *= room / (abs(ui) * dt_s)
    for i in range(n):
        u_n_m[i] *= scale
    null_space_momentum(p, h_n_m_s, dt_s, u_n_m)
    return scale


@njit
def direct_allocation(p, tx, ty, tz, u_n_m):
    """Direct allocation of the body torque ``(tx, ty, tz)``; returns the scale.

    The motor torques go into ``u_n_m``.

    The facet the torque's ray leaves the envelope through is the one of the
    largest gauge ``g`` (the envelope's gauge function: ``tau / g`` is on
    its boundary); the wheels off its plane run at ``g`` times their corner.
    The rest lies in the facet's plane, and its ray leaves the facet's
    zonogon through the edge of the largest in-plane gauge ``g2 <= g``: the
    in-plane wheels off that edge run at ``g2`` times theirs, and the
    wheels along the edge share what is left, each in proportion to its
    limit (:func:`direct_tables`). ``-A u`` is then ``tau`` to rounding,
    with no wheel beyond ``g`` of its limit. Returns 1 inside the envelope,
    ``1/g`` beyond it (``u`` then exceeds the limits by ``g``, and the
    caller's scaling puts the torque on the boundary, along its direction).

    ``p`` is the wheel array (:class:`WheelParams`, its facet tables);
    ``tx``, ``ty``, ``tz`` [N m] the body torque commanded about body x, y, z;
    ``u_n_m`` (n) receives the motor torques [N m].
    """
    best, f = -1.0, 0
    for k in range(p.facet_gauge.shape[0]):
        v = p.facet_gauge[k, 0] * tx + p.facet_gauge[k, 1] * ty + p.facet_gauge[k, 2] * tz
        if v > best:
            best, f = v, k
    g = max(best, 0.0)
    rx = tx - g * p.facet_corner[f, 0]
    ry = ty - g * p.facet_corner[f, 1]
    rz = tz - g * p.facet_corner[f, 2]
    best, e = -1.0, 0
    for k in range(p.edge_gauge.shape[1]):
        row = p.edge_gauge[f, k]
        v = row[0] * rx + row[1] * ry + row[2] * rz
        if v > best:
            best, e = v, k
    g2 = max(best, 0.0)
    c = p.edge_corner[f, e]
    d = p.edge_axis[f, e]
    along = (d[0] * (rx - g2 * c[0]) + d[1] * (ry - g2 * c[1]) + d[2] * (rz - g2 * c[2]))
    for i in range(p.axes.shape[0]):
        u_n_m[i] = -(g * p.facet_sign[f, i] + g2 * p.edge_sign[f, e, i]
                     + along * p.edge_share[f, e, i])
    return 1.0 / g if g > 1.0 else 1.0


@njit
def null_space_momentum(p, h_n_m_s, dt_s, u_n_m):
    """Add ``-(I - A+ A) h / T`` to the motor torques, within the torque room.

    It turns no body (``A (I - A+ A) = 0``) and returns the momentum the
    direct allocation stored in the array's null space. The share ``a`` in
    [0, 1] is the largest that keeps every ``|u_i|`` within its limit and
    spins no wheel past its momentum limit over the frame.

    ``p`` is the wheel array (:class:`WheelParams`), ``h_n_m_s`` (n) the wheel
    momenta [N m s], ``dt_s`` [s] the frame length, ``u_n_m`` (n) the motor
    torques [N m] so far, added to.
    """
    n = p.axes.shape[0]
    a = 1.0
    for i in range(n):
        v = 0.0
        for j in range(n):
            v -= p.null_projector[i, j] * h_n_m_s[j]
        v *= p.null_rate_per_s
        if v != 0.0:
            room = p.max_torque_n_m[i] - abs(u_n_m[i])
            a = min(a, max(room, 0.0) / abs(v))
            if v * h_n_m_s[i] > 0.0:
                spare = max(p.max_momentum_n_m_s[i] - abs(h_n_m_s[i] + u_n_m[i] * dt_s), 0.0)
                a = min(a, spare / (abs(v) * dt_s))
    if a <= 0.0:
        return
    for i in range(n):
        v = 0.0
        for j in range(n):
            v -= p.null_projector[i, j] * h_n_m_s[j]
        u_n_m[i] += a * v * p.null_rate_per_s


@njit_stage
def unload_valves(p, h_n_m_s, unload, valve):
    """Jet valve commands (-1/0/+1 per body axis) into ``valve``: momentum unloading.

    ``unload`` (4,) int64 is the unloader's state: ``[0]`` 1 while unloading,
    ``[1:4]`` the frames each axis has fired pulses for. Unloading starts when
    a wheel reaches ``unload_start_fraction`` of its limit; while it lasts,
    each body axis whose stored momentum ``(A h)_a`` is outside the dead band
    fires a pulse of ``unload_pulse_frames`` every ``unload_period_frames[a]``
    frames, against that momentum. ``p`` is the wheel array
    (:class:`WheelParams`); ``h_n_m_s`` (n) the wheel momenta [N m s].
    """
    n = p.axes.shape[0]
    if unload[0] == 0:
        for i in range(n):
            if abs(h_n_m_s[i]) >= p.unload_start_fraction * p.max_momentum_n_m_s[i]:
                unload[0] = 1
    firing = False
    for a in range(3):
        valve[a] = 0
        stored = 0.0
        for i in range(n):
            stored += p.axes[i, a] * h_n_m_s[i]
        if unload[0] != 0 and abs(stored) > p.unload_deadband_n_m_s:
            firing = True
            if unload[1 + a] % p.unload_period_frames[a] < p.unload_pulse_frames:
                valve[a] = -1 if stored > 0.0 else 1
            unload[1 + a] += 1
        else:
            unload[1 + a] = 0
    if not firing:
        unload[0] = 0


def wheel_speeds_rad_s(p: WheelParams, h_n_m_s, rate_body_rad_s) -> np.ndarray:
    """Wheel speeds relative to the body [rad/s]: ``h_i / J_i - g_i . w``.

    ``p`` is the wheel array, ``h_n_m_s`` (n) the wheel momenta [N m s] and
    ``rate_body_rad_s`` (3) the body rate ``w`` [rad/s], body axes.
    """
    return np.asarray(h_n_m_s) / p.inertia_kg_m2 - p.axes @ np.asarray(rate_body_rad_s)


def spin_inertia_tensor_kg_m2(p: WheelParams) -> np.ndarray:
    """The wheels' spin inertia about their axes in body axes, ``sum_i J_i g_i g_i^T``.

    The gyrostat's body inertia is the vehicle's less this
    (:func:`allsky.vehicle.plant.gyrostat_params`). ``p`` is the wheel array
    (its axes and spin inertias).
    """
    return (p.axes.T * p.inertia_kg_m2) @ p.axes


@njit_stage
def advance_momentum(p, u_n_m, dt_s, h_n_m_s, peak_fraction):
    """The wheel momenta over a frame of constant motor torque: ``h += u dt`` (exact).

    ``peak_fraction`` (1,) keeps the largest ``|h_i| / limit_i`` reached.

    Parameters
    ----------
    p : WheelParams
        The wheel array.
    u_n_m : array of n float
        [N m] motor torques, held over the frame.
    dt_s : float
        [s] frame length.
    h_n_m_s : array of n float
        [N m s] wheel momenta, advanced in place.
    """
    for i in range(p.axes.shape[0]):
        h_n_m_s[i] += u_n_m[i] * dt_s
        peak_fraction[0] = max(peak_fraction[0], abs(h_n_m_s[i]) / p.max_momentum_n_m_s[i])
