"""The wheel pyramid and the jet torques, with the dither example checked in them.

Data for ``allsky analyze --envelope``: the envelopes of
:mod:`allsky.vehicle.envelopes` for the default (or given) wheel pyramid and
the scenario's jet couples, and the margin of the dither document's example
(16000 kg m^2, 100 urad, 51.2 s) in each.
"""

import math
from types import MappingProxyType

import numpy as np

#: [deg] Default angle of each pyramid wheel's spin axis from +x: atan(sqrt 2), at which
#: all twelve facets of the torque envelope are equally far from the origin, so the
#: inscribed sphere (the torque available in every direction) is largest.
DEFAULT_PYRAMID_BETA_DEG = math.degrees(math.atan(math.sqrt(2.0)))
#: [N m] Default torque limit of each wheel, sized for the dither example's 16000 kg m^2
#: vehicle: at DEFAULT_PYRAMID_BETA_DEG one failed wheel leaves an inscribed radius of
#: 0.816 tau = 0.082 N m, 3.4 times the dither's 0.0241 N m peak about any axis.
DEFAULT_WHEEL_TORQUE_N_M = 0.1
#: [N m s] Default momentum limit of each wheel. The dither stores only J A w = 0.196 N m s;
#: the limit is set instead by a 0.1 deg/s slew of the 16000 kg m^2 vehicle about any axis
#: with one wheel failed: J w = 27.9 N m s <= 0.816 h needs h >= 34 N m s (500 s of full
#: torque per wheel).
DEFAULT_WHEEL_MOMENTUM_N_M_S = 50.0
#: The dither example the wheels are checked against: inertia [kg m^2] (about each body
#: axis), amplitude [rad] and period [s] (docs/envelopes.md).
DITHER_EXAMPLE = MappingProxyType({"inertia_kg_m2": 16000.0, "amplitude_rad": 100e-6,
                                   "period_s": 51.2})
#: Samples per dither period in the profile check; a multiple of 4 puts samples on the peaks.
DITHER_SAMPLES = 64
AXIS_NAMES = ("roll", "pitch", "yaw")


def dither_profiles_n_m(inertia_kg_m2, amplitude_rad, period_s, samples=DITHER_SAMPLES):
    """Feed-forward torque over one period of a dither about each body axis in turn.

    Parameters
    ----------
    inertia_kg_m2 : float
        Inertia about each body axis [kg m^2] (the estimate the feed-forward uses).
    amplitude_rad : float
        Dither amplitude [rad].
    period_s : float
        Dither period [s].
    samples : int
        Samples per period.

    Returns
    -------
    ndarray, shape (3, samples, 3)
        ``[axis, sample]``: the torque vector [N m], body axes, from
        :func:`allsky.sequencer.dither.feedforward_torque_n_m`; its peak is
        ``J A w^2`` along the dithered axis.
    """
    from allsky.sequencer.dither import feedforward_torque_n_m

    inertia = float(inertia_kg_m2) * np.eye(3)
    omega = np.full(3, 2.0 * math.pi / float(period_s))
    t_s = np.arange(samples) * (float(period_s) / samples)
    return np.array([[feedforward_torque_n_m(inertia, amplitude_rad * np.eye(3)[k], omega, t)
                      for t in t_s] for k in range(3)])


def _dither_margins(envelope, profiles) -> dict:
    """Margin of each axis's dither profile in ``envelope``, and the least."""
    from allsky.vehicle.envelopes import check_profile

    per_axis = [check_profile(envelope, p).margin for p in profiles]
    worst = int(np.argmin(per_axis))
    return {"inside": bool(per_axis[worst] >= 1.0), "margin": float(per_axis[worst]),
            "worst_axis": AXIS_NAMES[worst], "margin_per_axis": [float(m) for m in per_axis]}


def envelope_analysis(jet_torque_n_m, beta_deg=DEFAULT_PYRAMID_BETA_DEG,
                      wheel_torque_n_m=DEFAULT_WHEEL_TORQUE_N_M,
                      wheel_momentum_n_m_s=DEFAULT_WHEEL_MOMENTUM_N_M_S,
                      dither=DITHER_EXAMPLE) -> dict:
    """Wheel-pyramid and jet envelopes, with the dither example checked in them.

    Parameters
    ----------
    jet_torque_n_m : array_like, shape (3,)
        Roll, pitch, yaw couple torques of jets 39-41 [N m], ``2 F r``
        (:func:`allsky.hardware.jets.make_params`).
    beta_deg : float
        Angle of each wheel's spin axis from +x [deg] (:func:`allsky.vehicle.envelopes.pyramid_axes`).
    wheel_torque_n_m, wheel_momentum_n_m_s : float
        Torque [N m] and momentum [N m s] limit of each wheel.
    dither : mapping
        ``inertia_kg_m2``, ``amplitude_rad``, ``period_s`` of the dither to check.

    Returns
    -------
    dict
        JSON-ready: ``wheels`` and ``jets`` exactly as
        :func:`allsky.vehicle.envelopes.envelope_summary`; ``wheel_array``
        (the inputs: ``beta_deg``, ``axes``, ``torque_max_n_m``,
        ``momentum_max_n_m_s``); ``dither_check``: the dither's inputs, its
        peak torque ``J A w^2`` [N m], and for ``wheels``, ``one_failed``
        (the worst single failure) and ``jets``: ``inside``, ``margin`` (the
        least over the three axes, :func:`allsky.vehicle.envelopes.check_profile`),
        ``worst_axis`` and ``margin_per_axis`` (dither about roll, pitch, yaw in turn).
    """
    from allsky.vehicle.envelopes import (
        envelope_summary,
        jet_envelope,
        make_envelope,
        pyramid_axes,
    )

    axes = pyramid_axes(beta_deg)
    result = envelope_summary(axes, wheel_torque_n_m, wheel_momentum_n_m_s, jet_torque_n_m)
    torque = make_envelope(axes, wheel_torque_n_m)
    failed = result["wheels"]["one_failed"]["wheel"]
    profiles = dither_profiles_n_m(**dither)
    omega = 2.0 * math.pi / dither["period_s"]
    result["wheel_array"] = {"beta_deg": float(beta_deg), "axes": axes.tolist(),
                             "torque_max_n_m": float(wheel_torque_n_m),
                             "momentum_max_n_m_s": float(wheel_momentum_n_m_s)}
    result["dither_check"] = {
        **{k: float(v) for k, v in dither.items()},
        "peak_torque_n_m": dither["inertia_kg_m2"] * dither["amplitude_rad"] * omega ** 2,
        "wheels": _dither_margins(torque, profiles),
        "one_failed": _dither_margins(torque.without(failed), profiles),
        "jets": _dither_margins(jet_envelope(jet_torque_n_m), profiles)}
    return result
