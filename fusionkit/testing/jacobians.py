"""Central-difference Jacobians of a GTSAM factor's whitened error on the manifold."""

from __future__ import annotations

import gtsam
import numpy as np


def numerical_jacobians(factor: gtsam.NonlinearFactor, values: gtsam.Values,
                        step: float = 1e-6) -> list[np.ndarray]:
    """d whitenedError / d delta for each key of `factor`, with x = values.retract(delta)."""
    zero = values.zeroVectors()
    out = []
    for key in factor.keys():
        dim = zero.at(key).shape[0]
        J = np.empty((factor.dim(), dim))
        for j in range(dim):
            d = np.zeros(dim)
            d[j] = step
            plus, minus = gtsam.VectorValues(zero), gtsam.VectorValues(zero)
            plus.update(key, d)
            minus.update(key, -d)
            J[:, j] = (factor.whitenedError(values.retract(plus)) -
                       factor.whitenedError(values.retract(minus))) / (2 * step)
        out.append(J)
    return out
