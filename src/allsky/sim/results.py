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
