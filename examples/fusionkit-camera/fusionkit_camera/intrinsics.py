"""The variable type `cal3_s2`: a pinhole camera's intrinsics K = [fx, fy, s, u0, v0] (px), stored as GTSAM's
Cal3_S2. Its tangent space is the same five numbers (Cal3_S2's retract adds), so the array form vectorized
residuals receive is that 5-vector and its retraction the default addition."""

from __future__ import annotations

import gtsam
import numpy as np

from fusionkit.api import VarType

AXES = ("fx", "fy", "skew", "u0", "v0")


def intrinsics_from(value) -> gtsam.Cal3_S2:
    """[fx, fy, s, u0, v0] (px) or a Cal3_S2; ValueError otherwise (fusionkit locates it in the YAML)."""
    if isinstance(value, gtsam.Cal3_S2):
        return value
    a = np.asarray(value, dtype=float)
    if a.shape != (5,):
        raise ValueError("expected [fx, fy, skew, u0, v0] (px)")
    if a[0] <= 0 or a[1] <= 0:
        raise ValueError("expected positive focal lengths fx, fy")
    return gtsam.Cal3_S2(*a)


CAL3_S2 = VarType(
    "cal3_s2", 5, lambda values, key: values.atCal3_S2(key), gtsam.PriorFactorCal3_S2, None,
    intrinsics_from, lambda k: [float(x) for x in k.vector()], lambda: gtsam.Cal3_S2(1.0, 1.0, 0.0, 0.0, 0.0),
    components=AXES, axes=AXES, axis_units=("px",) * 5,
    to_array=lambda k: np.asarray(k.vector(), dtype=float),
    summary="pinhole camera intrinsics [fx, fy, skew, u0, v0] (px), GTSAM's Cal3_S2 (fusionkit-camera)")
