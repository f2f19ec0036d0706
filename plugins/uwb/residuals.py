"""Residuals of the UWB factors GTSAM has no native factor for, with analytic Jacobians.

Tag position on a body X with lever arm b: p = R b + t (Pose3, tangent [rot, trans] in the body
frame: dp/dX = [-R [b]x, R]); on a planar body (Pose2, tangent [x, y, theta] in the body frame)
p = (R(theta) b_xy + t, b_z): dp/dX = [[R, R J b_xy], [0, 0]], J the 90-degree rotation.
"""

from __future__ import annotations

import gtsam
import numpy as np

from fusionkit.api import POSE2, POSE3, VectorizedResidual, lie

J90 = np.array([[0.0, -1.0], [1.0, 0.0]])


def tag_position(pose, b: np.ndarray, H: list | None = None) -> np.ndarray:
    """3-D position of the tag at body point b (3,); with H, H[0] = dp/dpose (3 x dim)."""
    if isinstance(pose, gtsam.Pose2):
        R = pose.rotation().matrix()
        p = np.concatenate([R @ b[:2] + np.array([pose.x(), pose.y()]), b[2:3]])
        if H is not None:
            D = np.zeros((3, 3))
            D[:2, :2] = R
            D[:2, 2] = R @ J90 @ b[:2]
            H[0] = D
        return p
    R = pose.rotation().matrix()
    p = R @ b + pose.translation()
    if H is not None:
        H[0] = np.hstack([-R @ np.array([[0, -b[2], b[1]], [b[2], 0, -b[0]], [-b[1], b[0], 0]]), R])
    return p


def tag_positions(pose: np.ndarray, b: np.ndarray, jacobians: bool):
    """tag_position for N poses in array form, Pose3 (N, 4, 4) or Pose2 (N, 3), tags b (N, 3): positions
    (N, 3) and, with `jacobians`, dp/dpose (N, 3, 6 or 3)."""
    if pose.ndim == 3:
        R = pose[:, :3, :3]
        p = np.einsum("nij,nj->ni", R, b) + pose[:, :3, 3]
        if not jacobians:
            return p, None
        return p, np.concatenate([-R @ lie.skew(b), R], axis=2)
    c, s = np.cos(pose[:, 2]), np.sin(pose[:, 2])
    R = np.stack([np.stack([c, -s], axis=1), np.stack([s, c], axis=1)], axis=1)  # (N, 2, 2)
    p = np.column_stack([np.einsum("nij,nj->ni", R, b[:, :2]) + pose[:, :2], b[:, 2]])
    if not jacobians:
        return p, None
    D = np.zeros((len(pose), 3, 3))
    D[:, :2, :2] = R
    D[:, :2, 2] = np.einsum("nij,nj->ni", R @ J90, b[:, :2])
    return p, D


def tag_ranges(x: list[np.ndarray], data: dict[str, np.ndarray], jacobians: bool):
    """e = ||p_a - p_b|| - z: ranges between tags on two robots (m), N at once; x = [poses a, poses b]
    (both Pose3 or both Pose2 in array form); data: tag a (N, 3), tag b (N, 3), z (N,)."""
    pa, Ha = tag_positions(x[0], data["tag_a"], jacobians)
    pb, Hb = tag_positions(x[1], data["tag_b"], jacobians)
    d = pa - pb
    r = np.linalg.norm(d, axis=1)
    e = (r - data["z"])[:, None]
    if not jacobians:
        return e
    u = d / np.where(r > 0, r, 1.0)[:, None]
    return e, [np.einsum("ni,nij->nj", u, Ha)[:, None, :], -np.einsum("ni,nij->nj", u, Hb)[:, None, :]]


TAG_RANGES = {False: VectorizedResidual("uwb.tag_range", (POSE3, POSE3), 1, tag_ranges),
              True: VectorizedResidual("uwb.tag_range", (POSE2, POSE2), 1, tag_ranges)}  # by planar


def scaled_range_residual(pose, anchor: np.ndarray, bias: float, alpha: float, b: np.ndarray, z: float,
                          H: list | None = None) -> np.ndarray:
    """e = (1 + alpha) ||p_tag - a|| + bias - z (m): UWB two-way range with a distance-proportional
    scale error alpha and an additive bias. A 3-D anchor (a planar robot's tag at the height b_z)
    or a 2-D one (planar world: the tag's x, y). Jacobians w.r.t. pose, anchor (1 x dim),
    bias (1x1), alpha (1x1)."""
    Hp = [None] if H is not None else None
    dim = len(anchor)
    d = tag_position(pose, b, Hp)[:dim] - anchor
    r = float(np.sqrt(d @ d))
    if H is not None:
        u = d / r if r > 0 else np.zeros(dim)
        H[0] = ((1 + alpha) * u @ Hp[0][:dim]).reshape(1, -1)
        H[1] = (-(1 + alpha) * u).reshape(1, dim)
        H[2] = np.ones((1, 1))
        H[3] = np.array([[r]])
    return np.array([(1 + alpha) * r + bias - z])


