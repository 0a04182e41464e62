"""The fault matrix: each fault kind started in each mode, and the fault-free run.

Each case flies the scenario with one more fault (:data:`MATRIX_FAULTS`:
the fault a row stands for) starting at the start of one mode, and records
its outcome: *complete*, with the final pointing error, the calibration
errors and the propellant, or *aborted*, with the reason (the mode, the
symptom and the fault). The cases are independent missions, flown on worker
processes (:func:`fault_matrix`). A case that raised instead of ending is
recorded with status ``"error"`` and the exception's text: the matrix counts
them (:func:`tally`), and a sound emulator has none.
"""


from allsky.config import scenario_from_dict
from allsky.config.faults import describe
from allsky.sequencer.master_sequencer import MODES
from allsky.sim.faults import symptom
from allsky.sim.mission import Mission
from allsky.sim.results import calibration_errors

#: The fault each row of the matrix flies (beyond its kind and its start).
#: Hardware failures are permanent; the optical ones last a minute or half
#: of one, longer than ``sequencer.sensor_loss_s``, as the glints and
#: dropouts of the Mariner and Voyager trackers did.
MATRIX_FAULTS = {
    "jet_stuck_open": {"axis": "roll", "sign": 1},
    "jet_failed_off": {"axis": "roll", "sign": 1},
    "gyro_stuck": {"axis": "roll"},
    "gyro_dead": {"axis": "roll"},
    "gyro_bias_step": {"axis": "yaw", "size_deg_h": 5.0},
    "gyro_scale_factor_step": {"axis": "roll", "size_ppm": 5000.0},
    "sun_sensor_blind": {"duration_s": 60.0},
    "tracker_dropout": {"duration_s": 60.0},
    "tracker_stray_light": {"offset_deg": 1.5, "duration_s": 30.0},
    "wrong_star": {"star": "Avior"},
    "counter_upset": {"register": "14", "bit": 12},
    # At the pitch jets' end of the vehicle (1.25 m along +z), the gas leaving along +x:
    # 5 g/s at 637 m/s thrusts 3.19 N, -3.98 N m about pitch (the pitch couple gives 1.25).
    "propellant_leak": {"rate_kg_s": 0.005, "vent_position_m": [0.0, 0.0, 1.25],
                        "vent_direction": [1.0, 0.0, 0.0]},
}
#: The modes a fault starts in, by default: the patent's.
MATRIX_MODES = MODES


def fault_entry(kind: str, mode: str) -> dict:
    """The ``[[faults]]`` table of the matrix's case: fault ``kind`` from ``mode``.

    ``kind`` is a key of :data:`MATRIX_FAULTS`, ``mode`` the name of the mode
    whose start the fault waits for.
    """
    return {"kind": kind, **MATRIX_FAULTS[kind], "start_mode": mode}


def fly_case(data: dict, kind, mode) -> dict:
    """Fly one case: scenario ``data`` plus fault ``kind`` from ``mode`` (None: none).

    Returns the case's row: kind, mode, fault (in words), status, outcome
    (:func:`allsky.sim.faults.symptom`), abort reason, pointing error
    [arcsec], calibration errors, propellant [kg], mission time [s], the
    planned and the locked star. Never raises for a mission that goes wrong:
    an exception is a row of status ``"error"``.
    """
    row = {"kind": kind, "mode": mode, "fault": None}
    try:
        case = dict(data)
        if kind is not None:
            entry = fault_entry(kind, mode)
            case["faults"] = [*data.get("faults", []), entry]
            row["fault"] = describe(entry)
        m = Mission(scenario_from_dict(case), telemetry=False)
        s = m.run()
    except Exception as e:  # noqa: BLE001 - the matrix counts these; it must not stop
        return {**row, "status": "error", "outcome": f"{type(e).__name__}: {e}",
                "abort_reason": f"{type(e).__name__}: {e}"}
    cal = calibration_errors(s["calibration"], s["truth"]) if s["calibration"] else None
    return {**row, "status": s["status"],
            "outcome": "complete" if s["status"] == "complete" else symptom(s["abort_reason"]),
            "abort_reason": s["abort_reason"],
            "pointing_error_arcsec": s["target"]["pointing_error_arcsec"],
            "calibration_errors": cal, "propellant_kg": s["propellant_kg"],
            "mission_time_s": s["mission_time_s"], "reference_star": s["reference_star"],
            "locked_star": s["locked_star"]}


def _fly(job):
    return fly_case(*job)


def died_case(job, reason) -> dict:
    """The row of a case whose worker died twice flying it (``worker_died``).

    ``job`` is the case's ``(scenario_dict, kind, mode)`` and ``reason`` why
    the worker died, in words.
    """
    _, kind, mode = job
    fault = describe(fault_entry(kind, mode)) if kind is not None else None
    return {"kind": kind, "mode": mode, "fault": fault, "status": "worker_died",
            "outcome": f"worker died: {reason}", "abort_reason": reason}


def fault_matrix(cfg, kinds=None, modes=None, workers=1, on_progress=None) -> dict:
    """Fly every fault kind from the start of every mode, and the fault-free reference.

    Parameters
    ----------
    cfg : Scenario
        The mission; its own faults, if any, stay in every case.
    kinds, modes : sequence of str, optional
        Rows and columns (default: every kind of :data:`MATRIX_FAULTS`, the
        modes of :data:`MATRIX_MODES`).
    workers : int
        Worker processes (1: in this process).
    on_progress : callable, optional
        ``on_progress(done, total)`` after each case.

    Returns
    -------
    dict
        ``kinds``, ``modes``, ``faults`` (the fault of each row),
        ``scenario_faults`` (the scenario's own faults, in words; they fly in
        every case), ``reference`` (the row without a further fault), ``cases`` (rows in kind-major
        order) and ``counts`` (:func:`tally`). Interrupted (Ctrl-C) with
        cases finished: those, with ``interrupted`` True.
    """
    from allsky.studies.montecarlo import ordered_rows

    kinds = list(kinds or MATRIX_FAULTS)
    modes = list(modes or MATRIX_MODES)
    data = cfg.as_dict()
    jobs = [(data, None, None)] + [(data, k, m) for k in kinds for m in modes]
    rows, interrupted = ordered_rows(_fly, jobs, workers, on_progress, died=died_case)
    out = {"kinds": kinds, "modes": modes,
           "faults": {k: describe({"kind": k, **MATRIX_FAULTS[k]}) for k in kinds},
           "scenario_faults": [describe(f) for f in cfg.faults],
           "reference": rows[0], "cases": rows[1:], "counts": tally(rows[1:])}
    if interrupted:
        out["interrupted"] = True
    return out


def tally(rows) -> dict:
    """Cases by status (complete, aborted, error, worker_died) and by outcome.

    ``rows`` are the matrix's case rows (:func:`fly_case`, :func:`died_case`).
    """
    by_status, by_outcome = {}, {}
    for r in rows:
        by_status[r["status"]] = by_status.get(r["status"], 0) + 1
        by_outcome[r["outcome"]] = by_outcome.get(r["outcome"], 0) + 1
    return {"status": by_status, "outcomes": by_outcome}
