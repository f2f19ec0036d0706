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


def fit_range_origin(points: np.ndarray, ranges: np.ndarray) -> tuple[np.ndarray, float, float]:
    """Where ranges are measured from, and their constant offset: the least-squares a, c of
    z_k = ||q_k - a|| + c over known points q_k (K, d), d = 2 or 3 (m). A rigid cable is this model
    with a = pulley, c = encoder offset; a UWB anchor with a constant bias is too.

    Closed form (linear multilateration): squaring ||q - a|| = z - c gives
        2 q.a - 2 z c + (c^2 - |a|^2) = |q|^2 - z^2,
    linear in (a, c, w = c^2 - |a|^2); points and ranges are centred first for conditioning.
    Returns (a, c, rms of the residuals z - ||q - a|| - c). Raises ValueError when the points do
    not determine a and c (fewer than d + 2, or all on one plane or line)."""
    q, z = np.asarray(points, float), np.asarray(ranges, float)
    d = q.shape[1]
    if len(q) < d + 2:
        raise ValueError(f"{len(q)} points; a range origin with an offset needs at least {d + 2}")
    q0, z0 = q.mean(axis=0), z.mean()
    qc, zc = q - q0, z - z0  # in centred coordinates a' = a - q0, c' = c - z0
    A = np.column_stack([2 * qc, -2 * zc, np.ones(len(q))])
    b = np.einsum("ki,ki->k", qc, qc) - zc * zc
    scale = np.abs(A).max(axis=0)
    scale[scale == 0] = 1.0
    sol, _, rank, sv = np.linalg.lstsq(A / scale, b, rcond=None)
    if rank < d + 2 or sv[-1] < 1e-9 * sv[0]:
        raise ValueError(f"the points do not span {d}-D space around the origin (rank {rank}/{d + 2}): "
                         "move along all axes")
    sol = sol / scale
    a, c = sol[:d] + q0, sol[d] + z0
    rms = float(np.sqrt(np.mean((z - np.linalg.norm(q - a, axis=1) - c) ** 2)))
    return a, float(c), rms


def range_factor(pose_key: int, point_key: int, z: float, noise, mount, bias_key: int | None = None):
    """The native GTSAM factor of z = ||X mount - a|| (+ bias): the body point `mount` (a Pose3
    or Pose2: its translation is the point on the body) of pose X to the point a, with an additive
    bias variable when `bias_key` is given. A rigid cable (a = pulley, bias = encoder offset) and a
    UWB range (a = anchor, bias = range bias) are both this factor."""
    if isinstance(mount, gtsam.Pose2):
        if bias_key is None:
            return gtsam.RangeFactorWithTransform2D(pose_key, point_key, float(z), noise, mount)
        return gtsam.RangeFactorWithTransformBias2D(pose_key, point_key, bias_key, float(z), noise, mount)
    if bias_key is None:
        return gtsam.RangeFactorWithTransform3D(pose_key, point_key, float(z), noise, mount)
    return gtsam.RangeFactorWithTransformBias3D(pose_key, point_key, bias_key, float(z), noise, mount)
