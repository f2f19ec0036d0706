"""Linear solves by QR instead of Cholesky, for graphs too ill-conditioned for the normal equations.

Cholesky factors A^T A, whose condition number is the square of A's: a whitened Jacobian with
condition 1e8 (heavy sagging cables: the equilibrium orientation moves the catenaries by metres
per milliradian, while pulleys are seen through a few poses) is already singular to it. QR
factors A itself (GTSAM's EliminateQR; `solver.factorization: qr`).
"""

from __future__ import annotations

import gtsam
import numpy as np


def eliminate(linear: gtsam.GaussianFactorGraph, qr: bool):
    """The multifrontal Bayes tree of `linear` (COLAMD ordering), by QR or Cholesky."""
    if not qr:
        return linear.eliminateMultifrontal()
    return linear.eliminateMultifrontal(gtsam.Ordering.ColamdGaussianFactorGraph(linear), gtsam.EliminateQR)


def solve_linear(linear: gtsam.GaussianFactorGraph, qr: bool) -> gtsam.VectorValues:
    return linear.optimize() if not qr else eliminate(linear, True).optimize()


def qr_marginals(graph: gtsam.NonlinearFactorGraph, values: gtsam.Values, keys: set[int]) -> dict[int, np.ndarray]:
    """Marginal covariances (tangent space at `values`) from a dense QR of the whitened Jacobian:
    Cov = (R^T R)^-1, without forming A^T A. Dense: meant for the graphs that need QR (hundreds to
    a few thousand unknowns), not for long trajectories."""
    linear = graph.linearize(values)
    order = sorted(values.keys())
    zero = values.zeroVectors()
    dims = [zero.at(k).shape[0] for k in order]
    start = dict(zip(order, np.concatenate([[0], np.cumsum(dims)[:-1]]).astype(int)))
    n = int(sum(dims))
    rows, cols, vals = linear.sparseJacobian_()
    rows, cols = rows.astype(int) - 1, cols.astype(int) - 1
    keep = cols < n  # the last column is the right-hand side
    A = np.zeros((int(rows.max()) + 1, n))
    A[rows[keep], cols[keep]] = vals[keep]
    R = np.linalg.qr(A, mode="r")
    R_inv = np.linalg.solve(R, np.eye(n))  # Cov = R^-1 R^-T
    out = {}
    for k in keys:
        s, d = start[k], zero.at(k).shape[0]
        block = R_inv[s:s + d]
        out[k] = block @ block.T
    return out
