"""Residuals of the UWB factors GTSAM has no native factor for, with analytic Jacobians.

Tag position on a body X with lever arm b: p = R b + t (Pose3, tangent [rot, trans] in the body
frame: dp/dX = [-R [b]x, R]); on a planar body (Pose2, tangent [x, y, theta] in the body frame)
p = (R(theta) b_xy + t, b_z): dp/dX = [[R, R J b_xy], [0, 0]], J the 90-degree rotation.
"""

from __future__ import annotations

import gtsam
import numpy as np

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


def tag_to_tag_residual(pose_a, pose_b, b_a: np.ndarray, b_b: np.ndarray, z: float,
                        H: list | None = None) -> np.ndarray:
    """e = ||p_a - p_b|| - z: the range between tags on two robots (m); Jacobians w.r.t. both poses."""
    Ha, Hb = ([None], [None]) if H is not None else (None, None)
    d = tag_position(pose_a, b_a, Ha) - tag_position(pose_b, b_b, Hb)
    r = float(np.sqrt(d @ d))
    if H is not None:
        u = d / r if r > 0 else np.zeros(3)
        H[0] = (u @ Ha[0]).reshape(1, -1)
        H[1] = (-u @ Hb[0]).reshape(1, -1)
    return np.array([r - z])
