"""Central-difference Jacobians of a GTSAM factor's whitened error on the manifold."""

from __future__ import annotations

import gtsam
import numpy as np


def _delta(dims: dict[int, int], key: int, d: np.ndarray) -> gtsam.VectorValues:
    out = gtsam.VectorValues()
    for k, n in dims.items():
        out.insert(k, d if k == key else np.zeros(n))
    return out


def numerical_jacobians(factor: gtsam.NonlinearFactor, values: gtsam.Values,
                        step: float = 1e-6) -> list[np.ndarray]:
    """d whitenedError / d delta for each key of `factor`, with x = values.retract(delta)."""
    zero = values.zeroVectors()
    dims = {k: zero.at(k).shape[0] for k in values.keys()}
    out = []
    for key in factor.keys():
        J = np.empty((factor.dim(), dims[key]))
        for j in range(dims[key]):
            d = np.zeros(dims[key])
            d[j] = step
            plus = factor.whitenedError(values.retract(_delta(dims, key, d)))
            minus = factor.whitenedError(values.retract(_delta(dims, key, -d)))
            J[:, j] = (plus - minus) / (2 * step)
        out.append(J)
    return out
