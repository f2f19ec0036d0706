"""The pixel residual of N observations at once, with analytic Jacobians.

A world point X (m) seen from a camera whose frame is the robot's body frame (x right, y down, z along the
optical axis) at pose T = (R, t):  p = R^T (X - t),  (x', y') = (p_x / p_z, p_y / p_z),
u = fx x' + s y' + u0,  v = fy y' + v0;  residual = (u, v) - measured (px).
Jacobians in GTSAM's coordinates: the pose perturbed on the right, T Exp([w, v]), so dp/dw = [p]_x and
dp/dv = -I; the intrinsics additively, [fx, fy, s, u0, v0].
"""

from __future__ import annotations

import numpy as np

from fusionkit.api import POSE3, VectorizedResidual

from .intrinsics import CAL3_S2


def _skew(p: np.ndarray) -> np.ndarray:
    out = np.zeros(p.shape[:-1] + (3, 3))
    out[..., 0, 1], out[..., 0, 2], out[..., 1, 2] = -p[..., 2], p[..., 1], -p[..., 0]
    return out - np.swapaxes(out, -1, -2)


def pixel_residual(x: list[np.ndarray], data: dict[str, np.ndarray], jacobians: bool):
    """x = [poses (N, 4, 4), intrinsics (N, 5)]; data: point (N, 3) world, pixel (N, 2) measured."""
    pose, k = x
    rotation, translation = pose[:, :3, :3], pose[:, :3, 3]
    p = np.einsum("nji,nj->ni", rotation, data["point"] - translation)
    if np.any(p[:, 2] <= 0):
        raise ValueError("a point lies behind the camera")
    xn, yn = p[:, 0] / p[:, 2], p[:, 1] / p[:, 2]
    fx, fy, s, u0, v0 = k.T
    residual = np.column_stack([fx * xn + s * yn + u0, fy * yn + v0]) - data["pixel"]
    if not jacobians:
        return residual
    n = len(p)
    d_normalized = np.zeros((n, 2, 3))
    d_normalized[:, 0, 0] = d_normalized[:, 1, 1] = 1 / p[:, 2]
    d_normalized[:, 0, 2], d_normalized[:, 1, 2] = -xn / p[:, 2], -yn / p[:, 2]
    d_pixel = np.zeros((n, 2, 2))
    d_pixel[:, 0, 0], d_pixel[:, 0, 1], d_pixel[:, 1, 1] = fx, s, fy
    d_point = d_pixel @ d_normalized  # (N, 2, 3): d pixel / d p
    d_pose = np.concatenate([d_point @ _skew(p), -d_point], axis=2)
    d_k = np.zeros((n, 2, 5))
    d_k[:, 0, 0], d_k[:, 0, 2], d_k[:, 0, 3] = xn, yn, 1.0
    d_k[:, 1, 1], d_k[:, 1, 4] = yn, 1.0
    return residual, [d_pose, d_k]


PIXEL = VectorizedResidual("camera.pixel", (POSE3, CAL3_S2), 2, pixel_residual)
