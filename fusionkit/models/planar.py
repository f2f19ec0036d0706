"""Planar (SE(2)) kinematics: the unicycle and the differential drive."""

from __future__ import annotations

import gtsam
import numpy as np


def differential_drive_twist(v_right: np.ndarray, v_left: np.ndarray,
                             wheel_distance: float) -> tuple[np.ndarray, np.ndarray]:
    """Forward speed v = (vr + vl) / 2 (m/s) and turn rate omega = (vr - vl) / d (rad/s) of a
    differential-drive robot from its wheel speeds (m/s) and axle length d (m)."""
    return 0.5 * (v_right + v_left), (v_right - v_left) / wheel_distance


def unicycle_increment(v: np.ndarray, omega: np.ndarray, dt: np.ndarray) -> gtsam.Pose2:
    """The body-frame motion of a unicycle holding speed v (m/s) and turn rate omega (rad/s) over
    each dt (s), composed exactly (arcs) interval by interval."""
    out = gtsam.Pose2()
    for vk, wk, h in zip(v, omega, dt):
        out = out.compose(gtsam.Pose2.Expmap(np.array([vk * h, 0.0, wk * h])))
    return out
