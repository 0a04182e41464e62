"""The sunlit Earth in star tracker 105's slit, against rays cast through the slit.

The loop decides in closed form (:func:`allsky.vehicle.environment.earth_glare`):
the disk against the slit's edges and corners, and the brightest point among
the constraint circles' tops and crossings. Here the same questions are
answered another way: rays on a grid across the slit, each intersected with
the Earth's sphere, the Sun's incidence read at the point each one hits.
"""

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from allsky.config.scenario import load_scenario
from allsky.sim.mission import Mission
from allsky.vehicle import environment as env
from allsky.vehicle.quaternion import dcm_body_from_inertial

P = math.radians(16.0)  # the default slit: +-16 deg along, +-8 deg across
Y = math.radians(8.0)
SLIT = env.slit_geometry(P, Y)


def _grid(n_long=129, n_narrow=65, pitch=(-P, P), yaw=(-Y, Y)):
    """Unit ray directions across the slit (or part of it), body axes, its edges included."""
    pitch, yaw = np.meshgrid(np.linspace(*pitch, n_long), np.linspace(*yaw, n_narrow),
                             indexing="ij")
    d = np.stack([np.tan(pitch), -np.tan(yaw), np.ones_like(pitch)], axis=-1)
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def _in_slit(d):
    """Which of the body-axis directions ``d`` (..., 3) lie in the slit."""
    return ((d[..., 2] > 0.0) & (np.abs(np.arctan2(d[..., 0], d[..., 2])) <= P)
            & (np.abs(np.arctan2(-d[..., 1], d[..., 2])) <= Y))


def _edge_and_limb_best(c, sin_ae, u, n=20001):
    """The largest incidence cosine along the slit's edges and the Earth's limb in it.

    Where the brightest point lies on the limb, a grid of rays across the slit
    comes to it only as the square root of its spacing; these rays run along
    the slit's four edges and around the limb itself (at ``a_e`` from the
    Earth's centre, where a ray grazes the sphere), finely.
    """
    c = np.asarray(c)
    t = np.linspace(-1.0, 1.0, n)
    edges = [np.stack([np.full(n, sp) * np.tan(P), -np.tan(t * Y), np.ones(n)], axis=-1)
             for sp in (-1.0, 1.0)]
    edges += [np.stack([np.tan(t * P), -np.full(n, sy) * np.tan(Y), np.ones(n)], axis=-1)
              for sy in (-1.0, 1.0)]
    rays = np.concatenate(edges)
    rays /= np.linalg.norm(rays, axis=-1, keepdims=True)
    e1 = _unit(np.cross(c, [1.0, 0.0, 0.0] if abs(c[0]) < 0.9 else [0.0, 1.0, 0.0]))
    e2 = np.cross(c, e1)
    phi = np.linspace(0.0, 2.0 * np.pi, 4 * n)[:, None]
    cos_ae = math.sqrt(1.0 - sin_ae * sin_ae)
    limb = cos_ae * c + sin_ae * (np.cos(phi) * e1 + np.sin(phi) * e2)
    limb = limb[_in_slit(limb)]
    best = np.nanmax(_cast(c, sin_ae, u, rays), initial=-np.inf)
    if limb.shape[0]:
        v = -c / sin_ae  # a limb ray grazes: it meets the sphere where it passes closest
        p = v + (-(limb @ v))[:, None] * limb
        p /= np.linalg.norm(p, axis=-1, keepdims=True)
        best = max(best, float((p @ u).max()))
    return best


RAYS = _grid()


def _cast(c, sin_ae, u, rays=RAYS):
    """Cosine of the Sun's incidence where each ray hits the Earth (NaN for a miss).

    Units of the Earth's radius: the vehicle at ``-c / sin a_e``, ``c`` the unit
    vector to the Earth's centre, ``u`` to the Sun.
    """
    v = -np.asarray(c) / sin_ae
    vs = rays @ v
    disc = vs * vs - (v @ v - 1.0)
    hit = disc >= 0.0
    t = -vs - np.sqrt(np.where(hit, disc, 0.0))
    hit &= t > 0.0
    p = v + t[..., None] * rays
    return np.where(hit, p @ np.asarray(u), np.nan)


def _unit(v):
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


directions = st.tuples(*(st.floats(-1.0, 1.0) for _ in range(3))).filter(
    lambda v: 0.1 < math.sqrt(sum(x * x for x in v)))


@settings(max_examples=300, deadline=None)
@given(altitude_km=st.floats(150.0, 3000.0), centre=directions, sun=directions,
       toward=st.floats(0.0, 1.0))
def test_the_brightest_point_in_the_slit_is_what_rays_find(altitude_km, centre, sun, toward):
    """The closed form's brightest point bounds every ray's, and the rays come near it."""
    c = _unit(centre)
    c = c + toward * 3.0 * np.array([0.0, 0.0, 1.0])  # often toward the boresight
    assume(np.linalg.norm(c) > 0.1)  # still a direction (not the zero vector)
    c = _unit(c)
    u = _unit(sun)
    sin_ae = 6378.137 / (6378.137 + altitude_km)
    ce = math.sqrt(1.0 - sin_ae * sin_ae)
    cos_i = _cast(c, sin_ae, u)
    hits = ~np.isnan(cos_i)
    best = env.brightest_in_slit(SLIT, c[0], c[1], c[2], ce, u[0], u[1], u[2])
    inside = env._disk_in_slit(SLIT, c[0], c[1], c[2], ce)
    if hits.any():
        assert inside
        found = float(np.nanmax(cos_i))
        assert found <= best + 1e-9  # no ray finds a point brighter than the maximum
        # and the rays along the slit's edges and the limb come to it
        fine = max(found, _edge_and_limb_best(c, sin_ae, u))
        assert fine <= best + 1e-9
        assert best - fine < 2e-3
    elif not inside:
        assert best == -2.0  # no point of the Earth in the slit


def test_a_disk_at_the_boresight_fills_the_slit_and_is_lit_where_the_sun_is_overhead():
    c = np.array([0.0, 0.0, 1.0])  # looking straight down
    sin_ae = 6378.137 / 6678.137
    ce = math.sqrt(1.0 - sin_ae * sin_ae)
    assert env._disk_in_slit(SLIT, 0.0, 0.0, 1.0, ce)
    # the Sun behind the vehicle: the sub-vehicle point is lit at normal incidence
    assert env.brightest_in_slit(SLIT, *c, ce, 0.0, 0.0, -1.0) == 1.0
    # the Sun straight ahead, behind the Earth: the whole slit sees night
    assert env.brightest_in_slit(SLIT, *c, ce, 0.0, 0.0, 1.0) < 0.0


def test_the_disk_meets_the_slit_at_its_edge_and_corner_to_the_nanoradian():
    """Centre ``a_e + d`` from the narrow edge (and from a corner): in for d < 0 only."""
    sin_ae = 6378.137 / 6678.137
    a_e = math.asin(sin_ae)
    ce = math.cos(a_e)
    for d in (-1e-7, 1e-7):
        # beyond the yaw edge at the boresight's pitch: the edge is the great circle yaw = Y
        yaw = Y + a_e + d
        c = np.array([0.0, -math.sin(yaw), math.cos(yaw)])
        assert env._disk_in_slit(SLIT, *c, ce) == (d < 0)
        # beyond the corner (+P, +Y), along the diagonal from the boresight
        corner = SLIT[2]
        axis = _unit(np.cross([0.0, 0.0, 1.0], corner))
        ang = math.acos(corner[2]) + a_e + d
        c = np.array([math.sin(ang) * corner[0] / math.hypot(*corner[:2]),
                      math.sin(ang) * corner[1] / math.hypot(*corner[:2]), math.cos(ang)])
        assert abs(axis @ c) < 1e-12
        assert env._disk_in_slit(SLIT, *c, ce) == (d < 0)


def test_a_sliver_of_sunlit_earth_outshines_the_window():
    """The geometric rule's premise: 1e-9 sr of sunlit Earth is brighter than -1 mag."""
    mu = env.surface_brightness(1.0)  # [mag/arcsec^2] at normal incidence
    assert mu == pytest.approx(2.38, abs=0.01)
    arcsec2 = 1e-9 / (math.pi / 648000.0) ** 2
    assert mu - 2.5 * math.log10(arcsec2) < -1.0
    # the whole slit sunlit: about -22 mag
    full = 4.0 * math.asin(math.sin(P) * math.sin(Y))  # a rectangle's solid angle [sr]
    assert full == pytest.approx(0.1535, abs=0.0001)
    assert mu - 2.5 * math.log10(full / (math.pi / 648000.0) ** 2) == pytest.approx(-22.2,
                                                                                    abs=0.1)


@pytest.fixture(scope="module")
def flown():
    m = Mission(load_scenario("shuttle-free-flyer"), telemetry=True)
    return m, m.run()


def test_the_flown_blinding_is_what_rays_through_the_slit_find(flown):
    """Each telemetry row: blinded per the journal exactly where rays find sunlit Earth.

    The row's attitude, the orbit's nadir, Sun and Earth radius at its time
    (the samples interpolated, as the loop does); rows within 1 s of a
    journal entry of the glare are left out (the row and the frame that
    decided are a frame apart, and the slit may move 0.01 deg a frame).
    """
    m, s = flown
    tlm = m.telemetry()
    o = m.params.orbit
    dt = m.params.frame_s
    edges = [(e["t_s"], e["active"]) for e in s["events"] if e["kind"] == "earth_glare"]
    assert edges, "the free flyer's tracker sees the sunlit Earth in Mode 4's roll"
    t = tlm[:, 0]
    blinded = np.zeros(t.shape, dtype=bool)
    for (t0, on) in edges:
        blinded[t >= t0] = on
    near = np.zeros(t.shape, dtype=bool)
    for (t0, _) in edges:
        near |= np.abs(t - t0) <= 1.0
    rays = _grid(97, 49)
    checked = 0
    for i in np.flatnonzero(~near)[::7]:
        frame = round(t[i] / dt)
        k = min(frame // o.step_frames, o.n - 2)
        w = min((frame - k * o.step_frames) / o.step_frames, 1.0)
        nadir = _unit(o.nadir_i[k] + w * (o.nadir_i[k + 1] - o.nadir_i[k]))
        sun = _unit(o.sun_i[k] + w * (o.sun_i[k + 1] - o.sun_i[k]))
        a_e = o.scalars[k, env.EARTH_RADIUS] + w * (o.scalars[k + 1, env.EARTH_RADIUS]
                                                    - o.scalars[k, env.EARTH_RADIUS])
        q = tlm[i, 2:6]  # q_w, q_x, q_y, q_z: inertial to body
        dcm = dcm_body_from_inertial(q)
        cos_i = _cast(dcm @ nadir, math.sin(a_e), dcm @ sun, rays)
        lit = bool(np.nan_to_num(cos_i, nan=-1.0).max() > 0.0)
        assert lit == blinded[i], f"row at {t[i]:.2f} s"
        checked += 1
    assert checked > 500
    assert blinded[~near].any() and not blinded[~near].all()


@settings(max_examples=400, deadline=None)
@given(altitude_km=st.floats(150.0, 3000.0), centre=directions, sun=directions,
       toward=st.floats(0.0, 1.0))
def test_asking_only_whether_the_slit_is_lit_gives_the_full_searchs_answer(
        altitude_km, centre, sun, toward):
    """earth_glare's early stop (``enough=0``) is lit exactly where the full search is."""
    c = _unit(_unit(centre) + toward * 3.0 * np.array([0.0, 0.0, 1.0]))
    u = _unit(sun)
    sin_ae = 6378.137 / (6378.137 + altitude_km)
    ce = math.sqrt(1.0 - sin_ae * sin_ae)
    best = env.brightest_in_slit(SLIT, c[0], c[1], c[2], ce, u[0], u[1], u[2])
    quick = env.brightest_in_slit(SLIT, c[0], c[1], c[2], ce, u[0], u[1], u[2], 0.0)
    assert (quick > 0.0) == (best > 0.0)
    if best <= 0.0:
        assert quick == best  # nothing lit: both searched every candidate
    else:
        assert 0.0 < quick <= best
