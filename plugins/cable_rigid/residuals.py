"""Pure residuals of the cable factors that GTSAM has no native factor for."""

from __future__ import annotations

import gtsam
import numpy as np

from fusionkit.api import body_point_range

from .pulley import pulley_cables


def elastic_cable_residual(pose: gtsam.Pose3, pulley: np.ndarray, offset: float, b: np.ndarray,
                           stretch: float, z: float, H: list | None = None, rho: float = 0.0,
                           axis: np.ndarray | None = None) -> np.ndarray:
    """Elastic cable (thesis eq. 4.2, docs/models/cable_rigid.md#elastic-cable):
    e = (1 - T/EA) l* + l0 - z, with stretch = T/EA (measured tension over axial stiffness) and
    l* = ||R b + t - a||, or with a pulley radius `rho` > 0 the length over a pulley swivelling about
    `axis` (pulley.py; its gradient in the attachment point is the free cable's direction n, in a it is -n).
    Jacobians w.r.t. pose, pulley, offset."""
    alpha = 1.0 - stretch
    if rho > 0:
        D = np.zeros((3, 6), order="F")
        length, n = pulley_cables(pose.transformFrom(b, D), pulley, rho, axis)
        length, J = float(length[0]), [(n[0] @ D).reshape(1, 6), -n[0].reshape(1, 3)]
    else:
        J = [None, None] if H is not None else None
        length = body_point_range(pose, b, pulley, J)
    if H is not None:
        H[0] = alpha * J[0]
        H[1] = alpha * J[1]
        H[2] = np.ones((1, 1))
    return np.array([alpha * length + offset - z])


def plane_distance_residual(a0, a1, a2, ak, H: list | None = None) -> np.ndarray:
    """Signed distance of ak from the plane through a0, a1, a2: ((u x v) . w) / ||u x v||, with
    u = a1 - a0, v = a2 - a0, w = ak - a0 (m). Jacobians w.r.t. a0, a1, a2, ak (1x3 each)."""
    u, v, w = a1 - a0, a2 - a0, ak - a0
    c = np.cross(u, v)
    s = float(np.linalg.norm(c))
    n = c / s
    f = float(n @ w)
    if H is not None:
        df_dc = (w - f * n) / s
        df_du = np.cross(v, df_dc)  # d(u x v) = du x v - dv x u, and g . (du x v) = (v x g) . du
        df_dv = -np.cross(u, df_dc)
        H[1] = df_du.reshape(1, 3)
        H[2] = df_dv.reshape(1, 3)
        H[3] = n.reshape(1, 3)
        H[0] = -(H[1] + H[2] + H[3])
    return np.array([f])


def along_normal_residual(ai, aj, normal: np.ndarray, H: list | None = None) -> np.ndarray:
    """n . (aj - ai): two pulleys on one wall with known unit normal n (m)."""
    if H is not None:
        H[0] = -normal.reshape(1, 3)
        H[1] = normal.reshape(1, 3)
    return np.array([float(normal @ (aj - ai))])
