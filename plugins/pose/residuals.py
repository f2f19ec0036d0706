"""Pure pose residuals with analytic Jacobians (right-perturbation, GTSAM tangent order [rot, trans])."""

from __future__ import annotations

import gtsam
import numpy as np


def scaled_between_residual(xa: gtsam.Pose3, xb: gtsam.Pose3, scale: float, measured: gtsam.Pose3,
                            H: list | None = None) -> np.ndarray:
    """Relative pose with unknown scale (thesis eq. 4.3,
    docs/models/cable_rigid.md#scaled-visual-odometry): the sensor reports (R, t / s).

    The residual lives in the sensor's own units, where its noise does not depend on s:
    B = xa^-1 xb, B_s = (R_B, t_B / s), e = Log(measured^-1 B_s) (rotation rad, translation in
    sensor units). (A residual in metres, Log((R, s t)^-1 B), lets the noise grow with s and biases
    the scale low.) With D = diag(I, I/s), E = measured^-1 B_s and Jr^-1 at e:
    d/dxb = Jr^-1 D;  d/dxa = -Jr^-1 D Ad(B^-1);  d/ds = Jr^-1 [0; -R_B^T t_B / s^2].
    """
    between = xa.between(xb)
    t = between.translation()
    err = measured.between(gtsam.Pose3(between.rotation(), t / scale))
    e = gtsam.Pose3.Logmap(err)
    if H is not None:
        j_inv = gtsam.Pose3.LogmapDerivative(e)
        jd = j_inv.copy()
        jd[:, 3:] /= scale
        H[1] = jd
        H[0] = -jd @ between.inverse().AdjointMap()
        H[2] = (j_inv[:, 3:] @ (-between.rotation().unrotate(t) / scale**2)).reshape(6, 1)
    return e


def co_registration_residual(xa: gtsam.Pose3, base: gtsam.Pose3, xb: gtsam.Pose3, z: gtsam.Pose3,
                             H: list | None = None) -> np.ndarray:
    """Robot a observes robot b: z = a_T_b. Robot b's pose xb lives in its own base frame,
    `base` = worldA_T_baseB. error = Log(z^-1 xa^-1 base xb)."""
    if H is None:
        return gtsam.Pose3.Logmap(z.between(xa.between(base.compose(xb))))
    Hw, Hxb = np.zeros((6, 6), order="F"), np.zeros((6, 6), order="F")
    world_b = base.compose(xb, Hw, Hxb)
    Hxa, Hwb = np.zeros((6, 6), order="F"), np.zeros((6, 6), order="F")
    rel = xa.between(world_b, Hxa, Hwb)
    Hz, Hrel = np.zeros((6, 6), order="F"), np.zeros((6, 6), order="F")
    err = z.between(rel, Hz, Hrel)
    Hl = np.zeros((6, 6), order="F")
    e = gtsam.Pose3.Logmap(err, Hl)
    HlHrel = Hl @ Hrel
    H[0] = HlHrel @ Hxa
    H[1] = HlHrel @ Hwb @ Hw
    H[2] = HlHrel @ Hwb @ Hxb
    return e
