"""Pure serial-arm residuals with analytic Jacobians (docs/models/serial_arm.md#factors).

Each takes the chain, the layout of the kinematic-parameter variables, joint values and the
parameters' values (kinematics.py), and the measurement; when `H` is given it receives one Jacobian
per variable in key order: the joint vector(s), then the layout's variables. GTSAM's conventions:
poses perturbed on the right, tangent [rotation, translation].
"""

from __future__ import annotations

import gtsam
import numpy as np

from .chain import SerialChain, adjoint, inverse
from .kinematics import Layout, Parameters, marker_pose


def tool_pose_residual(chain: SerialChain, layout: Layout, q: np.ndarray, p: Parameters, measured: gtsam.Pose3,
                       H: list | None = None) -> np.ndarray:
    """6-D tracker: e = Log(measured^-1 T), T = meas_T_marker; d e/d x = Jr^-1(e) d twist/d x."""
    T, blocks = marker_pose(chain, layout, q, p, H is not None)
    e = gtsam.Pose3.Logmap(gtsam.Pose3(measured.inverse().matrix() @ T))
    if H is not None:
        j_inv = gtsam.Pose3.LogmapDerivative(e)
        for i, block in enumerate(blocks):
            H[i] = j_inv @ block
    return e


def tool_position_residual(chain: SerialChain, layout: Layout, q: np.ndarray, p: Parameters, measured: np.ndarray,
                           H: list | None = None) -> np.ndarray:
    """Laser tracker: e = t(T) - measured (m); the marker origin moves by R dv under a twist (dw, dv)."""
    T, blocks = marker_pose(chain, layout, q, p, H is not None)
    if H is not None:
        R = T[:3, :3]
        for i, block in enumerate(blocks):
            H[i] = R @ block[3:]
    return T[:3, 3] - np.asarray(measured, float)


def relative_tool_pose_residual(chain: SerialChain, layout: Layout, qa: np.ndarray, qb: np.ndarray, p: Parameters,
                                measured: gtsam.Pose3, H: list | None = None) -> np.ndarray:
    """Marker motion between configurations a and b: e = Log(measured^-1 Ta^-1 Tb) (the base cancels).
    With D = Ta^-1 Tb: d D/d twist_b = I, d D/d twist_a = -Ad(D^-1); shared parameters add both."""
    Ta, blocks_a = marker_pose(chain, layout, qa, p, H is not None)
    Tb, blocks_b = marker_pose(chain, layout, qb, p, H is not None)
    D = inverse(Ta) @ Tb
    e = gtsam.Pose3.Logmap(gtsam.Pose3(measured.inverse().matrix() @ D))
    if H is not None:
        j_inv = gtsam.Pose3.LogmapDerivative(e)
        back = -j_inv @ adjoint(inverse(D))
        H[0] = back @ blocks_a[0]
        H[1] = j_inv @ blocks_b[0]
        for i, (a, b) in enumerate(zip(blocks_a[1:], blocks_b[1:])):
            H[2 + i] = back @ a + j_inv @ b
    return e


def held_axes_residual(vartype: str, value, x, axes: list[int], H: list | None = None) -> np.ndarray:
    """The chosen tangent axes of x away from `value` (a pose3: Log(value^-1 x); a vector or scalar:
    x - value): holds those axes of an unidentifiable parameter (docs/models/serial_arm.md#identifiability)."""
    if vartype == "pose3":
        full = gtsam.Pose3.Logmap(value.between(x))
        J = gtsam.Pose3.LogmapDerivative(full)
    else:
        full = np.atleast_1d(np.asarray(x, float) - np.asarray(value, float))
        J = np.eye(len(full))
    if H is not None:
        H[0] = J[axes]
    return full[axes]
