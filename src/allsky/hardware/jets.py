"""Cold-gas jets 39, 40, 41 (roll, pitch, yaw couples).

Each axis fires a couple: two jets of thrust ``F`` on opposite sides, each at
``r`` from the centre of mass, so the couple gives a pure torque ``2 F r``
[N m] and no net force. A firing couple uses propellant at ``2 F / (Isp g0)``
[kg/s]. With the tank empty the valves open on nothing.

The patent's drawing of the vehicle shows the same jets as 106 and 107, fed
from gas tank 108; the tank is the ``propellant_kg`` of the mission state.
"""

from typing import NamedTuple

import numpy as np

from allsky import units
from allsky.jit import njit


class JetParams(NamedTuple):
    """The three jet couples."""

    torque_n_m: np.ndarray  #: [N m] torque of each axis's couple, 2 F r
    flow_kg_s: np.ndarray  #: [kg/s] propellant flow of each firing couple


def make_params(thrust_n, moment_arm_m, isp_s) -> JetParams:
    """Build :class:`JetParams` from thrust [N], arm [m] and specific impulse [s].

    Each value is per jet.
    """
    f = np.asarray(thrust_n, dtype=float)
    r = np.asarray(moment_arm_m, dtype=float)
    return JetParams(2.0 * f * r, 2.0 * f / (float(isp_s) * units.G0_M_S2))


@njit
def jets(p, valve, dt_s, propellant_kg, torque_n_m):
    """Torque of the three jet couples for valve commands ``valve`` (-1/0/+1).

    The commands are held over one frame.

    ``propellant_kg`` (1 element) is decremented; returns False when the tank
    is empty (then no torque).
    """
    use = 0.0
    for i in range(3):
        use += abs(valve[i]) * p.flow_kg_s[i] * dt_s
    if propellant_kg[0] <= 0.0 or use > propellant_kg[0]:
        propellant_kg[0] = 0.0
        for i in range(3):
            torque_n_m[i] = 0.0
        return False
    propellant_kg[0] -= use
    for i in range(3):
        torque_n_m[i] = valve[i] * p.torque_n_m[i]
    return True
