"""When to eject: the mission flown from each ejection time over one orbit.

:func:`ejection_window` moves the ejection on by ``every_s`` at a time over
one orbital period: ``mission.date_utc`` moves on, and with it the vehicle
along its orbit (a circular orbit's argument of latitude and node move on at
their rates, :func:`allsky.vehicle.orbit.circular_rates`; a two-line element
set is propagated to the new date by SGP4). Each candidate is a whole
mission; the row says how it ended, the sunlit margin at its end (the time
from the end of Mode 6-2, or the hold, to the next orbit sunset), whether
the Earth hid the planned reference star or the target while it flew, how
long sunlit Earth blinded the star tracker (and whether it took the star the
loop was closed on), and the propellant used.
"""

from __future__ import annotations

import math
from datetime import timedelta

from allsky.vehicle import orbit

#: [s] the default spacing of candidate ejection times
EVERY_S = 60.0


def period_s(cfg) -> float:
    """[s] the period of ``cfg``'s orbit: its argument of latitude's, or 2 pi / n."""
    o = cfg.orbit
    if o.kind == "circular":
        _, _, du = orbit.circular_rates(o.altitude_km, o.inclination_deg, o.j2)
        return 2.0 * math.pi / du
    sat = orbit.parse_tle(o.tle_line1, o.tle_line2)
    return 2.0 * math.pi / sat.no_kozai * 60.0  # no_kozai in rad/min


def candidate(data: dict, offset_s: float) -> dict:
    """The scenario ``data`` (a plain dict) ejected ``offset_s`` [s] later."""
    from allsky.config.scenario import scenario_from_dict

    cfg = scenario_from_dict(data)
    o = cfg.orbit
    case = {k: dict(v) if isinstance(v, dict) else v for k, v in data.items()}
    case["mission"]["date_utc"] = cfg.mission.date_utc + timedelta(seconds=offset_s)
    if o.kind == "circular":
        _, draan, du = orbit.circular_rates(o.altitude_km, o.inclination_deg, o.j2)
        case["orbit"]["raan_deg"] = (o.raan_deg + math.degrees(draan * offset_s)) % 360.0
        case["orbit"]["arg_latitude_deg"] = (o.arg_latitude_deg
                                             + math.degrees(du * offset_s)) % 360.0
    return case


def fly_candidate(data: dict, offset_s: float) -> dict:
    """One row of the window: the mission of ``data`` ejected ``offset_s`` [s] later."""
    from allsky.config.scenario import scenario_from_dict
    from allsky.sim.mission import Mission, target_name, target_specs

    row = {"offset_s": float(offset_s)}
    try:
        case = candidate(data, offset_s)
        cfg = scenario_from_dict(case)
        m = Mission(cfg, telemetry=False)
        s = m.run()
    except Exception as e:  # noqa: BLE001 - a row of the table, never the end of it
        return {**row, "status": "error", "outcome": f"{type(e).__name__}: {e}"}
    orb = s.get("orbit") or {}
    occulted = set(orb.get("occulted", ()))
    ref = cfg.star_tracker.reference_star
    return {**row, "date_utc": cfg.mission.date_utc.isoformat().replace("+00:00", "Z"),
            "arg_latitude_deg": (float(cfg.orbit.arg_latitude_deg)
                                 if cfg.orbit.kind == "circular" else None),
            "status": s["status"],
            "outcome": "complete" if s["status"] == "complete" else s["abort_reason"],
            "sunlit_margin_s": orb.get("sunlit_margin_s"),
            "eclipsed_s": orb.get("eclipsed_s"),
            "earth_glare_s": orb.get("earth_glare_s"),
            "glare_took_star": orb.get("glare_took_star"),
            "reference_occulted": ref in occulted,
            "target_occulted": "target" in occulted,
            "target": target_name(target_specs(cfg)[0]),
            "pointing_error_arcsec": s["target"]["pointing_error_arcsec"],
            "propellant_kg": s["propellant_kg"],
            "mission_time_s": s["mission_time_s"]}


def _fly(job):
    return fly_candidate(*job)


def _died(job, reason) -> dict:
    return {"offset_s": float(job[1]), "status": "worker_died",
            "outcome": f"worker died: {reason}"}


def ejection_window(cfg, every_s=EVERY_S, workers=1, on_progress=None) -> dict:
    """Fly ``cfg`` from each ejection time ``k * every_s`` over one orbital period.

    ``every_s`` [s] apart, on ``workers`` processes; ``on_progress(done, total)``
    (``on_progress``) after each.

    Returns ``{"period_s", "every_s", "rows"}`` (rows in time order, each
    :func:`fly_candidate`'s), with ``interrupted`` True after a Ctrl-C.

    Raises
    ------
    ValueError
        If the scenario flies no orbit (``orbit.kind = "none"``).
    """
    from allsky.studies.montecarlo import ordered_rows

    if cfg.orbit.kind == "none":
        raise ValueError('the scenario flies no orbit (orbit.kind = "none"): give --orbit or '
                         "a scenario in orbit such as shuttle-free-flyer")
    period = period_s(cfg)
    n = max(1, math.ceil(period / every_s - 1e-9))
    data = cfg.as_dict()
    jobs = [(data, k * every_s) for k in range(n)]
    rows, interrupted = ordered_rows(_fly, jobs, workers, on_progress, died=_died)
    out = {"period_s": period, "every_s": float(every_s), "rows": rows}
    if interrupted:
        out["interrupted"] = True
    return out
