"""Pure pose residuals with analytic Jacobians (right-perturbation, GTSAM tangent order [rot, trans])."""

from __future__ import annotations

import numpy as np

from fusionkit.api import POSE3, SCALAR, VectorizedResidual, lie


def scaled_between(x: list[np.ndarray], data: dict[str, np.ndarray], jacobians: bool):
    """Relative pose with unknown scale (thesis eq. 4.3,
    docs/models/cable_rigid.md#scaled-visual-odometry) for N factors: the sensor reports (R, t / s).
    x = [xa (N, 4, 4), xb (N, 4, 4), s (N,)], data["measured"] (N, 4, 4).

    The residual lives in the sensor's own units, where its noise does not depend on s:
    B = xa^-1 xb, B_s = (R_B, t_B / s), e = Log(measured^-1 B_s) (rotation rad, translation in
    sensor units). (A residual in metres, Log((R, s t)^-1 B), lets the noise grow with s and biases
    the scale low.) With D = diag(I, I/s), E = measured^-1 B_s and Jr^-1 at e:
    d/dxb = Jr^-1 D;  d/dxa = -Jr^-1 D Ad(B^-1);  d/ds = Jr^-1 [0; -R_B^T t_B / s^2].
    """
    xa, xb, s = x
    between = lie.inverse(xa) @ xb
    scaled = between.copy()
    scaled[:, :3, 3] /= s[:, None]
    e = lie.log(lie.inverse(data["measured"]) @ scaled)
    if not jacobians:
        return e
    j_inv = lie.jr_inv(e)
    jd = j_inv.copy()
    jd[:, :, 3:] /= s[:, None, None]
    local_t = np.einsum("nji,nj->ni", between[:, :3, :3], between[:, :3, 3])  # R_B^T t_B
    d_scale = j_inv[:, :, 3:] @ (-local_t / s[:, None] ** 2)[:, :, None]
    return e, [-jd @ lie.adjoint(lie.inverse(between)), jd, d_scale]


SCALED_BETWEEN = VectorizedResidual("pose.scaled_relative", (POSE3, POSE3, SCALAR), 6, scaled_between)


def co_registrations(x: list[np.ndarray], data: dict[str, np.ndarray], jacobians: bool):
    """Robot a observes robot b (N at once): z = a_T_b; robot b's pose xb lives in its own base frame,
    `base` W = worldA_T_baseB. With M = xa^-1 W xb and E = z^-1 M: e = Log(E) (rad, m). Jacobians, Jr^-1 at
    e: d/dxb = Jr^-1; d/dW = Jr^-1 Ad(xb^-1); d/dxa = -Jr^-1 Ad(M^-1). x = [xa, W, xb] (N, 4, 4), data z
    (N, 4, 4)."""
    xa, base, xb = x
    M = lie.inverse(xa) @ base @ xb
    e = lie.log(lie.inverse(data["z"]) @ M)
    if not jacobians:
        return e
    j = lie.jr_inv(e)
    return e, [-j @ lie.adjoint(lie.inverse(M)), j @ lie.adjoint(lie.inverse(xb)), j]


CO_REGISTRATION = VectorizedResidual("pose.co_registration", (POSE3, POSE3, POSE3), 6, co_registrations)
