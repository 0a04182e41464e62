"""Reference timing of Basilisk on a scenario like allsky's, side by side with mission_benchmark.py.

What it is for: a yardstick. ``benchmarks/mission_benchmark.py`` times one
allsky mission (a rigid vehicle, jet couples, a 100 Hz frame); this script
times the Basilisk spacecraft simulation framework (PyPI ``bsk``, 2.x) on a
comparable problem, so that allsky's figures can be read against a widely used
C++ simulator. It is not part of allsky and is never imported by it.

The scenario, 1500 s simulated in one 0.01 s task (100 Hz, as allsky's frame):

* one rigid hub (``spacecraft``), 500 kg, inertia diag(100, 650, 680) kg m^2,
  no gravity or other environment (inertial pointing, as allsky's attitude
  problem), Basilisk's default RK4 integrator;
* a ``thrusterDynamicEffector`` with 12 on/off jets in six pure couples:
  +-roll, +-pitch, +-yaw. allsky's couples fire either way (valve -1/0/+1),
  and a Basilisk thruster pushes one way only, so each allsky couple is two
  Basilisk couples here. Per-jet thrust and moment arm are allsky's defaults
  (roll 0.25 N at 0.5 m, pitch and yaw 0.5 N at 1.25 m, so couple torques
  0.25, 1.25, 1.25 N m), minimum on time 0.01 s, Isp 65 s;
* flight software: ``simpleNav`` (noise-free) -> ``inertial3D`` (hold the
  inertial frame) -> ``attTrackingError`` -> ``mrpFeedback`` (PD, no integral)
  -> ``thrForceMapping`` -> ``thrFiringRemainder`` (minimum fire time 0.01 s,
  the unfired remainder carried over: a pulse-frequency modulator) -> the jets;
* initial attitude error of about 113 degrees and tip-off rates of
  (0.6, -0.4, 0.8) deg/s; only the final state is read, and a 1 Hz recorder
  of the tracking error gives the settling time.

Each repetition builds a fresh simulation (timed as build + init), then times
``ExecuteSimulation()`` alone with ``time.perf_counter`` (and its CPU time with
``time.process_time``, which a busy machine disturbs less). Printed: the Basilisk
version, the build/init time, each run's wall time, the median over the
repetitions, simulated seconds per wall second, and the end state as a check
that the controller did its job.

Run: ``python benchmarks/basilisk_reference.py [--repeats 5] [--duration 1500]``
with a Python that has ``pip install bsk`` (a separate virtual environment is
best: bsk pins its own numpy and matplotlib). Without Basilisk it says so and
exits 0.
"""

import argparse
import statistics
import sys
import time

try:
    import Basilisk
except ImportError as exc:  # not an error: this is an optional yardstick
    print(f"Basilisk is not importable here ({exc}).")
    print("This reference benchmark needs Basilisk: run it with a Python that has "
          "`pip install bsk` (e.g. python3 -m venv /tmp/bsk-venv && "
          "/tmp/bsk-venv/bin/pip install bsk).")
    sys.exit(0)

t_import = time.perf_counter()
import numpy as np  # bsk depends on numpy
from Basilisk.architecture import messaging
from Basilisk.fswAlgorithms import (
    attTrackingError,
    inertial3D,
    mrpFeedback,
    thrFiringRemainder,
    thrForceMapping,
)
from Basilisk.simulation import simpleNav, spacecraft, thrusterDynamicEffector
from Basilisk.utilities import SimulationBaseClass, macros, simIncludeThruster

IMPORT_S = time.perf_counter() - t_import

FRAME_S = 0.01  # one task for dynamics and flight software, 100 Hz
MASS_KG = 500.0
INERTIA_KG_M2 = [100.0, 0.0, 0.0, 0.0, 650.0, 0.0, 0.0, 0.0, 680.0]
# Per axis [roll, pitch, yaw]: per-jet thrust [N] and moment arm [m] (allsky's defaults).
THRUST_N = (0.25, 0.5, 0.5)
ARM_M = (0.5, 1.25, 1.25)
MIN_ON_TIME_S = 0.01
ISP_S = 65.0
SIGMA_BN0 = [0.3, -0.2, 0.4]  # MRP, about 113 deg from the target attitude
OMEGA_BN0_DEG_S = [0.6, -0.4, 0.8]  # tip-off rates


def jet_layout():
    """(position, direction) of the 12 jets: a pure couple for each of +-roll, +-pitch, +-yaw."""
    jets = []
    for axis in range(3):
        arm_axis = (axis + 1) % 3  # roll: arm along y, thrust along z; pitch: z, x; yaw: x, y
        thrust_axis = (axis + 2) % 3
        for sign in (+1.0, -1.0):  # torque sign about ``axis``
            for side in (+1.0, -1.0):  # the two jets of the couple
                r = [0.0, 0.0, 0.0]
                d = [0.0, 0.0, 0.0]
                r[arm_axis] = side * ARM_M[axis]
                d[thrust_axis] = side * sign  # e_arm x e_thrust = +e_axis
                jets.append((axis, r, d))
    return jets


def build(duration_s):
    """Build and initialise the scenario; returns the sim and the objects read after the run."""
    sim = SimulationBaseClass.SimBaseClass()
    proc = sim.CreateNewProcess("proc")
    task = "task"
    proc.addTask(sim.CreateNewTask(task, macros.sec2nano(FRAME_S)))

    # Flight software first in the task, then the actuators and the dynamics,
    # so each frame the jets act on the command computed from the last state.
    nav = simpleNav.SimpleNav()
    nav.ModelTag = "nav"
    guid = inertial3D.inertial3D()
    guid.ModelTag = "inertial3D"
    guid.sigma_R0N = [0.0, 0.0, 0.0]
    err = attTrackingError.attTrackingError()
    err.ModelTag = "attError"
    ctrl = mrpFeedback.mrpFeedback()
    ctrl.ModelTag = "mrpFeedback"
    ctrl.K = 4.0  # [N m] per unit MRP; small-angle natural frequency roll 0.1, pitch/yaw 0.04 rad/s
    ctrl.P = 40.0  # [N m s]
    ctrl.Ki = -1.0  # negative: no integral term
    mapping = thrForceMapping.thrForceMapping()
    mapping.ModelTag = "thrForceMapping"
    mapping.controlAxes_B = [1, 0, 0, 0, 1, 0, 0, 0, 1]
    mapping.thrForceSign = +1  # on-pulsing attitude jets
    # At a 0.01 s control period equal to the minimum on time there is no room
    # for pulse-width modulation (and thrFiringSchmitt's on-level becomes a wide
    # dead zone); the remainder logic carries the unfired fraction of each frame
    # to the next, a sigma-delta pulse-frequency modulator, as allsky's PWPF.
    firing = thrFiringRemainder.thrFiringRemainder()
    firing.ModelTag = "thrFiringRemainder"
    firing.thrMinFireTime = MIN_ON_TIME_S

    thr = thrusterDynamicEffector.ThrusterDynamicEffector()
    sc = spacecraft.Spacecraft()
    sc.ModelTag = "vehicle"
    sc.hub.mHub = MASS_KG
    sc.hub.r_BcB_B = [[0.0], [0.0], [0.0]]
    sc.hub.IHubPntBc_B = [INERTIA_KG_M2[0:3], INERTIA_KG_M2[3:6], INERTIA_KG_M2[6:9]]
    sc.hub.sigma_BNInit = [[s] for s in SIGMA_BN0]
    sc.hub.omega_BN_BInit = [[w * macros.D2R] for w in OMEGA_BN0_DEG_S]

    factory = simIncludeThruster.thrusterFactory()
    for axis, r, d in jet_layout():
        factory.create("MOOG_Monarc_1", r, d, MaxThrust=THRUST_N[axis],
                       steadyIsp=ISP_S, MinOnTime=MIN_ON_TIME_S, useMinPulseTime=True)
    factory.addToSpacecraft("jets", thr, sc)

    for m in (nav, guid, err, ctrl, mapping, firing, thr, sc):
        sim.AddModelToTask(task, m)

    veh_msg = messaging.VehicleConfigMsg().write(
        messaging.VehicleConfigMsgPayload(ISCPntB_B=INERTIA_KG_M2, CoM_B=[0.0, 0.0, 0.0]))
    thr_conf_msg = factory.getConfigMessage()

    nav.scStateInMsg.subscribeTo(sc.scStateOutMsg)
    err.attNavInMsg.subscribeTo(nav.attOutMsg)
    err.attRefInMsg.subscribeTo(guid.attRefOutMsg)
    ctrl.guidInMsg.subscribeTo(err.attGuidOutMsg)
    ctrl.vehConfigInMsg.subscribeTo(veh_msg)
    mapping.cmdTorqueInMsg.subscribeTo(ctrl.cmdTorqueOutMsg)
    mapping.thrConfigInMsg.subscribeTo(thr_conf_msg)
    mapping.vehConfigInMsg.subscribeTo(veh_msg)
    firing.thrConfInMsg.subscribeTo(thr_conf_msg)
    firing.thrForceInMsg.subscribeTo(mapping.thrForceCmdOutMsg)
    thr.cmdsInMsg.subscribeTo(firing.onTimeOutMsg)

    rec = err.attGuidOutMsg.recorder(macros.sec2nano(1.0))  # 1 Hz, modest
    sim.AddModelToTask(task, rec)

    sim.InitializeSimulation()
    sim.ConfigureStopTime(macros.sec2nano(duration_s))
    # Keep the message objects alive as long as the sim (Basilisk holds raw pointers).
    return sim, {"sc": sc, "rec": rec, "keep": (veh_msg, thr_conf_msg, factory, thr)}


def settle_time_s(rec, tol_deg=0.1):
    """First recorded time after which the pointing error stays below ``tol_deg``."""
    t = rec.times() * macros.NANO2SEC
    err_deg = 4.0 * np.degrees(np.arctan(np.linalg.norm(rec.sigma_BR, axis=1)))
    above = np.nonzero(err_deg > tol_deg)[0]
    if len(above) == 0:
        return 0.0
    if above[-1] == len(t) - 1:
        return float("nan")
    return float(t[above[-1] + 1])


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--duration", type=float, default=1500.0, help="simulated seconds")
    a = ap.parse_args()

    version = getattr(Basilisk, "__version__", None)
    if version is None:
        from importlib.metadata import version as _v
        version = _v("bsk")
    print(f"Basilisk {version} (Python {sys.version.split()[0]}, numpy {np.__version__})")
    print(f"scenario: rigid hub {MASS_KG:.0f} kg, I = diag(100, 650, 680) kg m^2, "
          f"12 jets (6 couples), {a.duration:.0f} s at {1 / FRAME_S:.0f} Hz "
          f"= {round(a.duration / FRAME_S)} frames")
    print(f"import of the Basilisk modules used: {IMPORT_S:.3f} s")

    builds, runs, cpus = [], [], []
    for i in range(a.repeats):
        t0 = time.perf_counter()
        sim, h = build(a.duration)
        t1 = time.perf_counter()
        c1 = time.process_time()
        sim.ExecuteSimulation()
        c2 = time.process_time()
        t2 = time.perf_counter()
        builds.append(t1 - t0)
        runs.append(t2 - t1)
        cpus.append(c2 - c1)
        print(f"  run {i + 1}: build + init {t1 - t0:.3f} s, ExecuteSimulation {t2 - t1:.3f} s "
              f"wall ({c2 - c1:.3f} s CPU)")

    med = statistics.median(runs)
    print(f"build + init: first {builds[0]:.3f} s, median {statistics.median(builds):.3f} s")
    print(f"ExecuteSimulation ({a.duration:.0f} s simulated): median {med:.3f} s over "
          f"{a.repeats} (min {min(runs):.3f}, max {max(runs):.3f})")
    # Wall above CPU means the process waited for a core: the machine was busy.
    print(f"  its CPU time (process_time): median {statistics.median(cpus):.3f} s")
    print(f"simulated seconds per wall second: {a.duration / med:.0f} "
          f"({a.duration / FRAME_S / med:,.0f} frames/s)")

    # A check that the last run did what it should (not part of the timing).
    state = h["sc"].scStateOutMsg.read()
    sigma = np.asarray(state.sigma_BN)
    omega = np.degrees(np.asarray(state.omega_BN_B))
    err_deg = 4.0 * np.degrees(np.arctan(np.linalg.norm(sigma)))
    print(f"end state: pointing error {err_deg:.3f} deg, body rates "
          f"[{omega[0]:+.4f}, {omega[1]:+.4f}, {omega[2]:+.4f}] deg/s, "
          f"settled (< 0.1 deg) at {settle_time_s(h['rec']):.0f} s")


if __name__ == "__main__":
    main()
