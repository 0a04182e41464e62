"""Where a calibration's final pointing error comes from.

Drift, scale factors or misalignment: which stored quantity costs what.

Mode 6 flies to the target on the gyros alone, through the drift counters
13/15/17 (drift DACs 7/9/11) and register 23 (scale factors and the four
cross-coupling factors). From the mission as its calibration left it,
Mode 6 is flown again with

* every stored quantity replaced by the truth: what is left is the
  open-loop *targeting* itself (the angle random walk over Mode 6, the
  Sun's motion, the settle tolerance and limit cycle, the drift DACs'
  rounding);
* the truth except one group kept as the method stored it: the drift
  counters, the two scale factors, or the four cross-coupling factors.

Every re-flight starts from the same state with the same noise (the loop
seeds each leg from the mission seed and the leg number), so a group's
contribution is the change it makes to the final line-of-sight error
*vector*, ``e_group - e_truth``; the contributions and the targeting add
up to the flown error, less an interaction term (reported) from the
limit cycle's dependence on the path.
"""

import numpy as np

from allsky import units, xmath
from allsky.computer import word_registers as wr
from allsky.vocabulary import AXES

#: Groups of stored quantities, in the order reported.
GROUPS = ("drift", "scale_factor", "misalignment")
_SLOTS = {"scale_factor": (wr.SF_ROLL, wr.SF_YAW),
          "misalignment": (wr.ROLL_INTO_PITCH, wr.ROLL_INTO_YAW, wr.YAW_INTO_PITCH,
                           wr.YAW_INTO_ROLL)}


def true_storage(m):
    """Register 23 and drift-counter values a perfect calibration stores for ``m``."""
    truth = m.summary()["truth"]
    w = np.array(m.state.word23, dtype=float)
    w[wr.SF_ROLL] = truth["scale_factor"]["roll"]
    w[wr.SF_YAW] = truth["scale_factor"]["yaw"]
    cc = truth["cross_coupling"]
    w[wr.ROLL_INTO_PITCH], w[wr.ROLL_INTO_YAW] = cc["roll_into_pitch"], cc["roll_into_yaw"]
    w[wr.YAW_INTO_PITCH], w[wr.YAW_INTO_ROLL] = cc["yaw_into_pitch"], cc["yaw_into_roll"]
    el = m.params.electronics
    hi = (1 << (el.drift_dac_bits - 1)) - 1
    counts = np.array([min(max(round(truth["drift_deg_h"][a] / el.drift_lsb_arcsec_s), -hi - 1),
                           hi) for a in AXES], dtype=m.state.drift_counters.dtype)
    return w, counts


def line_of_sight_error_arcsec(m) -> np.ndarray:
    """[arcsec] The roll axis's error from the target as a vector, ``t x x``.

    Inertial axes, for mission ``m`` as it stands (its attitude and target).

    Its length is the sine of the pointing error (the pointing error to
    1e-9 at these angles).
    """
    from allsky.vehicle import quaternion

    x_body = quaternion.dcm_body_from_inertial(m.state.x[0:4])[0]
    return np.cross(m.target_direction(), x_body) * units.RAD2ARCSEC


def _fly_mode6(history, arrays, word23, drift_counters):
    from allsky.computer import word_registers as wr
    from allsky.sim.mission import Mission
    from allsky.vocabulary import AXES

    m = Mission.from_snapshot(history, arrays, telemetry=False)
    by = "the pointing decomposition"
    m.board.load_word23({name: float(word23[k]) for name, k in wr.WORD23.items()}, by=by)
    m.board.load_drift({axis: int(d) for axis, d in zip(AXES, drift_counters)}, by=by)
    m.run()
    return line_of_sight_error_arcsec(m) if m.status == "complete" else None


def decompose(history, arrays) -> dict | None:
    """The final pointing of a calibrated mission, taken apart (module docstring).

    ``history`` and ``arrays`` are the two parts of the
    :meth:`~allsky.sim.mission.Mission.snapshot` taken at the end of the
    calibration, before Mode 6.

    Returns
    -------
    dict or None
        ``total_arcsec`` (Mode 6 as stored), ``targeting_arcsec`` (with the
        truth stored), ``drift_arcsec``, ``scale_factor_arcsec``,
        ``misalignment_arcsec`` (each group's contribution, the length of
        its change of the error vector) and ``interaction_arcsec`` (what
        the sum of the parts misses); None if a re-flight did not complete.
    """
    from allsky.sim.mission import Mission

    start = Mission.from_snapshot(history, arrays, telemetry=False)
    stored_w = np.array(start.state.word23, dtype=float)
    stored_d = np.array(start.state.drift_counters)
    true_w, true_d = true_storage(start)
    total = _fly_mode6(history, arrays, stored_w, stored_d)
    base = _fly_mode6(history, arrays, true_w, true_d)
    if total is None or base is None:
        return None
    out = {"total_arcsec": xmath.norm3(total), "targeting_arcsec": xmath.norm3(base)}
    parts = np.zeros(3)
    for group in GROUPS:
        w, d = true_w.copy(), true_d.copy()
        if group == "drift":
            d = stored_d
        else:
            for slot in _SLOTS[group]:
                w[slot] = stored_w[slot]
        e = _fly_mode6(history, arrays, w, d)
        if e is None:
            return None
        out[f"{group}_arcsec"] = xmath.norm3(e - base)
        parts += e - base
    out["interaction_arcsec"] = xmath.norm3(total - base - parts)
    return out
