"""The scenario's wheel array and jets, with the dither example checked in them.

Data for ``allsky analyze --envelope``: the envelopes of
:mod:`allsky.vehicle.envelopes` for the wheel array the scenario's ``[wheels]``
table describes (any number of wheels, any spin axes, one limit per wheel),
with its limits or its axes replaced on request (:func:`wheel_array`), beside
the scenario's jet couples 39-41; and the margin, in each, of the dither
document's example.

That example (16000 kg m^2 about each axis, 100 urad, 51.2 s) is the dither
document's vehicle, not the emulated one (``vehicle.inertia_kg_m2``, 100 to
680 kg m^2): its check says how much of the array's torque that document's
dither would take, whatever the array analysed.
"""

import math
from types import MappingProxyType

import numpy as np

from allsky.vocabulary import AXES

#: The dither example the wheels are checked against: inertia [kg m^2] (about each body
#: axis), amplitude [rad] and period [s] (docs/envelopes.md).
DITHER_EXAMPLE = MappingProxyType({"inertia_kg_m2": 16000.0, "amplitude_rad": 100e-6,
                                   "period_s": 51.2})
#: Samples per dither period in the profile check; a multiple of 4 puts samples on the peaks.
DITHER_SAMPLES = 64
#: ``wheel_array["source"]`` values: a part taken from the scenario's ``[wheels]`` table,
#: or given by the caller (the command's ``--wheel-*`` options).
FROM_SCENARIO = "scenario"
GIVEN = "given"
#: The scenario key each part of the array comes from, when it does.
SCENARIO_KEYS = MappingProxyType({"axes": "wheels.axes",
                                  "torque_max_n_m": "wheels.max_torque_n_m",
                                  "momentum_max_n_m_s": "wheels.max_momentum_n_m_s"})


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
            "worst_axis": AXES[worst], "margin_per_axis": [float(m) for m in per_axis]}


def _per_wheel(key, value, n, replaced_axes) -> list:
    """One limit per wheel from the scenario's one number or ``n`` numbers."""
    from allsky.config import ConfigError

    if np.ndim(value) == 0:
        return [float(value)] * n
    if len(value) != n:
        # Only when the axes were replaced: the scenario checked its own count.
        raise ConfigError(key, value, f"one limit per wheel of {SCENARIO_KEYS['axes']}, "
                          f"{len(value)} in all, cannot be spread over the {n} wheels "
                          f"{replaced_axes}; give one limit for those wheels")
    return [float(v) for v in value]


def wheel_array(wheels, beta_deg=None, torque_max_n_m=None, momentum_max_n_m_s=None) -> dict:
    """The wheel array to analyse: the scenario's ``[wheels]``, any part replaced.

    Parameters
    ----------
    wheels : scenario section
        The scenario's ``[wheels]`` (``cfg.wheels``): ``axes`` (n x 3 unit
        vectors, body axes), ``max_torque_n_m`` and ``max_momentum_n_m_s``
        (one number, or one per wheel).
    beta_deg : float, optional
        Replace the axes by the four-wheel pyramid about +x (roll) with each
        spin axis ``beta_deg`` from it
        (:func:`allsky.vehicle.envelopes.pyramid_axes`). The scenario's
        limits carry over when they are one number or four.
    torque_max_n_m : float or array_like, shape (n,), optional
        Replace the torque limit of each wheel [N m].
    momentum_max_n_m_s : float or array_like, shape (n,), optional
        Replace the momentum limit of each wheel [N m s].

    Returns
    -------
    dict
        JSON-ready: ``axes`` (n rows [x, y, z]), ``torque_max_n_m`` and
        ``momentum_max_n_m_s`` (n numbers each), ``beta_deg`` (the pyramid's
        angle, None for the scenario's axes) and ``source``: for each of
        ``axes``, ``torque_max_n_m``, ``momentum_max_n_m_s``,
        :data:`FROM_SCENARIO` (from the key named in :data:`SCENARIO_KEYS`)
        or :data:`GIVEN`.

    Raises
    ------
    ConfigError
        The pyramid replaces the axes while the scenario gives a limit per
        wheel for another number of wheels, and no limit replaces it.
    """
    from allsky.vehicle.envelopes import pyramid_axes

    if beta_deg is None:
        axes = [[float(x) for x in row] for row in wheels.axes]
    else:
        axes = pyramid_axes(beta_deg).tolist()
    n = len(axes)
    replaced = None if beta_deg is None else f"of a pyramid at {float(beta_deg):g} deg"
    limits = {}
    for name, given in (("torque_max_n_m", torque_max_n_m),
                        ("momentum_max_n_m_s", momentum_max_n_m_s)):
        key = SCENARIO_KEYS[name]
        value = getattr(wheels, key.split(".")[1]) if given is None else given
        limits[name] = _per_wheel(key if given is None else name, value, n, replaced)
    return {"axes": axes, **limits,
            "beta_deg": None if beta_deg is None else float(beta_deg),
            "source": {"axes": FROM_SCENARIO if beta_deg is None else GIVEN,
                       "torque_max_n_m": FROM_SCENARIO if torque_max_n_m is None else GIVEN,
                       "momentum_max_n_m_s": (FROM_SCENARIO if momentum_max_n_m_s is None
                                              else GIVEN)}}


def envelope_analysis(jet_torque_n_m, axes, torque_max_n_m, momentum_max_n_m_s,
                      dither=DITHER_EXAMPLE) -> dict:
    """Wheel-array and jet envelopes, with the dither example checked in them.

    Parameters
    ----------
    jet_torque_n_m : array_like, shape (3,)
        Roll, pitch, yaw couple torques of jets 39-41 [N m], ``2 F r``
        (:func:`allsky.hardware.jets.make_params`).
    axes : array_like, shape (n, 3)
        Unit spin axes of the wheels, body axes, spanning 3-D.
    torque_max_n_m, momentum_max_n_m_s : float or array_like, shape (n,)
        Torque [N m] and momentum [N m s] limit of each wheel, or one for all.
    dither : mapping
        ``inertia_kg_m2``, ``amplitude_rad``, ``period_s`` of the dither to check.

    Returns
    -------
    dict
        JSON-ready: ``wheels`` and ``jets`` exactly as
        :func:`allsky.vehicle.envelopes.envelope_summary`; ``wheel_array``
        (the inputs: ``axes``, and ``torque_max_n_m`` and
        ``momentum_max_n_m_s`` one per wheel); ``dither_check``: the dither's
        inputs, its peak torque ``J A w^2`` [N m], and for ``wheels``,
        ``one_failed`` (the worst single failure) and ``jets``: ``inside``,
        ``margin`` (the least over the three axes,
        :func:`allsky.vehicle.envelopes.check_profile`), ``worst_axis`` and
        ``margin_per_axis`` (dither about roll, pitch, yaw in turn).
    """
    from allsky.vehicle.envelopes import envelope_summary, jet_envelope, make_envelope

    torque = make_envelope(axes, torque_max_n_m)
    momentum = make_envelope(axes, momentum_max_n_m_s)
    result = envelope_summary(torque.axes, torque.limits, momentum.limits, jet_torque_n_m)
    failed = result["wheels"]["one_failed"]["wheel"]
    profiles = dither_profiles_n_m(**dither)
    omega = 2.0 * math.pi / dither["period_s"]
    result["wheel_array"] = {"axes": torque.axes.tolist(),
                             "torque_max_n_m": torque.limits.tolist(),
                             "momentum_max_n_m_s": momentum.limits.tolist()}
    result["dither_check"] = {
        **{k: float(v) for k, v in dither.items()},
        "peak_torque_n_m": dither["inertia_kg_m2"] * dither["amplitude_rad"] * omega ** 2,
        "wheels": _dither_margins(torque, profiles),
        "one_failed": _dither_margins(torque.without(failed), profiles),
        "jets": _dither_margins(jet_envelope(jet_torque_n_m), profiles)}
    return result


def pseudo_inverse_reach(axes, torque_max_n_m, momentum_max_n_m_s) -> dict:
    """What the minimum-norm distribution reaches: radius and reach along each axis.

    ``{"torque": {"min_radius_n_m", "max_n_m"}, "momentum": {"min_radius_n_m_s",
    "max_n_m_s"}}``, the layout of the envelopes
    (:func:`allsky.vehicle.envelopes.envelope_summary`), for the polytope
    ``|(A+ v)_i| <= L_i`` (:func:`allsky.vehicle.wheels.pseudo_inverse_envelope`):
    torques it delivers without scaling, momenta it holds with every wheel
    within its limit (the wheels' momenta being ``A+`` of the body's).
    ``axes`` are the wheels' unit spin axes, (n, 3) in body axes;
    ``torque_max_n_m`` [N m] and ``momentum_max_n_m_s`` [N m s] each wheel's
    limits, one number for all or one per wheel.
    """
    from allsky.vehicle.wheels import pseudo_inverse_envelope

    out = {}
    for part, limit, unit in (("torque", torque_max_n_m, "n_m"),
                              ("momentum", momentum_max_n_m_s, "n_m_s")):
        normals, offsets = pseudo_inverse_envelope(axes, limit)
        reach = []
        for a in range(3):
            cos = normals[:, a]
            reach.append(float(np.min(offsets[cos > 0] / cos[cos > 0])))
        out[part] = {f"min_radius_{unit}": float(offsets.min()), f"max_{unit}": reach}
    return out


def scenario_envelopes(cfg, beta_deg=None, torque_max_n_m=None,
                       momentum_max_n_m_s=None) -> dict:
    """The envelopes of the scenario's wheel array and jets, with the dither check.

    Parameters
    ----------
    cfg : allsky.config.Scenario
        Gives the wheel array (``[wheels]``) and the jet couples (``[jets]``).
    beta_deg, torque_max_n_m, momentum_max_n_m_s : optional
        Replacements for parts of the wheel array, as :func:`wheel_array`.

    Returns
    -------
    dict
        :func:`envelope_analysis` of that array, with ``wheels.pseudo_inverse``
        (:func:`pseudo_inverse_reach`, what the minimum-norm distribution
        reaches) and ``wheels.allocation`` (the scenario's), its
        ``wheel_array`` from :func:`wheel_array` (so with ``beta_deg`` and
        ``source``), and in
        ``dither_check`` the diagonal of the emulated vehicle's inertia,
        ``emulated_inertia_kg_m2`` [kg m^2], beside the example's.
    """
    from allsky.hardware.jets import make_params

    array = wheel_array(cfg.wheels, beta_deg, torque_max_n_m, momentum_max_n_m_s)
    jets = make_params(cfg.jets.thrust_n, cfg.jets.moment_arm_m, cfg.jets.isp_s)
    result = envelope_analysis(jets.torque_n_m, array["axes"], array["torque_max_n_m"],
                               array["momentum_max_n_m_s"])
    result["wheels"]["pseudo_inverse"] = pseudo_inverse_reach(
        array["axes"], array["torque_max_n_m"], array["momentum_max_n_m_s"])
    result["wheels"]["allocation"] = cfg.wheels.allocation
    result["wheel_array"] = array
    result["dither_check"]["emulated_inertia_kg_m2"] = [
        float(x) for x in np.diag(np.asarray(cfg.vehicle.inertia_kg_m2, dtype=float))]
    return result


def flown_dither_check(cfg) -> dict:
    """The scenario's dither feed-forward torque in its actuators' envelopes.

    ``cfg`` is the scenario; its ``[dither]``, vehicle, jets and wheels are read.

    The torque the dither method asks of the actuators over its record:
    ``J_est a(t)`` with every axis dithered at once at its amplitude and
    period (``[dither]``; ``J_est`` the vehicle's inertia times
    ``dither.inertia_estimate_scale``), sampled every ``dither.sample_s``.

    Returns
    -------
    dict
        ``torque_peak_n_m`` (the largest magnitude reached about each body
        axis [N m]) and, for ``wheels`` (the scenario's ``[wheels]`` array)
        and ``jets`` (couples of jets 39-41): ``inside`` and ``margin``
        (:func:`allsky.vehicle.envelopes.check_profile`: how many times the
        profile could be scaled and still be met).
    """
    from allsky.hardware.jets import make_params
    from allsky.sequencer.dither import feedforward_torque_n_m
    from allsky.vehicle.envelopes import check_profile, jet_envelope, make_envelope

    d = cfg.dither
    inertia = np.asarray(cfg.vehicle.inertia_kg_m2, dtype=float) * float(d.inertia_estimate_scale)
    amplitude_rad = np.asarray(d.amplitude_urad, dtype=float) * 1e-6
    omega = 2.0 * math.pi / np.asarray(d.period_s, dtype=float)
    t_s = np.arange(0.0, float(d.record_s), float(d.sample_s))
    profile = np.array([feedforward_torque_n_m(inertia, amplitude_rad, omega, t) for t in t_s])
    array = wheel_array(cfg.wheels)
    jets = make_params(cfg.jets.thrust_n, cfg.jets.moment_arm_m, cfg.jets.isp_s)
    out = {"torque_peak_n_m": [float(x) for x in np.abs(profile).max(axis=0)]}
    for name, envelope in (("wheels", make_envelope(array["axes"], array["torque_max_n_m"])),
                           ("jets", jet_envelope(jets.torque_n_m))):
        check = check_profile(envelope, profile)
        out[name] = {"inside": bool(check.inside), "margin": float(check.margin)}
    return out
