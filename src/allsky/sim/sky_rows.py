"""The rows of star tracker 105's sky: the window's stars, then the moving bodies.

One place decides what the tracker can see and in which order, so that its
parameters (:func:`allsky.sim.mission.build_params`), the names the journal
and the summary give a lock (:func:`allsky.sim.record.tracker_star_names`)
and the orbit's occultations agree row for row:

1. the catalog stars inside the magnitude window, brightest first;
2. the moving bodies (:mod:`allsky.vehicle.bodies`) whose magnitude on the
   mission date is inside the window, in the order of ``BODIES``, when
   ``star_tracker.moving_bodies`` flies them;
3. a wrong star of a fault not already there (:mod:`allsky.sim.faults`).

The bright gate counts the light of every catalog star and, when bodies fly,
of every body, inside the window or not (the Moon at -12 mag in the slit
drops the lock).

``moving_bodies = "auto"`` flies the bodies with an ``[orbit]`` and not
without one, so the patent's vehicle far from any body keeps its results.
In orbit a body's row moves with the orbit's samples: it is its direction
from the vehicle at the middle of the sample interval, held through it (the
Moon moves up to 4.7"/s seen from a low orbit, so 2.4" at most at 1 s
samples; a planet under 0.1"). Without an orbit a body's row is its
geocentric place at ejection, fixed: the Moon moves 0.55"/s (0.2 deg over a
25-minute mission), a planet at most 0.1"/s.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from allsky.vehicle import bodies as sky_bodies
from allsky.vehicle import sky


def bodies_flown(cfg) -> bool:
    """Whether scenario ``cfg`` flies the bodies (``star_tracker.moving_bodies``)."""
    setting = cfg.star_tracker.moving_bodies
    if setting == "auto":
        return cfg.orbit.kind != "none"
    return setting == "on"


class SkyRows(NamedTuple):
    """The tracker's rows (window stars, then bodies) and the gate's."""

    names: list  #: the tracker's rows by name
    directions: np.ndarray  #: (n, 3) unit vectors, ICRF, at ejection (geocentric)
    magnitudes: np.ndarray  #: [mag] (n,)
    body_names: list  #: the bodies flown (all of them, in the order of BODIES), or []
    body_rows: np.ndarray  #: (len(body_names),) each body's tracker row, -1 outside the window
    gate_directions: np.ndarray  #: (m, 3) every light the bright gate counts ((0, 3): no gate)
    gate_magnitudes: np.ndarray  #: [mag] (m,)
    gate_rows: np.ndarray  #: (len(body_names),) each body's gate row, -1 without a gate


def sky_rows(cfg) -> SkyRows:
    """The tracker's and the bright gate's rows for scenario ``cfg`` on its date."""
    date = cfg.mission.date_utc
    lo, hi = cfg.star_tracker.magnitude_window
    stars = sky.stars_in_magnitude_window(lo, hi, date)
    names = [s.name for s in stars]
    dirs = [sky.radec_to_unit(s.ra_deg, s.dec_deg) for s in stars]
    mags = [s.magnitude for s in stars]
    flown = sky_bodies.bodies(date) if bodies_flown(cfg) else []
    body_rows = np.full(len(flown), -1, dtype=np.int64)
    for j, b in enumerate(flown):
        if lo <= b.magnitude <= hi:
            body_rows[j] = len(names)
            names.append(b.name)
            dirs.append(sky.radec_to_unit(b.ra_deg, b.dec_deg))
            mags.append(b.magnitude)
    gate_rows = np.full(len(flown), -1, dtype=np.int64)
    if cfg.star_tracker.bright_gate:
        every = [sky.star(n, date) for n in sky.star_names()]
        gate_dirs = [sky.radec_to_unit(s.ra_deg, s.dec_deg) for s in every]
        gate_mags = [s.magnitude for s in every]
        for j, b in enumerate(flown):
            gate_rows[j] = len(gate_dirs)
            gate_dirs.append(sky.radec_to_unit(b.ra_deg, b.dec_deg))
            gate_mags.append(b.magnitude)
        gate = (np.array(gate_dirs, dtype=float).reshape(-1, 3), np.array(gate_mags, dtype=float))
    else:
        gate = (np.zeros((0, 3)), np.zeros(0))
    return SkyRows(names, np.array(dirs, dtype=float).reshape(-1, 3),
                   np.array(mags, dtype=float), [b.name for b in flown], body_rows, *gate,
                   gate_rows)


def body_table(rows: SkyRows, cfg, track, step_s: float) -> np.ndarray:
    """(n, b, 3): each of ``rows``' b bodies seen from the vehicle, by sample interval.

    Row ``k`` is the direction at the middle of the interval from sample
    ``k`` of ``track`` (:class:`allsky.vehicle.orbit.Track`), ``step_s`` [s]
    long, which the frame loop holds through it. ``rows`` is
    :func:`sky_rows`' (its ``body_names``), ``cfg`` the scenario (its date).
    """
    if not rows.body_names:
        return np.zeros((track.t_s.shape[0], 0, 3))
    half = 0.5 * step_s
    t = track.t_s + half
    r = track.r_m + half * track.v_m_s  # the vehicle at the middle (a t^2 / 2: 1 m at 0.5 s)
    return np.ascontiguousarray(sky_bodies.directions_from(
        rows.body_names, cfg.mission.date_utc, t, r / 1000.0))
