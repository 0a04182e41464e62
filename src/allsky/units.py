"""Unit conversions, named as conversions (value_in_b = value_in_a * A2B).

SI inside the physics; the hardware's own units (arcsec, pulses, counts,
volts) inside the electronics. Convert here, at the boundary.
"""

import math

DEG2RAD = math.pi / 180.0
RAD2DEG = 180.0 / math.pi
ARCSEC2RAD = math.pi / (180.0 * 3600.0)
RAD2ARCSEC = 180.0 * 3600.0 / math.pi
DEG2ARCSEC = 3600.0
ARCSEC2DEG = 1.0 / 3600.0
HOUR_S = 3600.0
PPM2FRACTION = 1e-6  #: parts per million -> fraction
FRACTION2PPM = 1e6  #: fraction -> parts per million
URAD2RAD = 1e-6  #: microradians -> radians
# Standard gravity, for specific impulse [m/s^2] (CGPM 1901 conventional value).
G0_M_S2 = 9.80665
# 1 deg/h expressed in arcsec/s is exactly 1: (3600 arcsec) / (3600 s).
DEG_H2ARCSEC_S = 1.0
