"""Telemetry recorder: names and units of the columns the frame loop writes, and export.

The loop fills a float64 table, one row every ``mission.telemetry_every_frames``
frames. Integers (counters, registers, switch bitmask) are exact in float64.
"""

import csv
from pathlib import Path

import numpy as np

#: (name, unit) of each column, in the order :func:`allsky.kernel._record` writes them.
COLUMNS = (
    ("time", "s"), ("mode", "-"),
    ("q_w", "-"), ("q_x", "-"), ("q_y", "-"), ("q_z", "-"),
    ("rate_x", "rad/s"), ("rate_y", "rad/s"), ("rate_z", "rad/s"),
    ("sun_pitch", "arcsec"), ("sun_yaw", "arcsec"), ("sun_present", "-"),
    ("tracker_yaw", "arcsec"), ("tracker_pitch", "arcsec"), ("star_present", "-"),
    ("counter14", "pulses"), ("counter16", "pulses"), ("counter18", "pulses"),
    ("drift_counter13", "pulses"), ("drift_counter15", "pulses"), ("drift_counter17", "pulses"),
    ("register25", "lsb"), ("register26", "lsb"), ("register27", "lsb"),
    ("valve_roll", "-"), ("valve_pitch", "-"), ("valve_yaw", "-"),
    ("amp31", "V"), ("amp32", "V"), ("amp33", "V"),
    ("error_roll", "arcsec"), ("error_pitch", "arcsec"), ("error_yaw", "arcsec"),
    ("propellant", "kg"), ("switches", "bitmask S1..S19"), ("s7_s8", "axis"),
    ("overflow", "bitmask 14,16,18,13,15,17"),
    ("corrected_roll", "arcsec"), ("corrected_yaw", "arcsec"), ("intermediate_pitch", "arcsec"),
)
INDEX = {name: i for i, (name, _) in enumerate(COLUMNS)}


def header() -> list:
    """Column headers ``name [unit]``."""
    return [f"{n} [{u}]" for n, u in COLUMNS]


def write_csv(path, table: np.ndarray) -> Path:
    """Write the telemetry table to CSV (full float precision)."""
    path = Path(path)
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header())
        for row in table:
            w.writerow([repr(float(v)) for v in row])
    return path


def switch_closed(table: np.ndarray, k: int) -> np.ndarray:
    """Boolean series: is on/off switch Sk closed in each row."""
    return (table[:, INDEX["switches"]].astype(np.int64) >> (k - 1)) & 1 == 1
