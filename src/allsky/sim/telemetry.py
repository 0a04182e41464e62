"""Telemetry tables: the columns the frame loop writes, and what they encode.

The loop fills a float64 table, one row every ``mission.telemetry_every_frames``
frames, through :mod:`allsky.sim.recorder`, which holds the column list
(:data:`COLUMNS`, :data:`INDEX`, re-exported here). Integers (counters,
registers, switch bitmask) are exact in float64.

Files carry the unit in every column name, ``name [unit]`` (:func:`header`);
they are written and read back, CSV or Parquet, by
:mod:`allsky.apps.telemetry_files`, which also generates ``docs/telemetry.md``.
"""

import numpy as np

# The column list lives beside the compiled recorder that writes it; re-exported here.
from allsky.sim.recorder import COLUMNS, INDEX, Column  # noqa: F401


def header() -> list:
    """Column names as written in files: ``name [unit]``."""
    return [f"{c.name} [{c.unit}]" for c in COLUMNS]


def switch_closed(table: np.ndarray, k: int) -> np.ndarray:
    """Boolean series: is on/off switch Sk closed in each row.

    ``table`` is a telemetry table (rows of :data:`COLUMNS`) and ``k`` the
    switch number.
    """
    return (table[:, INDEX["switches"]].astype(np.int64) >> (k - 1)) & 1 == 1
