"""Shared geometric residual pieces (robot-agnostic), with analytic Jacobians.

Range from a point b fixed on a body with pose X = (R, t) to a point a:
    r = || R b + t - a ||
The model of a rigid cable (pulley a, attachment b) and of a UWB range (anchor a, tag b).
"""

from __future__ import annotations

import gtsam
import numpy as np


def body_point_range(pose: gtsam.Pose3, b: np.ndarray, a: np.ndarray,
                     H: list | None = None) -> float:
    """r = ||R b + t - a|| (m). With H, fills H[0] = dr/dpose (1x6, tangent [rot, trans] in the body
    frame) and H[1] = dr/da (1x3). At r = 0 the direction is undefined and the Jacobians are zero."""
    R = pose.rotation().matrix()
    d = R @ b + pose.translation() - a
    r = float(np.sqrt(d @ d))
    if H is not None:
        u = d / r if r > 0 else np.zeros(3)
        ub = R.T @ u  # the direction in the body frame
        H[0] = np.concatenate([np.cross(b, ub), ub]).reshape(1, 6)
        H[1] = -u.reshape(1, 3)
    return r
