"""Basilisk's gravity-gradient effector as referee of allsky's flown hold in orbit.

The hold of ``tests/flights/test_gravity_gradient_hold.py``: 300 s in a
circular 300 km orbit (inclination 28.5 deg, node 40 deg, argument of
latitude 10 deg at t = 0, no J2), the gravity gradient the only torque, from
40 deg about (1, 2, 3) and body rates (0.02, -0.01, 0.03) deg/s, the
scenario's full inertia tensor. allsky flies it through its frame loop's orbit
and plant stages (the torque held over each 0.01 s frame, the orbit sampled
every 1 s and interpolated); Basilisk (PyPI ``bsk``, 2.x) flies it as one
``spacecraft.Spacecraft`` hub with a ``GravityGradientEffector`` and a
point-mass Earth of the same mu, its default RK4 at a 0.01 s task, the
torque evaluated at every stage and the orbit integrated. Printed: the
rotation [arcsec] between the two attitudes and the largest body-rate
difference [deg/s] every 30 s, and their largest over the hold.

Run, allsky and Basilisk in their own environments (bsk pins its own numpy)::

    python benchmarks/basilisk_gravity_gradient.py --write /tmp/gg_hold.npz   # allsky's
    python benchmarks/basilisk_gravity_gradient.py --read /tmp/gg_hold.npz    # Basilisk's

or without arguments in a Python that has both. Not part of allsky, never
imported by it, and outside the test run.
"""

import argparse
import math
import sys
import time

import numpy as np

#: [m^3/s^2] the Earth's gravitational parameter (WGS 84, EGM96; allsky's MU_EARTH_M3_S2)
MU_M3_S2 = 3.986004418e14
#: [m] the Earth's equatorial radius (WGS 84)
RE_M = 6378137.0
ALTITUDE_KM, INCLINATION_DEG, RAAN_DEG, ARG_LATITUDE_DEG = 300.0, 28.5, 40.0, 10.0
HOLD_S = 300.0
FRAME_S = 0.01  #: [s] allsky's frame and Basilisk's task
CHECK_EVERY_S = 30.0
AXIS0 = np.array([1.0, 2.0, 3.0]) / math.sqrt(14.0)
ANGLE0_DEG = 40.0
RATE0_DEG_S = (0.02, -0.01, 0.03)


def start_state():
    """(7,) the start: inertial-to-body quaternion [w, x, y, z], body rate [rad/s]."""
    h = math.radians(ANGLE0_DEG) / 2.0
    return np.concatenate([[math.cos(h)], math.sin(h) * AXIS0, np.radians(RATE0_DEG_S)])


def fly_allsky():
    """allsky's hold: (times [s], states (n, 7)) every CHECK_EVERY_S, the inertia [kg m^2]."""
    from allsky.config.scenario import load_scenario
    from allsky.sim.frame_loop import advance_vehicle
    from allsky.sim.mission import build_params
    from allsky.sim.parts import orbit_next, orbit_sky, orbit_start, orbit_torque

    cfg = load_scenario(overrides=[
        'orbit.kind="circular"', "orbit.j2=false", f"orbit.altitude_km={ALTITUDE_KM}",
        f"orbit.inclination_deg={INCLINATION_DEG}", f"orbit.raan_deg={RAAN_DEG}",
        f"orbit.arg_latitude_deg={ARG_LATITUDE_DEG}", "orbit.aerodynamic=false",
        "orbit.solar_pressure=false", f"mission.frame_s={FRAME_S}"])
    p = build_params(cfg)
    o = p.orbit
    x = start_state()
    sun_i, sun_b, dtheta = np.zeros(3), np.zeros(3), np.zeros(3)
    frame = np.zeros(1, dtype=np.int64)
    every = round(CHECK_EVERY_S / p.frame_s)
    k, j, w = orbit_start(o, 0, sun_i)
    rows = [x.copy()]
    for f in range(round(HOLD_S / p.frame_s)):  # the loop's stages in its order, jets quiet
        _, kh, wh, _ = orbit_sky(o, k, w, f == 0, p.tracker)
        torque = np.zeros(3)
        orbit_torque(o, kh, wh, p.frame_s, x, p.plant.inertia_kg_m2, sun_b, torque)
        k, j, w = orbit_next(o, k, j, w, sun_i)
        advance_vehicle(p.plant, None, 0, p.frame_s, torque, None, None, None, None, None, x,
                        dtheta, frame)
        if frame[0] % every == 0:
            rows.append(x.copy())
    times = np.arange(len(rows)) * every * p.frame_s
    return times, np.array(rows), np.array(cfg.vehicle.inertia_kg_m2, dtype=float)


def orbit_start_m():
    """(r [m], v [m/s]) at t = 0 on the circular orbit, J2000."""
    a = RE_M + ALTITUDE_KM * 1000.0
    speed = math.sqrt(MU_M3_S2 / a)
    cn, sn = math.cos(math.radians(RAAN_DEG)), math.sin(math.radians(RAAN_DEG))
    ci, si = math.cos(math.radians(INCLINATION_DEG)), math.sin(math.radians(INCLINATION_DEG))
    cu, su = math.cos(math.radians(ARG_LATITUDE_DEG)), math.sin(math.radians(ARG_LATITUDE_DEG))
    r = a * np.array([cn * cu - sn * su * ci, sn * cu + cn * su * ci, su * si])
    v = speed * np.array([-cn * su - sn * cu * ci, -sn * su + cn * cu * ci, cu * si])
    return r, v


def fly_basilisk(times, inertia):
    """Basilisk's hold: states (n, 7) at ``times`` [s] (multiples of CHECK_EVERY_S)."""
    from Basilisk.simulation import GravityGradientEffector, spacecraft
    from Basilisk.utilities import SimulationBaseClass, macros, simIncludeGravBody

    sim = SimulationBaseClass.SimBaseClass()
    proc = sim.CreateNewProcess("proc")
    proc.addTask(sim.CreateNewTask("task", macros.sec2nano(FRAME_S)))
    sc = spacecraft.Spacecraft()
    sc.ModelTag = "vehicle"
    sc.hub.mHub = 500.0  # [kg] (no force depends on it)
    sc.hub.r_BcB_B = [[0.0], [0.0], [0.0]]
    sc.hub.IHubPntBc_B = inertia.tolist()
    x0 = start_state()
    if x0[0] < 0.0:
        x0[:4] = -x0[:4]
    sigma0 = x0[1:4] / (1.0 + x0[0])  # the MRP of the quaternion (Schaub and Junkins)
    sc.hub.sigma_BNInit = [[s] for s in sigma0]
    sc.hub.omega_BN_BInit = [[w] for w in x0[4:]]
    r0, v0 = orbit_start_m()
    sc.hub.r_CN_NInit = [[c] for c in r0]
    sc.hub.v_CN_NInit = [[c] for c in v0]
    grav = simIncludeGravBody.gravBodyFactory()
    earth = grav.createEarth()  # a point mass (no spherical harmonics)
    earth.isCentralBody = True
    earth.mu = MU_M3_S2
    grav.addBodiesTo(sc)
    gg = GravityGradientEffector.GravityGradientEffector()
    gg.ModelTag = "gravityGradient"
    gg.addPlanetName(earth.planetName)
    sc.addDynamicEffector(gg)
    sim.AddModelToTask("task", sc)
    sim.AddModelToTask("task", gg)
    rec = sc.scStateOutMsg.recorder(macros.sec2nano(CHECK_EVERY_S))
    sim.AddModelToTask("task", rec)
    sim.InitializeSimulation()
    sim.ConfigureStopTime(macros.sec2nano(float(times[-1])))
    t0 = time.perf_counter()
    sim.ExecuteSimulation()
    wall_s = time.perf_counter() - t0
    t = rec.times() * macros.NANO2SEC
    sigma = np.asarray(rec.sigma_BN)
    omega = np.asarray(rec.omega_BN_B)
    s2 = (sigma * sigma).sum(axis=1)
    q = np.column_stack([(1.0 - s2) / (1.0 + s2), 2.0 * sigma / (1.0 + s2)[:, None]])
    out = np.column_stack([q, omega])
    keep = [int(np.argmin(np.abs(t - ti))) for ti in times]
    assert np.allclose(t[keep], times, atol=1e-9), "the recorder missed a check time"
    return out[keep], wall_s


def misses(a, b):
    """Per row: rotation [arcsec] from ``b``'s attitude to ``a``'s, largest rate difference
    [deg/s]."""
    out = []
    for x, y in zip(a, b, strict=True):
        a0, av = y[0], -y[1:4]
        b0, bv = x[0], x[1:4]
        v = a0 * bv + b0 * av + np.cross(av, bv)
        s = a0 * b0 - av @ bv
        out.append((math.degrees(2.0 * math.atan2(np.linalg.norm(v), abs(s))) * 3600.0,
                    math.degrees(float(np.abs(x[4:] - y[4:]).max()))))
    return np.array(out)


def compare(times, flown, inertia):
    """Fly Basilisk and print its difference from allsky's ``flown`` at ``times``."""
    try:
        import Basilisk
    except ImportError as exc:
        print(f"Basilisk is not importable here ({exc}): run --read with a Python that has "
              "`pip install bsk`.")
        return 0
    from importlib.metadata import version

    ref, wall_s = fly_basilisk(times, inertia)
    d = misses(flown, ref)
    turn = misses(flown[-1:], flown[:1])[0, 0] / 3600.0
    print(f"Basilisk {getattr(Basilisk, '__version__', None) or version('bsk')}: "
          f"{times[-1]:.0f} s in {wall_s:.2f} s; the vehicle turned {turn:.2f} deg")
    print("  t [s]  attitude [arcsec]  rate [deg/s]")
    for t, (da, dw) in zip(times, d, strict=True):
        print(f"{t:7.0f}  {da:17.4f}  {dw:12.3e}")
    print(f"largest over the hold: {d[:, 0].max():.4f} arcsec, {d[:, 1].max():.3e} deg/s")
    return 0


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    g = ap.add_mutually_exclusive_group()
    g.add_argument("--write", metavar="NPZ", help="fly allsky's hold and write it here")
    g.add_argument("--read", metavar="NPZ", help="fly Basilisk's against the hold written here")
    a = ap.parse_args()
    if a.read:
        z = np.load(a.read)
        return compare(z["time_s"], z["state"], z["inertia_kg_m2"])
    times, flown, inertia = fly_allsky()
    if a.write:
        np.savez(a.write, time_s=times, state=flown, inertia_kg_m2=inertia)
        print(f"allsky's hold ({times[-1]:.0f} s, {len(times)} states) written to {a.write}")
        return 0
    return compare(times, flown, inertia)


if __name__ == "__main__":
    sys.exit(main())
