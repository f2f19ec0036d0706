"""Pure pose residuals with analytic Jacobians (right-perturbation, GTSAM tangent order [rot, trans])."""

from __future__ import annotations

import gtsam
import numpy as np


def scaled_between_residual(xa: gtsam.Pose3, xb: gtsam.Pose3, scale: float, rot: gtsam.Rot3,
                            t_unscaled: np.ndarray, H: list | None = None) -> np.ndarray:
    """Relative pose with unknown scale (spec eq. 4.3): the sensor reports (R, t / s).

    Measurement Z(s) = (R, s * t_unscaled); error e = Log(E), E = Z(s)^-1 xa^-1 xb.
    Jacobians (written into H when given), with Jr^-1 the inverse right Jacobian at e:
    d/dxb = Jr^-1;  d/dxa = -Jr^-1 Ad((xa^-1 xb)^-1);  d/ds = -Jr^-1 Ad(E^-1) [0; R^T t_unscaled]
    (Z(s + ds) = Z(s) Exp([0, R^T t ds])).
    """
    between = xa.between(xb)
    err = gtsam.Pose3(rot, scale * t_unscaled).between(between)
    e = gtsam.Pose3.Logmap(err)
    if H is not None:
        j_inv = gtsam.Pose3.LogmapDerivative(e)
        H[0] = -j_inv @ between.inverse().AdjointMap()
        H[1] = j_inv
        dz_ds = np.concatenate([np.zeros(3), rot.unrotate(t_unscaled)])
        H[2] = -(j_inv @ (err.inverse().AdjointMap() @ dz_ds)).reshape(6, 1)
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
