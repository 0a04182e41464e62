"""What a mission stored against what the scenario set: the calibration errors.

One place for the "stored minus truth" arithmetic that the report, the
comparison, the Monte Carlo rows and the figures all show.
"""

from allsky.units import FRACTION2PPM, RAD2ARCSEC

AXES = ("roll", "pitch", "yaw")
#: Axes whose scale factor the patent's computer calibrates (register 23).
SCALE_FACTOR_AXES = ("roll", "yaw")
#: Cross-coupling factors of register 23.
CROSS_COUPLING_KEYS = ("roll_into_pitch", "roll_into_yaw", "yaw_into_pitch", "yaw_into_roll")


def calibration_errors(calibration: dict, truth: dict) -> dict:
    """Stored minus true calibration, in the units people read them in.

    Parameters
    ----------
    calibration, truth : dict
        The summary's ``calibration`` (drift DACs and register 23) and
        ``truth`` (:meth:`allsky.sim.mission.Mission.summary`).

    Returns
    -------
    dict
        ``drift_deg_h`` per axis [deg/h], ``scale_factor_ppm`` for roll and
        yaw [ppm], ``cross_coupling_arcsec`` per factor [arcsec].
    """
    return {
        "drift_deg_h": {a: calibration["drift_deg_h"][a] - truth["drift_deg_h"][a]
                        for a in AXES},
        "scale_factor_ppm": {
            a: FRACTION2PPM * (calibration["scale_factor"][a] - truth["scale_factor"][a])
            for a in SCALE_FACTOR_AXES},
        "cross_coupling_arcsec": {
            k: RAD2ARCSEC * (calibration["cross_coupling"][k] - truth["cross_coupling"][k])
            for k in CROSS_COUPLING_KEYS},
    }


def fly_calibrating(m, cal_modes, on_start=None, on_end=None):
    """Fly ``m`` to its end, measuring its calibration modes ``cal_modes`` on the way.

    The excursion is measured from the attitude at the start of the first
    calibration mode to the end of the last. ``on_start(m)`` runs as the
    first begins; ``on_end(m)`` after the last, and the flight stops there
    if it returns False.

    Returns
    -------
    tuple
        Calibration time [s], its propellant [kg] and each calibration
        mode's duration [s] by name.
    """
    t_cal, prop, durations = 0.0, 0.0, {}
    while not m.finished:
        name = m.plan[m.next_mode]
        if name == cal_modes[0]:
            m.state.excursion_ref_q[:] = m.state.x[0:4]
            if on_start is not None:
                on_start(m)
        p0 = m.state.propellant_kg[0]
        rec = m.run_mode()
        if name in cal_modes:
            t_cal += rec.end_s - rec.start_s
            durations[name] = rec.end_s - rec.start_s
            prop += p0 - m.state.propellant_kg[0]
        if name == cal_modes[-1]:
            m.state.excursion_ref_q[:] = 0.0
            if on_end is not None and on_end(m) is False:
                break
    return t_cal, prop, durations
