"""Summing amplifiers 4, 5, 6 against their two output nodes (SPEC sec. 3).

Truth::

    VFC node  = gyro - drift * [S1/S2/S3 closed]
    line 130/131 = VFC node - command * [S16/S17 closed]

The rate command is summed after the converter's node, so the counter
integrates the vehicle's rotation and only the loop sees the rate error
(docs/assumptions.md).
"""

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from allsky.hardware.summing_amp import summing_amp

CMD_ARCSEC_S = 5400.0  # 1.5 deg/s, the patent's rate command


def test_drift_is_subtracted_only_through_its_closed_switch():
    assert summing_amp(100.0, 2.5, 0, 0.0, 0) == (100.0, 100.0)
    assert summing_amp(100.0, 2.5, 1, 0.0, 0) == (97.5, 97.5)


def test_vfc_node_excludes_the_rate_command_and_the_line_includes_it():
    assert summing_amp(100.0, 0.0, 0, CMD_ARCSEC_S, 0) == (100.0, 100.0)
    assert summing_amp(100.0, 0.0, 0, CMD_ARCSEC_S, 1) == (100.0, 100.0 - CMD_ARCSEC_S)


def test_turning_at_the_commanded_rate_nulls_the_line_but_not_the_count():
    """Gyro = 1.5 deg/s + drift 3 "/s; drift DAC through S1 and the command through S16."""
    vfc_in, line = summing_amp(CMD_ARCSEC_S + 3.0, 3.0, 1, CMD_ARCSEC_S, 1)
    assert vfc_in == CMD_ARCSEC_S
    assert line == 0.0


finite = {"allow_nan": False, "allow_infinity": False}


@settings(deadline=None)
@given(gyro=st.floats(-1e6, 1e6, **finite), drift=st.floats(-100.0, 100.0, **finite),
       drift_switch=st.sampled_from([0, 1]), cmd=st.floats(-1e4, 1e4, **finite),
       cmd_switch=st.sampled_from([0, 1]))
def test_two_node_law(gyro, drift, drift_switch, cmd, cmd_switch):
    vfc_in, line = summing_amp(gyro, drift, drift_switch, cmd, cmd_switch)
    assert vfc_in == (gyro - drift if drift_switch else gyro)
    assert line == pytest.approx(vfc_in - (cmd if cmd_switch else 0.0), rel=1e-15, abs=1e-12)
