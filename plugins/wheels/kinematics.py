"""What a differential drive's wheel stream says between two times (docs/models/wheels.md#streams):
pure numpy, for every interval at once.

A wheel stream has columns `t, left, right[, passive][, gyro]`: cumulative wheel angles (rad), or
cumulative encoder ticks when the robot description gives `ticks_per_revolution`, and the gyro's z
rate (rad/s, counter-clockwise positive). A cumulative reading is continuous in time, so it is
interpolated linearly at any time inside the stream; the gyro sample of row i is the mean rate over
the interval that ends at t_i (the interval of the encoder increments of the same row), so its
integral is piecewise linear between the stamps as well.

Per interval, the travel of a wheel's contact point (m) is its angle increment times its radius
(`fusionkit.api.differential_drive_twist` turns the driven wheels' travels into the axle midpoint's
forward travel and heading change).
"""

from __future__ import annotations

import numpy as np

def wheel_angles(readings: np.ndarray, ticks_per_revolution: float | None) -> np.ndarray:
    """Wheel angles (rad) from a stream column: the column itself, or ticks * 2 pi / ticks per revolution."""
    readings = np.asarray(readings, float)
    return readings if ticks_per_revolution is None else readings * (2.0 * np.pi / ticks_per_revolution)


def inside(stream_t: np.ndarray, times: np.ndarray) -> np.ndarray:
    """Mask of the times inside the stream's span (where its readings can be interpolated)."""
    return (times >= stream_t[0]) & (times <= stream_t[-1])


def increments(stream_t: np.ndarray, cumulative: np.ndarray, times: np.ndarray) -> np.ndarray:
    """(len(times) - 1,) change of a cumulative reading between consecutive `times` (inside the stream)."""
    return np.diff(np.interp(times, stream_t, cumulative))


def gyro_increments(stream_t: np.ndarray, rate: np.ndarray, times: np.ndarray) -> np.ndarray:
    """(len(times) - 1,) integral of the gyro rate (rad) between consecutive `times`; sample i holds over
    (t_{i-1}, t_i] (the first sample covers nothing)."""
    angle = np.concatenate([[0.0], np.cumsum(np.asarray(rate, float)[1:] * np.diff(stream_t))])
    return increments(stream_t, angle, times)

