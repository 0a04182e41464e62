"""The roll braking after a star hand-over against the slit, at the feed's thrust.

A roll search (Modes 2 and 4, a re-acquisition) turns at the rate of
rate-command module 120, ``electronics.rate_command_deg_s``. Once the star
is within the hand-over threshold (``sequencer.handover_arcsec``) of the
tracker's null, the fine loop takes over and the roll jets brake at their
full couple: the vehicle stops ``w^2 / (2 a)`` further on, ``a = phi T /
I_xx`` with ``T`` the roll couple at full pressure and ``phi`` the feed's
thrust fraction. The star stays in the slit while that stop lies within
the hand-over threshold plus the narrow half-field
(``star_tracker.fov_narrow_half_deg``) past the null; beyond, it leaves the
slit on the far side and is lost. So the braking needs at least::

    phi_min = w^2 I_xx / (2 T (h + s))

A regulated feed gives ``phi = 1`` to the end. A blow-down feed gives
``phi = f + (1 - f) m / M`` (:func:`allsky.hardware.jets.thrust_fraction`):
the stop overshoots once the usable propellant left falls below
``m_min = M (phi_min - f) / (1 - f)``. (The model is the bang-bang stop
from the hand-over at the commanded rate; the flight's own stop adds the
fine loop's first frames, a fraction of a percent of it.)
"""

import math

from allsky import units


def handover_braking(cfg) -> dict:
    """The roll stop after a star hand-over and the thrust it needs (module notes).

    ``cfg`` is a validated scenario. Returns ``stop_deg`` [deg] (the stop
    past the hand-over at full thrust), ``room_deg`` [deg] (hand-over plus
    the narrow half-field), ``min_thrust_fraction`` (``phi_min``),
    ``final_thrust_fraction`` (what the feed gives with the usable
    propellant gone: 1 regulated, ``f`` blow-down) and ``min_propellant_kg``
    [kg] (the usable propellant below which the stop overshoots: 0 when it
    never does, the whole tank when it always does).
    """
    jets = cfg.jets
    rate = cfg.electronics.rate_command_deg_s * units.DEG2RAD
    torque = 2.0 * jets.thrust_n[0] * jets.moment_arm_m[0]
    inertia = float(cfg.vehicle.inertia_kg_m2[0][0])
    stop = rate * rate * inertia / (2.0 * torque)
    room = (cfg.sequencer.handover_arcsec * units.ARCSEC2RAD
            + cfg.star_tracker.fov_narrow_half_deg * units.DEG2RAD)
    phi_min = stop / room
    usable = float(jets.propellant_kg)
    if jets.supply == "blowdown":
        f = jets.tank_pressure_final_bar / jets.tank_pressure_initial_bar
    else:
        f = 1.0
    if phi_min <= f:
        m_min = 0.0
    elif phi_min >= 1.0:
        m_min = usable
    else:
        m_min = usable * (phi_min - f) / (1.0 - f)
    return {"stop_deg": math.degrees(stop), "room_deg": math.degrees(room),
            "min_thrust_fraction": phi_min, "final_thrust_fraction": f,
            "min_propellant_kg": m_min}


def handover_warning(cfg):
    """A sentence when the roll stop after a hand-over can overshoot the slit, or None.

    ``cfg`` is a validated scenario. Only a vehicle on its jets
    (``actuators.kind = "jets"``); the wheels brake without the tank.
    """
    if cfg.actuators.kind != "jets":
        return None
    b = handover_braking(cfg)
    if b["min_propellant_kg"] <= 0.0:
        return None
    usable = float(cfg.jets.propellant_kg)
    what = (f"the roll braking after a star hand-over stops {b['stop_deg']:.2f} deg past it at "
            f"full thrust, and the slit leaves {b['room_deg']:.2f} deg (sequencer.handover_arcsec"
            f" + star_tracker.fov_narrow_half_deg): it needs {b['min_thrust_fraction']:.3f} of "
            "the full thrust")
    if b["min_propellant_kg"] >= usable:
        return what + ", more than the jets give: every roll search overshoots the slit"
    return (what + f"; the blow-down tank gives less once under {b['min_propellant_kg']:.3f} kg "
            f"of usable propellant (p/p0 {b['min_thrust_fraction']:.3f}, after "
            f"{usable - b['min_propellant_kg']:.3f} of its {usable:g} kg are used): a star "
            "acquisition or re-acquisition from then on overshoots the slit and loses the star")


def flight_warning(cfg, propellant_left_kg):
    """:func:`handover_warning` with what a flight's tank ended with, or None.

    The summary's first warning and the replay's (at 0 s: it is the
    scenario's). ``cfg`` is the scenario flown, ``propellant_left_kg`` [kg]
    the usable propellant left at the end of the flight.
    """
    text = handover_warning(cfg)
    if text is None:
        return None
    left = float(propellant_left_kg)
    below = left < handover_braking(cfg)["min_propellant_kg"]
    return f"{text}; this flight's tank ended with {left:.3f} kg" + (", below it" if below else "")
