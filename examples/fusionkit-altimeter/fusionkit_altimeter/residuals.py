"""Layer 3: the pure residual with analytic Jacobians. No keys, no Values, no config: plain
inputs in, error (and Jacobians) out, so it can be tested and reused on its own.

Conventions are GTSAM's: a Pose3 X = (R, t) is perturbed on the right, X' = X * Exp(xi) with
xi = [rotation (3), translation (3)] in the body frame, so to first order t' = t + R xi_trans and
the rotation part of xi does not move t.
"""

from __future__ import annotations

import gtsam
import numpy as np


def height_residual(pose: gtsam.Pose3, bias: float, measured: float,
                    H: list | None = None) -> np.ndarray:
    """Altimeter error e = t_z(pose) + bias - measured (m), shape (1,).

    When `H` is given, H[0] = de/dxi (1x6) and H[1] = de/dbias (1x1) are written into it:
    de/dxi_rot = 0 and de/dxi_trans = d t_z / d xi_trans = third row of R.
    """
    error = np.array([pose.translation()[2] + bias - measured])
    if H is not None:
        R = pose.rotation().matrix()
        H[0] = np.concatenate([np.zeros(3), R[2, :]]).reshape(1, 6)
        H[1] = np.ones((1, 1))
    return error
