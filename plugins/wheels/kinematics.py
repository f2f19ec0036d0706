"""What a differential drive's wheel stream says between two times (docs/models/wheels.md#streams):
pure numpy, for every interval at once.

A wheel stream has columns `t, left, right[, passive][, gyro]`: cumulative wheel angles (rad), or
cumulative encoder ticks when the robot description gives `ticks_per_revolution`, and the gyro's z
rate (rad/s, counter-clockwise positive). A cumulative reading is continuous in time, so it is
interpolated linearly at any time inside the stream; the gyro sample of row i is the mean rate over
the interval that ends at t_i (the interval of the encoder increments of the same row), so its
integral is piecewise linear between the stamps as well. The wheel columns may be named by the
robot's joints instead (`joints` in the description: a ROS JointState topic's columns).

The gyro may instead come from an IMU stream at its own rate (column `gz`, e.g. a sensor_msgs/Imu
topic's angular_velocity.z): each sample is the rate at its stamp, and the rate between two samples
is their linear interpolation, integrated exactly (the trapezoid rule, with partial trapezoids at
interval ends that fall between samples).

Per interval, the travel of a wheel's contact point (m) is its angle increment times its radius
(`fusionkit.api.differential_drive_twist` turns the driven wheels' travels into the axle midpoint's
forward travel and heading change).
"""

from __future__ import annotations

import numpy as np

from fusionkit.api import DataError, Stream, differential_drive_twist

from .model import AXLE, GYRO_BIAS, GYRO_SCALE, RADIUS

GYRO, IMU_GYRO = "gyro", "gz"   # a wheel stream's gyro column (interval means); an IMU's z rate (samples)


def wheel_angles(readings: np.ndarray, ticks_per_revolution: float | None) -> np.ndarray:
    """Wheel angles (rad) from a stream column: the column itself, or ticks * 2 pi / ticks per revolution."""
    readings = np.asarray(readings, float)
    return readings if ticks_per_revolution is None else readings * (2.0 * np.pi / ticks_per_revolution)


def wheel_column(stream: Stream, drive, wheel: str) -> np.ndarray:
    """A wheel's cumulative angles (rad) from its column of the wheel stream (drive: model.DiffDrive)."""
    return wheel_angles(stream.column(drive.columns[wheel]), drive.ticks[wheel])


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


def trapezoid_increments(sample_t: np.ndarray, rate: np.ndarray, times: np.ndarray) -> np.ndarray:
    """(len(times) - 1,) integral (rad) between consecutive `times` (inside the samples' span) of the rate
    interpolated linearly between instantaneous samples (at least two)."""
    rate = np.asarray(rate, float)
    cumulative = np.concatenate([[0.0], np.cumsum(np.diff(sample_t) * 0.5 * (rate[1:] + rate[:-1]))])
    j = np.clip(np.searchsorted(sample_t, times, side="right") - 1, 0, len(sample_t) - 2)
    angle = cumulative[j] + (times - sample_t[j]) * 0.5 * (rate[j] + np.interp(times, sample_t, rate))
    return np.diff(angle)


def gyro_integrals(stream: Stream, times: np.ndarray) -> np.ndarray:
    """(len(times) - 1,) gyro reading integrated between consecutive `times` (rad, gyro units): a wheel
    stream's `gyro` column (interval means, gyro_increments) or an IMU stream's `gz` (instantaneous samples,
    trapezoid_increments)."""
    if GYRO in stream.columns:
        return gyro_increments(stream.t, stream.column(GYRO), times)
    if len(stream) < 2:
        raise DataError(f"{stream.origin or stream.name}: one IMU sample; integrating the gyro needs at least two")
    return trapezoid_increments(stream.t, stream.column(IMU_GYRO), times)


def gyro_turns(stream: Stream, drive, times: np.ndarray) -> np.ndarray:
    """(len(times) - 1,) heading change (rad) the gyro gives between consecutive `times` at the description's
    scale and bias (drive: model.DiffDrive; a calibrated gyro): scale * integrated reading + bias * dt."""
    return drive.nominal[GYRO_SCALE] * gyro_integrals(stream, times) + drive.nominal[GYRO_BIAS] * np.diff(times)


def driven_twist(stream: Stream, drive, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(forward travel m, heading change rad), each (len(times) - 1,), of the driven wheels' odometry between
    consecutive `times` at the description's radii and axle length (drive: model.DiffDrive)."""
    travel = [drive.nominal[RADIUS[w]] * increments(stream.t, wheel_column(stream, drive, w), times)
              for w in ("right", "left")]
    return differential_drive_twist(*travel, drive.nominal[AXLE])
