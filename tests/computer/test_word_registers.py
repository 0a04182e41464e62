"""Computed word register 23 and programmed word register 24: layout and neutral value.

Truth: register 23 holds six calibration results (roll and yaw scale
factors, four cross-coupling factors; SPEC sec. 3), register 24 the
programmed roll and yaw angles; "no calibration" is a unit scale factor
and zero coupling. The summary keys match :func:`allsky.hardware.gyro.perfect_calibration`.
"""

import numpy as np

from allsky.computer import word_registers as wr
from allsky.hardware import gyro

COMPUTED = ("SF_ROLL", "SF_YAW", "ROLL_INTO_PITCH", "ROLL_INTO_YAW", "YAW_INTO_PITCH",
            "YAW_INTO_ROLL")
PROGRAMMED = ("PROGRAMMED_ROLL", "PROGRAMMED_YAW")


def test_register_23_layout_is_a_permutation():
    idx = sorted(getattr(wr, n) for n in COMPUTED)
    assert idx == list(range(wr.N_COMPUTED)) and wr.N_COMPUTED == 6


def test_register_24_layout_is_a_permutation():
    idx = sorted(getattr(wr, n) for n in PROGRAMMED)
    assert idx == list(range(wr.N_PROGRAMMED)) and wr.N_PROGRAMMED == 2


def test_neutral_register_is_unit_scale_factor_zero_coupling():
    w = wr.neutral_computed()
    assert w.shape == (wr.N_COMPUTED,) and w.dtype == np.float64
    assert w[wr.SF_ROLL] == w[wr.SF_YAW] == 1.0
    assert [w[getattr(wr, n)] for n in COMPUTED[2:]] == [0.0] * 4
    w[0] = 5.0
    assert wr.neutral_computed()[0] == 1.0  # a fresh array each call


def test_computed_as_dict_reads_each_slot():
    w = np.arange(10.0, 10.0 + wr.N_COMPUTED)  # distinct values: any mix-up shows
    d = wr.computed_as_dict(w)
    assert d == {
        "scale_factor": {"roll": w[wr.SF_ROLL], "yaw": w[wr.SF_YAW]},
        "cross_coupling": {"roll_into_pitch": w[wr.ROLL_INTO_PITCH],
                           "roll_into_yaw": w[wr.ROLL_INTO_YAW],
                           "yaw_into_pitch": w[wr.YAW_INTO_PITCH],
                           "yaw_into_roll": w[wr.YAW_INTO_ROLL]},
    }
    assert all(type(v) is float for part in d.values() for v in part.values())


def test_keys_match_the_perfect_calibration_summary():
    p = gyro.make_params([0.0] * 3, [0.0] * 3, np.zeros((3, 3)), 0.0, 0.0, 10.0)
    truth = gyro.perfect_calibration(p)
    d = wr.computed_as_dict(wr.neutral_computed())
    for part in d:
        assert d[part].keys() == truth[part].keys()
    # A perfect triad needs no correction: its perfect values are the neutral register.
    assert d == {k: truth[k] for k in d}
