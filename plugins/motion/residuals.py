"""The constant-velocity residual with analytic Jacobians (right perturbation, GTSAM tangent order)."""

from __future__ import annotations

import numpy as np

from fusionkit.api import POSE2, POSE3, VectorizedResidual, lie, se2


def constant_velocity(x: list[np.ndarray], data: dict[str, np.ndarray], jacobians: bool):
    """Constant body-frame twist across three states (N at once): e = Log(X0^-1 X1)/dt1 - Log(X1^-1 X2)/dt2,
    data dt1, dt2 (N,) in s; Pose3 (N, 4, 4) or Pose2 (N, 3). With B = Xa^-1 Xb, d Log(B) / d Xa = -Jr^-1 Ad(B^-1)
    and d / d Xb = Jr^-1."""
    x0, x1, x2 = x
    dt1, dt2 = data["dt1"][:, None], data["dt2"][:, None]
    if x0.ndim == 2:
        group, b1, b2 = se2, se2.between(x0, x1), se2.between(x1, x2)
    else:
        group, b1, b2 = lie, lie.inverse(x0) @ x1, lie.inverse(x1) @ x2
    xi1, xi2 = group.log(b1), group.log(b2)
    e = xi1 / dt1 - xi2 / dt2
    if not jacobians:
        return e
    j1, j2 = group.jr_inv(xi1) / dt1[:, :, None], group.jr_inv(xi2) / dt2[:, :, None]
    return e, [-j1 @ group.adjoint(group.inverse(b1)), j1 + j2 @ group.adjoint(group.inverse(b2)), -j2]


CONSTANT_VELOCITY = {planar: VectorizedResidual("motion.constant_velocity", (t, t, t), t.dim, constant_velocity)
                     for planar, t in ((False, POSE3), (True, POSE2))}
