"""Rotation matrices to unit quaternions in bulk, with the bits gtsam's Rot3.toQuaternion() gives.

Rot3.toQuaternion() is Eigen's Quaternion(Matrix3): Shoemake's method ("Quaternion Calculus and
Fast Animation", Ken Shoemake, SIGGRAPH 1987 course notes). The same floating-point operations in
the same order, on numpy arrays, give the same numbers without a Python call per rotation.
"""

from __future__ import annotations

import numpy as np


def quaternions_xyzw(rotations: np.ndarray) -> np.ndarray:
    """(n, 4) quaternions x y z w of (n, 3, 3) rotation matrices, each equal to Rot3.toQuaternion()."""
    r = np.asarray(rotations, dtype=float).reshape(-1, 3, 3)
    q = np.empty((len(r), 4))
    trace = r[:, 0, 0] + (r[:, 1, 1] + r[:, 2, 2])  # Eigen's order of the sum
    pos = trace > 0
    m = r[pos]
    t = np.sqrt(trace[pos] + 1.0)
    q[pos, 3] = 0.5 * t
    t = 0.5 / t
    q[pos, 0] = (m[:, 2, 1] - m[:, 1, 2]) * t
    q[pos, 1] = (m[:, 0, 2] - m[:, 2, 0]) * t
    q[pos, 2] = (m[:, 1, 0] - m[:, 0, 1]) * t
    # trace <= 0: start from the largest diagonal element i (the first of equal ones), then j, k cyclic
    rows = np.flatnonzero(~pos)
    m, n = r[rows], np.arange(len(rows))
    i = np.where(m[:, 1, 1] > m[:, 0, 0], 1, 0)
    i = np.where(m[:, 2, 2] > m[n, i, i], 2, i)
    j, k = (i + 1) % 3, (i + 2) % 3
    t = np.sqrt(m[n, i, i] - m[n, j, j] - m[n, k, k] + 1.0)
    sub = np.empty((len(rows), 4))
    sub[n, i] = 0.5 * t
    t = 0.5 / t
    sub[:, 3] = (m[n, k, j] - m[n, j, k]) * t
    sub[n, j] = (m[n, j, i] + m[n, i, j]) * t
    sub[n, k] = (m[n, k, i] + m[n, i, k]) * t
    q[rows] = sub
    return q
