"""The hold residual of the identifiability analysis (docs/models/serial_arm.md#identifiability); the
marker residuals, evaluated for many samples at once, are in vectorized_kinematics.py."""

from __future__ import annotations

import gtsam
import numpy as np


def held_axes_residual(vartype: str, value, x, axes: list[int], H: list | None = None) -> np.ndarray:
    """The chosen tangent axes of x away from `value` (a pose3: Log(value^-1 x); a vector or scalar:
    x - value): holds those axes of an unidentifiable parameter (docs/models/serial_arm.md#identifiability)."""
    if vartype == "pose3":
        full = gtsam.Pose3.Logmap(value.between(x))
        J = gtsam.Pose3.LogmapDerivative(full)
    else:
        full = np.atleast_1d(np.asarray(x, float) - np.asarray(value, float))
        J = np.eye(len(full))
    if H is not None:
        H[0] = J[axes]
    return full[axes]
