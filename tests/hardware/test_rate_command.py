"""Rate-command modules 120 (roll, via S16) and 128 (yaw, via S17).

Truth: the patent's commanded rate is 1.5 deg/s = 5400 arcsec/s, in the
direction the master sequencer chooses; 360 deg at that rate takes 240 s.
"""

import pytest

from allsky import units
from allsky.hardware.rate_command import rate_command

RATE_ARCSEC_S = 1.5 * units.DEG2ARCSEC


def test_patent_rate_in_arcsec_s():
    assert RATE_ARCSEC_S == 5400.0
    assert 360.0 * units.DEG2ARCSEC / rate_command(RATE_ARCSEC_S, 1) == 240.0


@pytest.mark.parametrize("sign", [1, -1])
def test_sign_sets_the_direction(sign):
    assert rate_command(RATE_ARCSEC_S, sign) == sign * 5400.0


def test_reversal_is_exact():
    assert rate_command(RATE_ARCSEC_S, 1) + rate_command(RATE_ARCSEC_S, -1) == 0.0
