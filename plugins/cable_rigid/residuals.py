"""Pure residuals of the cable factors that GTSAM has no native factor for."""

from __future__ import annotations

from functools import partial

import numpy as np

from fusionkit.api import POINT3, POSE3, SCALAR, VectorizedResidual, pulley_cables


def elastic_cables(rho: float, axis, x: list[np.ndarray], data: dict[str, np.ndarray], jacobians: bool):
    """Elastic cables (thesis eq. 4.2, docs/models/cable_rigid.md#elastic-cable) for N factors:
    e = (1 - T/EA) l* + l0 - z (m), stretch = T/EA (measured tension over axial stiffness),
    l* = ||R b + t - a||, or with a pulley radius `rho` > 0 the length over a pulley swivelling about
    `axis` (pulley.py; its gradient in the attachment point p = R b + t is the free cable's direction n,
    in the pulley a it is -n). x = [poses (N, 4, 4), pulleys a (N, 3), offsets l0 (N,)]; data:
    attachment b (N, 3), stretch (N,), z (N,). d e / d pose = (1 - stretch) [b x R^T n, R^T n]."""
    pose, pulley, offset = x
    b, alpha = data["attachment"], 1.0 - data["stretch"]
    R = pose[:, :3, :3]
    p = np.einsum("nij,nj->ni", R, b) + pose[:, :3, 3]
    length, n = pulley_cables(p, pulley, rho, axis)
    e = (alpha * length + offset - data["z"])[:, None]
    if not jacobians:
        return e
    body = np.einsum("nji,nj->ni", R, n)  # the cable's direction in the body frame
    d_pose = alpha[:, None, None] * np.concatenate([np.cross(b, body), body], axis=1)[:, None, :]
    return e, [d_pose, (-alpha[:, None] * n)[:, None, :], np.ones((len(e), 1, 1))]


def elastic_cable_residual(rho: float = 0.0, axis=None) -> VectorizedResidual:
    """The elastic-cable residual of a robot whose pulleys have radius `rho` (0: none) about `axis`."""
    axis = np.ones(3) if axis is None else np.asarray(axis, float)
    return VectorizedResidual("cable.elastic_length", (POSE3, POINT3, SCALAR), 1,
                              partial(elastic_cables, float(rho), axis))


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
