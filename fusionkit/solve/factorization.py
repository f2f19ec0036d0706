"""How the batch solvers solve each linear system: the factorization and the elimination ordering.

Cholesky factors A^T A, whose condition number is the square of A's: a whitened Jacobian with
condition 1e8 (heavy sagging cables: the equilibrium orientation moves the catenaries by metres
per milliradian, while pulleys are seen through a few poses) is already singular to it. QR
factors A itself (GTSAM's EliminateQR; `solver.factorization: qr`).

GTSAM orders the elimination by COLAMD. Where a few variables touch nearly every factor (UWB
anchors and time-varying biases along a 10,000-epoch trajectory) METIS's nested dissection
eliminates 9 times faster (0.21 s vs 1.9 s measured); `solver.ordering: metis`.
"""

from __future__ import annotations

import gtsam
import numpy as np


def linear_settings(settings: dict) -> tuple[bool, str]:
    """(qr, ordering) of a batch solver's resolved settings: `factorization` and `ordering`."""
    return settings["factorization"] == "qr", settings["ordering"]


def eliminate(linear: gtsam.GaussianFactorGraph, qr: bool, ordering: str = "colamd"):
    """The multifrontal Bayes tree of `linear` (COLAMD or METIS ordering), by QR or Cholesky."""
    if not qr and ordering == "colamd":
        return linear.eliminateMultifrontal()
    order = (gtsam.Ordering.MetisGaussianFactorGraph(linear) if ordering == "metis"
             else gtsam.Ordering.ColamdGaussianFactorGraph(linear))
    return linear.eliminateMultifrontal(order, gtsam.EliminateQR) if qr else linear.eliminateMultifrontal(order)


def solve_linear(linear: gtsam.GaussianFactorGraph, qr: bool, ordering: str = "colamd") -> gtsam.VectorValues:
    if not qr and ordering == "colamd":
        return linear.optimize()
    return eliminate(linear, qr, ordering).optimize()


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
