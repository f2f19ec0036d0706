"""Rate signals (wheel speeds, IMU samples) integrated between two state times, sample and hold:
each sample's value holds from its time until the next sample's."""

from __future__ import annotations

import numpy as np


def held_intervals(sample_t: np.ndarray, t0: float, t1: float) -> tuple[np.ndarray, np.ndarray]:
    """(rows, dt): the samples whose hold intervals overlap [t0, t1) and for how long (s) each holds
    inside it. The last sample before t0 covers the start; the last one holds on after its time; a
    sample at t1 or later contributes nothing; before the first sample nothing is known (that part
    of [t0, t1) is left out)."""
    first = max(int(np.searchsorted(sample_t, t0, side="right")) - 1, 0)
    last = int(np.searchsorted(sample_t, t1, side="left"))
    rows = np.arange(first, max(last, first + 1))
    ends = np.append(sample_t, np.inf)[rows + 1]
    dt = np.clip(np.minimum(ends, t1) - np.maximum(sample_t[rows], t0), 0.0, None)
    return rows, dt
