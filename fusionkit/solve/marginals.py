"""Marginal covariances of many variables from one multifrontal Cholesky elimination (what
gtsam.Marginals does), with a shortcut for cliques that share a separator.

A clique's conditional R x_F + S x_S = d and the joint marginal covariance C_S of its separator give
the covariance of its frontal variables exactly: Cov(x_F) = R^-1 R^-T + (R^-1 S) C_S (R^-1 S)^T. Where
many cliques hang on the same separator (a thousand joint states of an arm, each linked only to the
same kinematic parameters), C_S is computed once for all of them instead of once per variable
(measured: 1016 variables of a 7-joint arm, 1.5 s -> 0.19 s). Other variables (the separators of a
trajectory differ from clique to clique) go through GTSAM's per-variable marginal, as before.
"""

from __future__ import annotations

import gtsam
import numpy as np

from ..graph.evaluator import GraphEvaluator


def frontal_count(cond: gtsam.GaussianConditional, dims: gtsam.VectorValues) -> int:
    """How many of the conditional's keys are frontal (their dimensions add up to R's rows)."""
    keys, rows, d, n = cond.keys(), cond.R().shape[0], 0, 0
    while d < rows:
        d += dims.at(keys[n]).shape[0]
        n += 1
    return n


def tree_marginals(graph: GraphEvaluator | gtsam.NonlinearFactorGraph, values: gtsam.Values, keys: set[int]) -> dict[int, np.ndarray]:
    """Marginal covariance (tangent space at `values`) of each key."""
    import scipy.linalg
    tree = graph.linearize(values).eliminateMultifrontal()
    dims = values.zeroVectors()
    cliques: dict[int, gtsam.GaussianConditional] = {}
    for key in keys:
        cond = tree[key].conditional()
        cliques.setdefault(cond.firstFrontalKey(), cond)
    by_separator: dict[tuple, list] = {}
    for cond in cliques.values():
        n = frontal_count(cond, dims)
        by_separator.setdefault(tuple(cond.keys()[n:]), []).append((cond, cond.keys()[:n]))
    out: dict[int, np.ndarray] = {}
    for separator, members in by_separator.items():
        if len(members) < 2 or not separator:
            out.update({k: np.asarray(tree.marginalCovariance(k)) for _, frontal in members for k in frontal
                        if k in keys})
            continue
        separator_cov = tree.jointMarginalCovariance(list(separator)).fullMatrix()
        for cond, frontal in members:
            R = cond.R()
            R_inv = scipy.linalg.solve_triangular(R, np.eye(len(R)))
            X = R_inv @ cond.S()
            cov = R_inv @ R_inv.T + X @ separator_cov @ X.T
            start = 0
            for k in frontal:
                d = dims.at(k).shape[0]
                if k in keys:
                    out[k] = cov[start:start + d, start:start + d]
                start += d
    return out
