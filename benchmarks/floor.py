"""The compiled floor: a bare loop of the mission's size, and the mission's ratio to it.

The floor kernel flies what any attitude simulation must, and nothing else:
a rigid body with the default vehicle's full inertia tensor, the same RK4
step at the same 100 Hz frame (:func:`allsky.vehicle.plant.rk4_step`, the
mission's own integrator), a PD law on the attitude error and three on/off
jet couples with a dead band, for as many frames as the default mission
flies (131,313). The default mission adds the patent's electronics (three
gyros with their noise and random walk, the sun sensor and the slit
tracker, three converters and counters, CPU 22, three PWPF modulators, the
watch, the journal). Their ratio is what the electronics cost;
``benchmarks/loop_profile.py`` says stage by stage where it goes
(docs/design.md, "The loop near its floor").

Run from the repository root::

    python benchmarks/floor.py [RUNS]      # default 15 runs of each, in turns

Each figure is the minimum CPU time (``time.process_time``) over RUNS, the
two taken in turns in one process so that both see the same machine; no
telemetry is recorded by either. Prints the floor [ms, ns/frame], the
mission [ms, ns/frame] and their ratio.
"""

import sys
import time

import numpy as np

from allsky.config.scenario import load_scenario
from allsky.jit import njit_alloc
from allsky.sim.mission import Mission, plant_params
from allsky.vehicle.plant import rk4_step

#: Frames of the default mission (1313.13 s at 0.01 s).
FRAMES = 131_313


@njit_alloc
def floor_kernel(p, x0, dt_s, frames, kp, kd, dead_band, couple_n_m):
    """Fly ``frames`` frames of rigid body, PD law and on/off jets; the final state.

    ``kp`` [1/s^2] and ``kd`` [1/s] scale the attitude error (twice the
    error quaternion's vector part) and the body rate into a command; a jet
    couple fires (+-``couple_n_m`` [N m] per axis) while the command is
    beyond ``dead_band``. Returns the state (7,) and the jet firings counted.
    """
    x = x0.copy()
    torque = np.zeros(3)
    dtheta = np.zeros(3)
    fired = 0
    for _ in range(frames):
        for a in range(3):
            cmd = -kp * 2.0 * x[1 + a] - kd * x[4 + a]
            if cmd > dead_band:
                torque[a] = couple_n_m[a]
                fired += 1
            elif cmd < -dead_band:
                torque[a] = -couple_n_m[a]
                fired += 1
            else:
                torque[a] = 0.0
        rk4_step(p, x, torque, dt_s, dtheta)
    return x, fired


def floor_args(cfg):
    """The floor kernel's arguments for the scenario's vehicle, jets and frame."""
    p = plant_params(cfg)
    x0 = np.array([0.9999, 0.01, -0.005, 0.008, 1e-3, -2e-3, 5e-4])
    x0[:4] /= np.linalg.norm(x0[:4])
    couple = 2.0 * np.asarray(cfg.jets.thrust_n) * np.asarray(cfg.jets.moment_arm_m)
    return p, x0, float(cfg.mission.frame_s), FRAMES, 0.04, 0.4, 1e-4, couple


def floor_cpu_s(args) -> float:
    """CPU seconds of one floor run."""
    t0 = time.process_time()
    floor_kernel(*args)
    return time.process_time() - t0


def mission_cpu_s(cfg) -> float:
    """CPU seconds of one default mission, without telemetry."""
    m = Mission(cfg, telemetry=False)
    t0 = time.process_time()
    m.run()
    return time.process_time() - t0


def measure(runs=15):
    """Minimum CPU time of the floor and of the mission [s], in turns, and the frames flown."""
    cfg = load_scenario()
    args = floor_args(cfg)
    for _ in range(2):  # compile or load both first
        floor_cpu_s(args)
        mission_cpu_s(cfg)
    floor, mission = [], []
    for _ in range(runs):
        floor.append(floor_cpu_s(args))
        mission.append(mission_cpu_s(cfg))
    m = Mission(cfg, telemetry=False)
    m.run()
    return min(floor), min(mission), int(m.state.frame[0])


def main():
    runs = int(sys.argv[1]) if len(sys.argv) > 1 else 15
    floor_s, mission_s, frames = measure(runs)
    print(f"floor:   {floor_s * 1e3:6.2f} ms, {floor_s / FRAMES * 1e9:5.1f} ns/frame "
          f"({FRAMES} frames)")
    print(f"mission: {mission_s * 1e3:6.2f} ms, {mission_s / frames * 1e9:5.1f} ns/frame "
          f"({frames} frames)")
    print(f"ratio:   {mission_s / floor_s * FRAMES / frames:.2f} (per frame), "
          f"minimum of {runs} runs each, in turns")


if __name__ == "__main__":
    main()
