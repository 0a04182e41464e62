"""Cold-gas jets 39, 40, 41 (roll, pitch, yaw couples), fed regulated or blow-down.

Each axis fires a couple: two jets of thrust ``F`` on opposite sides, each at
``r`` from the centre of mass, so the couple gives a pure torque ``2 F r``
[N m] and no net force. A firing couple uses propellant at ``2 F / (Isp g0)``
[kg/s]. With the tank empty the valves open on nothing.

The patent's drawing of the vehicle shows the same jets as 106 and 107, fed
from gas tank 108; the tank is the ``propellant_kg`` of the mission state.
How the tank feeds them (``jets.supply``) the patent does not say:

* ``"regulated"``: a pressure regulator holds the jets' feed pressure, so
  thrust and flow are constant until the tank is empty;
* ``"blowdown"``: no regulator; the jets see the tank pressure, and thrust
  and flow (at constant specific impulse) are proportional to it. The gas
  is an ideal gas in a tank of fixed volume held at constant temperature
  (isothermal: the tank's walls keep the gas warm over the minutes a
  mission takes), so the pressure is proportional to the gas left. It falls
  from ``tank_pressure_initial_bar`` with a full tank to
  ``tank_pressure_final_bar`` once the usable propellant is gone; the gas
  still in the tank then is the residual, never expelled::

      p / p0 = f + (1 - f) m / M,   f = p_final / p0

  with ``m`` the usable propellant left and ``M`` the usable propellant at
  ejection. ``thrust_n`` is the thrust at ``p0``.
"""

from typing import NamedTuple

import numpy as np

from allsky import units
from allsky.jit import njit

#: ``jets.supply`` -> code (:attr:`JetParams.supply`).
SUPPLIES = {"regulated": 0, "blowdown": 1}
REGULATED = SUPPLIES["regulated"]
BLOWDOWN = SUPPLIES["blowdown"]


class JetParams(NamedTuple):
    """The three jet couples and their feed."""

    torque_n_m: np.ndarray  #: [N m] torque of each axis's couple, 2 F r, at full pressure
    flow_kg_s: np.ndarray  #: [kg/s] propellant flow of each firing couple, at full pressure
    supply: int = REGULATED  #: REGULATED or BLOWDOWN
    #: [-] blow-down: feed pressure with the usable propellant gone, over the initial
    final_pressure_fraction: float = 1.0
    usable_kg: float = 1.0  #: [kg] blow-down: the usable propellant at ejection


def make_params(thrust_n, moment_arm_m, isp_s, supply="regulated", pressure_initial_bar=1.0,
                pressure_final_bar=1.0, propellant_kg=1.0) -> JetParams:
    """Build :class:`JetParams` from thrust [N], arm [m] and specific impulse [s].

    ``thrust_n`` and ``moment_arm_m`` are per jet (one number per axis);
    ``isp_s`` [s] is the specific impulse.
    ``supply`` is "regulated" or "blowdown"; for the latter the tank's
    pressures with a full tank and with the usable propellant gone,
    ``pressure_initial_bar`` and ``pressure_final_bar`` [bar] (only their
    ratio matters), and the usable propellant ``propellant_kg`` [kg].
    """
    f = np.asarray(thrust_n, dtype=float)
    r = np.asarray(moment_arm_m, dtype=float)
    return JetParams(2.0 * f * r, 2.0 * f / (float(isp_s) * units.G0_M_S2), SUPPLIES[supply],
                     float(pressure_final_bar) / float(pressure_initial_bar),
                     float(propellant_kg))


@njit
def thrust_fraction(p, propellant_kg):
    """Thrust (and flow) over their full-pressure values with ``propellant_kg`` left.

    1 on a regulated feed; on a blow-down feed the tank pressure over the
    initial, ``f + (1 - f) m / M`` (module docstring). ``p`` is the jets'
    :class:`JetParams`.
    """
    if p.supply == BLOWDOWN:
        f = p.final_pressure_fraction
        return f + (1.0 - f) * max(propellant_kg, 0.0) / p.usable_kg
    return 1.0


@njit
def jets(p, valve, dt_s, propellant_kg, torque_n_m):
    """Torque of the three jet couples for valve commands ``valve`` (-1/0/+1).

    The commands are held over one frame, at the thrust the feed gives at
    the frame's start (:func:`thrust_fraction`).

    ``propellant_kg`` (1 element) is decremented; returns False when the tank
    is empty (then no torque).

    Parameters
    ----------
    p : JetParams
        The couples and their feed.
    dt_s : float
        [s] frame length, over which the valves are held.
    torque_n_m : array of 3 float
        [N m] written: torque about body x, y, z (roll, pitch, yaw).
    """
    scale = thrust_fraction(p, propellant_kg[0])
    use = 0.0
    for i in range(3):
        use += abs(valve[i]) * p.flow_kg_s[i] * dt_s
    use *= scale
    if propellant_kg[0] <= 0.0 or use > propellant_kg[0]:
        propellant_kg[0] = 0.0
        for i in range(3):
            torque_n_m[i] = 0.0
        return False
    propellant_kg[0] -= use
    for i in range(3):
        torque_n_m[i] = valve[i] * p.torque_n_m[i] * scale
    return True
