"""Pure residuals of the RCM arm's factors with analytic Jacobians (docs/models/arash.md).

Variables in the order of the factors' keys: joints q (vector3: phi, psi, d), then the scalars
alpha, theta, l_1234; a base-to-base transform W (Pose3) is perturbed on the right, tangent
[rotation, translation], as everywhere in GTSAM. Lengths are in the convention's unit (m or mm).
"""

from __future__ import annotations

import gtsam
import numpy as np

from .kinematics import tip_jacobians, tip_position


def tool_position_residual(q: np.ndarray, k: np.ndarray, z: np.ndarray, convention: str,
                           H: list | None = None) -> np.ndarray:
    """A tracker sees the tool tip in the arm's base frame: e = p(q, k) - z, shape (3,).
    H (when given) receives de/dq (3x3) and de/dalpha, de/dtheta, de/dl_1234 (3x1 each)."""
    if H is None:
        return tip_position(q, k, convention) - z
    p, jq, jk = tip_jacobians(q, k, convention)
    H[0] = jq
    for i in range(3):
        H[1 + i] = jk[:, i:i + 1]
    return p - z


def tool_to_tool_residual(qa: np.ndarray, ka: np.ndarray, qb: np.ndarray, kb: np.ndarray, base: gtsam.Pose3,
                          z: np.ndarray, convention: str, H: list | None = None) -> np.ndarray:
    """Arm b's tip seen from arm a's tip, in a's base frame: e = W p_b - p_a - z, with W = a_T_b the
    pose of b's base in a's (z = 0: the tips coincide). H receives, in key order, de/dqa,
    de/d(alpha, theta, l_1234)_a, de/dqb, de/d(alpha, theta, l_1234)_b and de/dW (3x6)."""
    if H is None:
        return base.transformFrom(tip_position(qb, kb, convention)) - tip_position(qa, ka, convention) - z
    pa, jqa, jka = tip_jacobians(qa, ka, convention)
    pb, jqb, jkb = tip_jacobians(qb, kb, convention)
    h_base, h_point = np.zeros((3, 6), order="F"), np.zeros((3, 3), order="F")
    seen = base.transformFrom(pb, h_base, h_point)
    H[0] = -jqa
    for i in range(3):
        H[1 + i] = -jka[:, i:i + 1]
    H[4] = h_point @ jqb
    for i in range(3):
        H[5 + i] = h_point @ jkb[:, i:i + 1]
    H[8] = h_base
    return seen - pa - z
