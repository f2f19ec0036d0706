"""SE(3) in GTSAM's conventions for many poses at once (numpy, leading axis N): twists are
[rotation (rad), translation (m)] and perturb a pose on the right, T Exp(xi); Jr is GTSAM's
`Pose3.ExpmapDerivative` and Jr^-1 its `LogmapDerivative` (docs/models/serial_arm.md#jacobians).
Poses are (N, 4, 4) homogeneous matrices, twists (N, 6)."""

from __future__ import annotations

import numpy as np

SMALL = 1e-2  # rad: below it the closed forms (cancelling: ~1e-7 relative at 1e-4) are replaced by their series to t^4


def skew(v: np.ndarray) -> np.ndarray:
    """(N, 3) -> (N, 3, 3) with skew(a) b = a x b."""
    out = np.zeros(v.shape[:-1] + (3, 3))
    out[..., 0, 1], out[..., 0, 2], out[..., 1, 2] = -v[..., 2], v[..., 1], -v[..., 0]
    out[..., 1, 0], out[..., 2, 0], out[..., 2, 1] = v[..., 2], -v[..., 1], v[..., 0]
    return out


def inverse(T: np.ndarray) -> np.ndarray:
    R, p = T[..., :3, :3], T[..., :3, 3]
    out = np.zeros_like(T)
    Rt = np.swapaxes(R, -1, -2)
    out[..., :3, :3] = Rt
    out[..., :3, 3] = -np.einsum("...ij,...j->...i", Rt, p)
    out[..., 3, 3] = 1.0
    return out


def adjoint(T: np.ndarray) -> np.ndarray:
    """Ad(T) (N, 6, 6): T Exp(xi) T^-1 = Exp(Ad(T) xi)."""
    R, p = T[..., :3, :3], T[..., :3, 3]
    out = np.zeros(T.shape[:-2] + (6, 6))
    out[..., :3, :3] = R
    out[..., 3:, 3:] = R
    out[..., 3:, :3] = skew(p) @ R
    return out


def _coefficients(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(sin t / t, (1 - cos t) / t^2, (t - sin t) / t^3), with series below SMALL."""
    t = np.where(theta < SMALL, 1.0, theta)
    t2 = theta ** 2
    small = theta < SMALL
    t4 = t2 * t2
    a = np.where(small, 1 - t2 / 6 + t4 / 120, np.sin(t) / t)
    b = np.where(small, 0.5 - t2 / 24 + t4 / 720, (1 - np.cos(t)) / t ** 2)
    c = np.where(small, 1 / 6 - t2 / 120 + t4 / 5040, (t - np.sin(t)) / t ** 3)
    return a, b, c


def exp(xi: np.ndarray) -> np.ndarray:
    """Exp of twists (N, 6) -> poses (N, 4, 4)."""
    w, v = xi[..., :3], xi[..., 3:]
    theta = np.linalg.norm(w, axis=-1)[..., None, None]
    a, b, c = _coefficients(theta)
    W = skew(w)
    W2 = W @ W
    eye = np.eye(3)
    out = np.zeros(xi.shape[:-1] + (4, 4))
    out[..., :3, :3] = eye + a * W + b * W2
    out[..., :3, 3] = np.einsum("...ij,...j->...i", eye + b * W + c * W2, v)
    out[..., 3, 3] = 1.0
    return out


def _so3_jr_inv(w: np.ndarray) -> np.ndarray:
    """Right Jacobian inverse of SO(3): I + W/2 + (1/t^2 - (1 + cos t)/(2 t sin t)) W^2."""
    theta = np.linalg.norm(w, axis=-1)[..., None, None]
    t = np.where(theta < SMALL, 1.0, theta)
    k = np.where(theta < SMALL, 1 / 12 + theta ** 2 / 720 + theta ** 4 / 30240,
                 1 / t ** 2 - (1 + np.cos(t)) / (2 * t * np.sin(t)))
    W = skew(w)
    return np.eye(3) + 0.5 * W + k * (W @ W)


def _q(xi: np.ndarray) -> np.ndarray:
    """The lower-left block of GTSAM's Pose3.ExpmapDerivative (Barfoot's Q with odd terms negated)."""
    w, v = xi[..., :3], xi[..., 3:]
    theta = np.linalg.norm(w, axis=-1)[..., None, None]
    W, V = skew(w), skew(v)
    WV, VW = W @ V, V @ W
    WVW = WV @ W
    small = theta < SMALL
    t = np.where(small, 1.0, theta)
    c1 = np.where(small, 1 / 6 - theta ** 2 / 120 + theta ** 4 / 5040, (t - np.sin(t)) / t ** 3)
    c2 = np.where(small, -1 / 24 + theta ** 2 / 720 - theta ** 4 / 40320, (1 - t ** 2 / 2 - np.cos(t)) / t ** 4)
    c3 = np.where(small, 1 / 120 - theta ** 2 / 2520 + theta ** 4 / 120960,
                  -0.5 * ((1 - t ** 2 / 2 - np.cos(t)) / t ** 4 - 3 * (t - np.sin(t) - t ** 3 / 6) / t ** 5))
    return (-0.5 * V + c1 * (WV + VW - WVW) + c2 * (W @ WV + VW @ W - 3 * WVW)
            + c3 * (WVW @ W + W @ WVW))


def jr(xi: np.ndarray) -> np.ndarray:
    """GTSAM's Pose3.ExpmapDerivative (N, 6, 6): Exp(xi + d) = Exp(xi) Exp(Jr(xi) d)."""
    w = xi[..., :3]
    theta = np.linalg.norm(w, axis=-1)[..., None, None]
    a, b, c = _coefficients(theta)
    W = skew(w)
    Jw = np.eye(3) - b * W + c * (W @ W)
    out = np.zeros(xi.shape[:-1] + (6, 6))
    out[..., :3, :3] = Jw
    out[..., 3:, 3:] = Jw
    out[..., 3:, :3] = _q(xi)
    return out


def jr_inv(xi: np.ndarray) -> np.ndarray:
    """GTSAM's Pose3.LogmapDerivative (N, 6, 6), the inverse of jr(xi)."""
    Ji = _so3_jr_inv(xi[..., :3])
    out = np.zeros(xi.shape[:-1] + (6, 6))
    out[..., :3, :3] = Ji
    out[..., 3:, 3:] = Ji
    out[..., 3:, :3] = -Ji @ _q(xi) @ Ji
    return out


def rotation_log(R: np.ndarray) -> np.ndarray:
    """Log of rotation matrices (..., 3, 3) -> rotation vectors (..., 3), angle in [0, pi]: through the
    unit quaternion taken from the largest of its four components (Shepperd), accurate up to pi."""
    d = np.stack([R[..., 0, 0], R[..., 1, 1], R[..., 2, 2]], axis=-1)
    trace = d.sum(axis=-1)
    candidates = np.concatenate([d, trace[..., None]], axis=-1)  # 4 q_i^2 - 1 for i = x, y, z, w (up to 1 + ...)
    pick = np.argmax(candidates, axis=-1)
    q = np.empty(R.shape[:-2] + (4,))
    for i in range(3):  # x, y, z largest
        j, k = (i + 1) % 3, (i + 2) % 3
        sel = pick == i
        Rs = R[sel]
        qi = np.sqrt(np.maximum(1 + 2 * Rs[:, i, i] - trace[sel], 0.0)) / 2
        q[sel, i] = qi
        q[sel, j] = (Rs[:, j, i] + Rs[:, i, j]) / (4 * qi)
        q[sel, k] = (Rs[:, k, i] + Rs[:, i, k]) / (4 * qi)
        q[sel, 3] = (Rs[:, k, j] - Rs[:, j, k]) / (4 * qi)
    sel = pick == 3
    Rs = R[sel]
    qw = np.sqrt(np.maximum(1 + trace[sel], 0.0)) / 2
    q[sel, 3] = qw
    q[sel, 0] = (Rs[:, 2, 1] - Rs[:, 1, 2]) / (4 * qw)
    q[sel, 1] = (Rs[:, 0, 2] - Rs[:, 2, 0]) / (4 * qw)
    q[sel, 2] = (Rs[:, 1, 0] - Rs[:, 0, 1]) / (4 * qw)
    q *= np.where(q[..., 3:] < 0, -1.0, 1.0)  # w >= 0: angle in [0, pi]
    v = q[..., :3]
    sin_half = np.linalg.norm(v, axis=-1)
    angle = 2 * np.arctan2(sin_half, q[..., 3])
    small = sin_half < 1e-12
    scale = np.where(small, 2.0 / np.where(q[..., 3] == 0, 1.0, q[..., 3]), angle / np.where(small, 1.0, sin_half))
    return v * scale[..., None]


def log(T: np.ndarray) -> np.ndarray:
    """Log of poses (N, 4, 4) -> twists (N, 6); the rotation angle in [0, pi]."""
    w = rotation_log(T[..., :3, :3])
    theta = np.linalg.norm(w, axis=-1)[..., None, None]
    t = np.where(theta < SMALL, 1.0, theta)
    k = np.where(theta < SMALL, 1 / 12 + theta ** 2 / 720 + theta ** 4 / 30240,
                 1 / t ** 2 - (1 + np.cos(t)) / (2 * t * np.sin(t)))
    W = skew(w)
    v = np.einsum("...ij,...j->...i", np.eye(3) - 0.5 * W + k * (W @ W), T[..., :3, 3])
    return np.concatenate([w, v], axis=-1)
