"""Planar (SE(2)) kinematics: the unicycle and the differential drive."""

from __future__ import annotations

import gtsam
import numpy as np


def differential_drive_twist(v_right: np.ndarray, v_left: np.ndarray,
                             wheel_distance: float) -> tuple[np.ndarray, np.ndarray]:
    """Forward speed v = (vr + vl) / 2 (m/s) and turn rate omega = (vr - vl) / d (rad/s) of a
    differential-drive robot from its wheel speeds (m/s) and axle length d (m)."""
    return 0.5 * (v_right + v_left), (v_right - v_left) / wheel_distance


def arc_path(v: np.ndarray, omega: np.ndarray, dt: np.ndarray, start=(0.0, 0.0, 0.0)) -> np.ndarray:
    """(N + 1, 3) poses x, y (m), theta (rad, unwrapped) from `start` of a unicycle holding speed v (m/s) and turn
    rate omega (rad/s) over each dt (s): the exact arcs (Pose2.Expmap of (v dt, 0, omega dt)) composed, written as
    chords: each arc moves ds sin(dth/2)/(dth/2) along the heading at its middle."""
    ds, dth = np.asarray(v, float) * dt, np.asarray(omega, float) * dt
    theta = start[2] + np.concatenate([[0.0], np.cumsum(dth)])
    chord = ds * np.sinc(dth / (2.0 * np.pi))  # ds * sin(dth/2) / (dth/2)
    mid = theta[:-1] + 0.5 * dth
    x = start[0] + np.concatenate([[0.0], np.cumsum(chord * np.cos(mid))])
    y = start[1] + np.concatenate([[0.0], np.cumsum(chord * np.sin(mid))])
    return np.column_stack([x, y, theta])


def unicycle_increment(v: np.ndarray, omega: np.ndarray, dt: np.ndarray) -> gtsam.Pose2:
    """The body-frame motion of a unicycle holding speed v (m/s) and turn rate omega (rad/s) over
    each dt (s): the end of its arc_path from the origin."""
    return gtsam.Pose2(*arc_path(v, omega, dt)[-1])
