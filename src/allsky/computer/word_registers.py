"""Computed word register 23 and programmed word register 24.

Register 23 holds the drift-free calibration results written by CPU 22 at
the end of Modes 4 and 5; register 24 holds the prestored target roll and
yaw angles [arcsec]. Both are float64 arrays laid out as below (the
computer's arithmetic is modelled in floating point; quantisation happens
where the hardware has fixed words: counters, registers 25-27, DACs).
"""

import numpy as np

# Register 23 layout.
SF_ROLL = 0  #: roll scale factor [-] (true angle / counted angle)
SF_YAW = 1  #: yaw scale factor [-]
ROLL_INTO_PITCH = 2  #: [-] pitch counts per unit true roll angle
ROLL_INTO_YAW = 3  #: [-] yaw counts per unit true roll angle
YAW_INTO_PITCH = 4  #: [-] pitch counts per unit true yaw angle
YAW_INTO_ROLL = 5  #: [-] roll counts per unit true yaw angle
N_COMPUTED = 6

# Register 24 layout.
PROGRAMMED_ROLL = 0  #: [arcsec]
PROGRAMMED_YAW = 1  #: [arcsec]
N_PROGRAMMED = 2


def neutral_computed() -> np.ndarray:
    """Register 23 with no calibration: unit scale factors, zero cross-coupling."""
    w = np.zeros(N_COMPUTED)
    w[SF_ROLL] = 1.0
    w[SF_YAW] = 1.0
    return w


#: Register 23's words by name, as the journal and the replay name them -> slot.
WORD23 = {"sf_roll": SF_ROLL, "sf_yaw": SF_YAW, "roll_into_pitch": ROLL_INTO_PITCH,
          "roll_into_yaw": ROLL_INTO_YAW, "yaw_into_pitch": YAW_INTO_PITCH,
          "yaw_into_roll": YAW_INTO_ROLL}


def computed_as_dict(w) -> dict:
    """Register 23 as the scale-factor and cross-coupling parts of the summary.

    ``w`` is register 23, (N_COMPUTED,) as laid out above. The parts are the
    calibration summary's ``scale_factor`` and ``cross_coupling``.
    """
    return {
        "scale_factor": {"roll": float(w[SF_ROLL]), "yaw": float(w[SF_YAW])},
        "cross_coupling": {"roll_into_pitch": float(w[ROLL_INTO_PITCH]),
                           "roll_into_yaw": float(w[ROLL_INTO_YAW]),
                           "yaw_into_pitch": float(w[YAW_INTO_PITCH]),
                           "yaw_into_roll": float(w[YAW_INTO_ROLL])},
    }
