"""Torque and momentum envelopes of reaction-wheel arrays and jet couples.

The set of body torques an array of ``n`` reaction wheels can give, each wheel
``i`` with unit spin axis ``g_i`` (body frame) and torque limit ``L_i``, is the
image of the n-cube ``{|c_i| <= 1}`` under the 3 x n matrix ``[L_i g_i]``: a
zonotope (R. G. Reynolds & F. L. Markley, *Maximum torque and momentum
envelopes for reaction wheel arrays*, NASA GSFC, the third source document;
journal version F. L. Markley, R. G. Reynolds, F. X. Liu & K. L. Lebsock,
J. Guidance Control Dyn. 33(5), 2010). The momentum envelope is the same set
with the momentum limits. On/off jet couples fill the same shape: each couple
fires -1, 0 or +1, and pulse-width modulation over a frame reaches every
average in between.

How it is computed
------------------
* Support function ``h(n) = sum_i L_i |n . g_i|``: the largest ``n . x`` over
  the envelope, reached at the corner ``c_i = sign(n . g_i)``.
* Facets (spanning axes, full rank): a facet's plane contains at least two
  non-parallel generators, so its unit normal is ``+-(g_i x g_j) / |g_i x g_j|``
  for a pair of non-parallel axes; its offset (distance from the origin) is
  ``h(n)``. Every such pair gives a genuine facet. Pairs whose axes lie in one
  plane with other axes give the same facet; a facet is identified by the set
  of axes perpendicular to its normal, so each appears once. Parallel or
  antiparallel axes are legal (they add up to one longer generator) and give
  no pair of their own.
* Largest magnitude along a direction ``u`` (unit):
  ``min over facets with n . u > 0 of h(n) / (n . u)``; the inscribed sphere
  about the origin has radius ``min h(n)`` over the facets.
* Axes in one plane (rank 2, e.g. three orthogonal wheels with one failed):
  the envelope is flat. It is described by the two faces ``+-p`` (``p`` the
  plane's normal) at offset 0 and, in the plane, the sides normal to
  ``p x g_k``. The same formulas then give 0 out of the plane and the
  polygon's reach inside it; the inscribed radius is 0. Axes that are all
  parallel are refused.

Tolerance: two unit axes count as parallel, and an axis as lying in a facet's
plane, when the sine (or cosine) concerned is below :data:`PLANE_TOL`.

Units follow the limits: [N m] for torque envelopes, [N m s] for momentum.
"""

from dataclasses import dataclass
from itertools import combinations
from typing import NamedTuple

import numpy as np

#: Sine of the angle below which two unit axes count as parallel; also the
#: largest ``|n . g|`` for an axis g to count as lying in the plane of normal n.
PLANE_TOL = 1e-9
#: Largest ``|n . u|`` taken as zero when finding the facet a ray leaves through,
#: so a direction in a flat envelope's plane is not stopped by its +-p faces.
RAY_TOL = 1e-12
#: Relative tolerance on the inscribed radius under which two single failures
#: count as equally bad (symmetric arrays give ties to rounding).
TIE_RTOL = 1e-12

#: The body axes x (roll), y (pitch), z (yaw), one per row.
BODY_AXES = np.eye(3)


@dataclass(frozen=True, eq=False)
class Envelope:
    """Reachable torques (or momenta) of an actuator array: a zonotope.

    Build it with :func:`make_envelope`. Arrays are read-only.
    """

    axes: np.ndarray  #: (n, 3) unit spin axes, body frame
    limits: np.ndarray  #: (n,) limit of each actuator [N m] or [N m s]
    normals: np.ndarray  #: (m, 3) unit outward facet normals, body frame
    offsets: np.ndarray  #: (m,) distance of each facet's plane from the origin = h(normal)
    facet_axes: tuple  #: per facet, the indices of the axes perpendicular to its normal
    rank: int  #: 3 for a solid envelope, 2 for a flat one (axes in one plane)

    @property
    def min_radius(self) -> float:
        """Radius of the largest sphere about the origin inside the envelope (0 if flat)."""
        return float(np.min(self.offsets))

    def support(self, direction) -> np.ndarray:
        """Support function ``h(d) = sum_i L_i |d . g_i|``, one (3,) or many (k, 3) ``d``.

        ``direction`` is ``d``, in body axes. Not normalised: ``h`` is
        positively homogeneous of degree 1, so for a unit ``d`` it is the
        largest component along ``d`` of any reachable vector.
        """
        d = np.asarray(direction, dtype=float)
        return np.abs(d @ self.axes.T) @ self.limits

    def max_along(self, direction) -> np.ndarray:
        """Largest magnitude reachable along ``direction`` (one or many, normalised here).

        Parameters
        ----------
        direction : array_like, shape (3,) or (k, 3)
            Direction(s) in body axes; any non-zero length.

        Returns
        -------
        float or ndarray, shape (k,)
            ``t`` such that ``t u`` (``u`` the unit direction) is on the
            envelope's boundary [N m] or [N m s].
        """
        return self._ray(direction)[0]

    def boundary_point(self, direction):
        """Where the ray along ``direction`` leaves the envelope, and through which facet.

        Returns
        -------
        point : ndarray, shape (3,) or (k, 3)
            ``max_along(u) * u`` for the unit direction(s) ``u``.
        facet : int or ndarray of int
            Index into :attr:`normals` of the facet containing the point.
        """
        t, k, u = self._ray(direction)
        return np.asarray(t)[..., None] * u, k

    def max_along_body_axes(self) -> np.ndarray:
        """Largest magnitude reachable along body x, y, z (roll, pitch, yaw), shape (3,)."""
        return self.max_along(BODY_AXES)

    def without(self, index: int) -> "Envelope":
        """The envelope with actuator ``index`` failed (removed)."""
        keep = np.arange(len(self.limits)) != index
        if keep.all():
            raise IndexError(f"no actuator {index} among {len(self.limits)}")
        return make_envelope(self.axes[keep], self.limits[keep])

    def _ray(self, direction):
        """(reach t, facet index, unit direction) for one (3,) or many (k, 3) directions."""
        u = np.asarray(direction, dtype=float)
        if u.shape[-1:] != (3,) or u.ndim > 2:
            raise ValueError(f"a direction has 3 components, shape (3,) or (k, 3); got {u.shape}")
        norm = np.linalg.norm(u, axis=-1, keepdims=True)
        if not np.all(np.isfinite(norm)) or np.any(norm == 0.0):
            raise ValueError("a direction must be finite and non-zero")
        u = u / norm
        cos = np.atleast_2d(u) @ self.normals.T
        # Facets facing away (or edge-on) cannot stop the ray. The envelope is
        # centrally symmetric and its normals span R^3, so some facet faces
        # every ray.
        facing = cos > RAY_TOL
        ratio = np.full(cos.shape, np.inf)
        np.divide(np.broadcast_to(self.offsets, cos.shape), cos, out=ratio, where=facing)
        k = np.argmin(ratio, axis=1)
        t = ratio[np.arange(len(k)), k]
        if u.ndim == 1:
            return float(t[0]), int(k[0]), u
        return t, k, u


def _limits(limit, n: int, name: str) -> np.ndarray:
    """One positive finite limit per actuator from one number or ``n`` numbers."""
    a = np.asarray(limit, dtype=float)
    if a.ndim == 0:
        a = np.full(n, float(a))
    if a.shape != (n,):
        raise ValueError(f"{name}: give one number or one per actuator ({n}); got shape {a.shape}")
    if not np.all(np.isfinite(a)) or np.any(a <= 0.0):
        raise ValueError(f"{name}: every limit must be finite and > 0; got {a.tolist()}")
    return a


def _unit_axes(axes) -> np.ndarray:
    """Check the spin axes: an (n, 3) array of finite unit vectors."""
    g = np.asarray(axes, dtype=float)
    if g.ndim != 2 or g.shape[1] != 3 or g.shape[0] == 0:
        raise ValueError(f"axes: an (n, 3) array of unit vectors, one row per actuator; "
                         f"got shape {g.shape}")
    if not np.all(np.isfinite(g)):
        raise ValueError("axes: every component must be finite")
    length = np.linalg.norm(g, axis=1)
    bad = np.flatnonzero(np.abs(length - 1.0) > PLANE_TOL)
    if bad.size:
        raise ValueError(f"axes: row {int(bad[0])} has length {length[bad[0]]:.12g}; "
                         "spin axes are unit vectors")
    return g


def _parallel_classes(g: np.ndarray) -> list:
    """Representative index of each set of mutually (anti)parallel axes, in order."""
    reps = []
    for i in range(len(g)):
        if all(np.linalg.norm(np.cross(g[i], g[r])) > PLANE_TOL for r in reps):
            reps.append(i)
    return reps


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def make_envelope(axes, limit) -> Envelope:
    """Envelope of actuators with unit axes ``axes`` and limits ``limit``.

    Parameters
    ----------
    axes : array_like, shape (n, 3)
        Unit spin (or couple) axes in body axes, one row per actuator.
    limit : float or array_like, shape (n,)
        Largest torque [N m] (or momentum [N m s]) of each actuator; one
        number for all.

    Returns
    -------
    Envelope
        Facets from every pair of non-parallel axes, both signs, each plane
        once (see the module notes).

    Raises
    ------
    ValueError
        Axes not unit vectors, limits not > 0, or all axes parallel (the
        envelope is a segment; no torque across it).
    """
    g = _unit_axes(axes)
    lim = _limits(limit, len(g), "limit")
    reps = _parallel_classes(g)
    if len(reps) < 2:
        raise ValueError("axes: all actuators are parallel; they reach torques along one "
                         "line only")
    rank = 3 if np.linalg.matrix_rank(g, tol=PLANE_TOL) >= 3 else 2

    def perpendicular(n):
        return tuple(int(k) for k in np.flatnonzero(np.abs(g @ n) <= PLANE_TOL))

    if rank == 3:
        # Each plane once, keyed by the axes lying in it (a coplanar triple
        # gives the same facet from all three of its pairs).
        planes = {}
        for a, b in combinations(reps, 2):
            n = _unit(np.cross(g[a], g[b]))
            planes.setdefault(perpendicular(n), n)
        sides = list(planes.items())
    else:
        p = _unit(np.cross(g[reps[0]], g[reps[1]]))
        sides = [(tuple(range(len(g))), p)]
        sides += [(perpendicular(n), n) for n in (_unit(np.cross(p, g[r])) for r in reps)]
    normals = np.array([s * n for _, n in sides for s in (1.0, -1.0)])
    facet_axes = tuple(key for key, _ in sides for _ in (1.0, -1.0))
    offsets = np.abs(normals @ g.T) @ lim
    if rank == 2:
        # No extent along p: the computed support is rounding noise (~1e-17).
        offsets[:2] = 0.0
    for a in (g, lim, normals, offsets):
        a.setflags(write=False)
    return Envelope(g, lim, normals, offsets, facet_axes, rank)


def single_failures(envelope: Envelope) -> list:
    """``envelope`` with each actuator failed in turn: ``[envelope.without(i) for i]``."""
    return [envelope.without(i) for i in range(len(envelope.limits))]


def worst_failure(torque: Envelope, momentum: Envelope) -> int:
    """Index of the single failure leaving the smallest torque inscribed radius.

    Ties (within :data:`TIE_RTOL`, as symmetric arrays give) go to the smaller
    momentum radius, then to the lowest index. The ``torque`` [N m] and
    ``momentum`` [N m s] envelopes (:func:`make_envelope`) must describe the
    same axes.
    """
    if torque.axes.shape != momentum.axes.shape or not np.array_equal(torque.axes,
                                                                      momentum.axes):
        raise ValueError("torque and momentum envelopes of different arrays")
    candidates = np.arange(len(torque.limits))
    for env in (torque, momentum):
        r = np.array([env.without(i).min_radius for i in candidates])
        candidates = candidates[r <= r.min() + TIE_RTOL * max(env.min_radius, r.max())]
    return int(candidates[0])


def pyramid_axes(beta_deg: float) -> np.ndarray:
    """Spin axes of the usual four-wheel pyramid about body +x (roll).

    Wheel ``k`` (k = 0..3) sits at azimuth ``90 k`` deg about +x, measured
    from +y toward +z, and its axis makes the angle ``beta`` with +x::

        g_k = (cos beta, sin beta cos(90 k), sin beta sin(90 k))

    so wheels 0 and 2 span the x-y plane and wheels 1 and 3 the x-z plane:
    each transverse body axis, y (pitch) and z (yaw), lies in the plane of
    one opposite pair.

    The pyramid axis is roll because roll needs the least: the vehicle's roll
    inertia is about a sixth of pitch and yaw (100 against 650-680 kg m^2 in
    the default scenario) and its roll jet couple gives a fifth of the
    others' torque. The pyramid gives ``4 tau cos(beta)`` along its axis and
    ``2 tau sin(beta)`` along y and z, so a large ``beta`` moves capability
    to pitch and yaw; ``beta = atan(sqrt(2)) = 54.74`` deg puts all twelve
    facets at the same distance, ``2 tau sqrt(2/3)`` (``docs/envelopes.md``).

    Parameters
    ----------
    beta_deg : float
        Angle between each spin axis and the pyramid axis [deg], 0 < beta < 90.

    Returns
    -------
    ndarray, shape (4, 3)
        Unit spin axes in body axes.
    """
    beta = float(beta_deg)
    if not 0.0 < beta < 90.0:
        raise ValueError(f"beta_deg: between 0 and 90 deg exclusive (0 = all wheels on +x, "
                         f"90 = all in the y-z plane); got {beta_deg}")
    c, s = np.cos(np.radians(beta)), np.sin(np.radians(beta))
    # Exact cos/sin of the 90-deg azimuths, so the zero components are zeros.
    azimuth = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]])
    return np.column_stack([np.full(4, c), s * azimuth[:, 0], s * azimuth[:, 1]])


def jet_envelope(couple_torque_n_m) -> Envelope:
    """Envelope of one on/off jet couple per body axis: a box.

    Parameters
    ----------
    couple_torque_n_m : array_like, shape (3,)
        Torque of the roll, pitch and yaw couples [N m], ``2 F r`` each
        (jets 39, 40, 41: :func:`allsky.hardware.jets.make_params` gives it
        as ``torque_n_m``).

    Returns
    -------
    Envelope
        Built by :func:`make_envelope` with the body axes as couple axes:
        inscribed radius = the smallest couple torque, reach along each axis
        = that axis's couple torque.
    """
    return make_envelope(BODY_AXES, _limits(couple_torque_n_m, 3, "couple_torque_n_m"))


class ProfileCheck(NamedTuple):
    """Whether a profile of torque (or momentum) vectors stays inside an envelope."""

    inside: bool  #: every sample within the envelope (margin >= 1)
    margin: float  #: smallest (available along the sample's direction) / (sample's magnitude)
    worst_sample: int  #: index of the sample setting the margin (-1 if all samples are zero)


def check_profile(envelope: Envelope, vectors) -> ProfileCheck:
    """Check that each vector of a profile lies inside ``envelope``, with the margin.

    Parameters
    ----------
    envelope : Envelope
        Torque [N m] or momentum [N m s] envelope, body axes.
    vectors : array_like, shape (k, 3) or (3,)
        The profile, same units and axes; zero samples need nothing and are
        skipped.

    Returns
    -------
    ProfileCheck
        ``margin = min_s max_along(v_s) / |v_s|``; ``inside`` when it is >= 1.
        A margin of 2 means the profile could be doubled and still be met.
    """
    v = np.atleast_2d(np.asarray(vectors, dtype=float))
    if v.ndim != 2 or v.shape[1] != 3:
        raise ValueError(f"vectors: shape (k, 3); got {np.shape(vectors)}")
    if not np.all(np.isfinite(v)):
        raise ValueError("vectors: every component must be finite")
    size = np.linalg.norm(v, axis=1)
    live = np.flatnonzero(size > 0.0)
    if live.size == 0:
        return ProfileCheck(True, float("inf"), -1)
    ratio = envelope.max_along(v[live]) / size[live]
    worst = int(np.argmin(ratio))
    margin = float(ratio[worst])
    return ProfileCheck(margin >= 1.0, margin, int(live[worst]))


def _reach(envelope: Envelope, unit: str) -> dict:
    """``{"min_radius_<unit>": r, "max_<unit>": [x, y, z]}`` as plain floats."""
    return {f"min_radius_{unit}": envelope.min_radius,
            f"max_{unit}": [float(x) for x in envelope.max_along_body_axes()]}


def envelope_summary(axes, torque_max_n_m, momentum_max_n_m_s, jet_torque_n_m) -> dict:
    """Torque and momentum reach: a wheel array, its worst single failure, the jets.

    Parameters
    ----------
    axes : array_like, shape (n, 3)
        Unit spin axes of the wheels, body axes (e.g. :func:`pyramid_axes`).
    torque_max_n_m : float or array_like, shape (n,)
        Largest torque of each wheel [N m].
    momentum_max_n_m_s : float or array_like, shape (n,)
        Largest momentum of each wheel [N m s].
    jet_torque_n_m : array_like, shape (3,)
        Torque of the roll, pitch and yaw jet couples [N m] (``2 F r``).

    Returns
    -------
    dict
        JSON-ready, this layout::

            {"wheels": {"torque": {"min_radius_n_m": r, "max_n_m": [x, y, z]},
                        "momentum": {"min_radius_n_m_s": r, "max_n_m_s": [x, y, z]},
                        "one_failed": {"wheel": i,
                                       "torque": {...same keys...},
                                       "momentum": {...same keys...}}},
             "jets": {"torque": {"min_radius_n_m": r, "max_n_m": [x, y, z]}}}

        ``max`` is the largest magnitude reachable along body x, y, z;
        ``min_radius`` the inscribed sphere's radius. ``one_failed`` is the
        single failure with the smallest torque radius (:func:`worst_failure`).

    Raises
    ------
    ValueError
        The wheel axes do not span three dimensions (the array cannot give
        torque in every direction), or bad axes or limits.
    """
    torque = make_envelope(axes, torque_max_n_m)
    momentum = make_envelope(axes, momentum_max_n_m_s)
    if torque.rank < 3:
        raise ValueError("axes: the wheel axes lie in one plane; they give no torque "
                         "across it")
    worst = worst_failure(torque, momentum)
    return {
        "wheels": {
            "torque": _reach(torque, "n_m"),
            "momentum": _reach(momentum, "n_m_s"),
            "one_failed": {"wheel": worst,
                           "torque": _reach(torque.without(worst), "n_m"),
                           "momentum": _reach(momentum.without(worst), "n_m_s")},
        },
        "jets": {"torque": _reach(jet_envelope(jet_torque_n_m), "n_m")},
    }


def _hull_2d(points: np.ndarray) -> np.ndarray:
    """Indices of the convex hull of 2-D points, counter-clockwise (monotone chain)."""
    order = sorted(range(len(points)), key=lambda i: (points[i, 0], points[i, 1]))

    def cross(o, a, b):
        return ((points[a, 0] - points[o, 0]) * (points[b, 1] - points[o, 1])
                - (points[a, 1] - points[o, 1]) * (points[b, 0] - points[o, 0]))

    scale = float(np.ptp(points)) ** 2 or 1.0
    chains = []
    for seq in (order, order[::-1]):
        chain = []
        for i in seq:
            # Collinear points (parallel in-plane axes, rounding) are dropped.
            while len(chain) >= 2 and cross(chain[-2], chain[-1], i) <= 1e-12 * scale:
                chain.pop()
            chain.append(i)
        chains.append(chain[:-1])
    return np.array(chains[0] + chains[1])


def facet_polygons(envelope) -> list:
    """The corners of each facet of an envelope, ordered around it.

    For the facet of outward normal ``n`` the axes not lying in its plane sit
    at their limit on the side of ``n``, ``sum sign(n . g_i) L_i g_i``, and
    the axes in its plane (``envelope.facet_axes``) take every combination
    of ``+-L_j g_j``; the facet is the convex hull of those points in the plane.

    Parameters
    ----------
    envelope : allsky.vehicle.envelopes.Envelope

    Returns
    -------
    list of ndarray, shape (k, 3)
        One polygon per facet, in the order of ``envelope.normals``; its
        vertices lie on the facet's plane ``n . x = h(n)``, counter-clockwise
        seen from outside.
    """
    g, lim = envelope.axes, envelope.limits
    polygons = []
    for n, plane in zip(envelope.normals, envelope.facet_axes, strict=True):
        inside = np.zeros(len(g), dtype=bool)
        inside[list(plane)] = True
        side = np.sign(g @ n)
        base = ((~inside) * side * lim) @ g
        signs = np.array(np.meshgrid(*[[-1.0, 1.0]] * len(plane))).reshape(len(plane), -1).T
        corners = base + (signs * lim[list(plane)]) @ g[list(plane)]
        # A right-handed basis of the plane, so that the hull's counter-clockwise
        # order is counter-clockwise seen from outside (along -n).
        e1 = np.cross(n, BODY_AXES[int(np.argmin(np.abs(n)))])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(n, e1)
        flat = (corners - corners.mean(axis=0)) @ np.column_stack([e1, e2])
        polygons.append(corners[_hull_2d(flat)])
    return polygons
