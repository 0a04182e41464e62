"""Independent sky geometry for the tests: where a star lies about the Sun line."""

import math

import numpy as np


def sun_azimuth_deg(sun, star, reference):
    """Azimuth [deg] of ``star`` about the Sun line from ``reference``, right-handed.

    ``sun``, ``star`` and ``reference`` are inertial unit vectors; the result,
    in (-180, 180], is the roll about the Sun line that takes the reference
    star's place on the star tracker's slit to the other star's.
    """
    def across(x):
        v = x - (x @ sun) * sun
        return v / np.linalg.norm(v)
    a, b = across(reference), across(star)
    return math.degrees(math.atan2(np.cross(a, b) @ sun, a @ b))
