"""Marginal covariances from a Bayes tree by one top-down pass. Each clique's conditional
R x_F + S x_S = d gives the joint covariance of its variables from its separator's, which its parent holds
(running intersection):

    C_SS from the parent,  X = R^-1 S,  C_FF = R^-1 R^-T + X C_SS X^T,  C_FS = -X C_SS.

One pass from the roots down, each clique's work cubic in its own size: time linear in the number of
cliques (GTSAM's per-variable marginal computes each variable's clique from the root again: 0.2 ms a
variable on a UWB trajectory, several times this pass), and a dense inverse of the whole system is cubic in its size. The
tree is a multifrontal Cholesky elimination (`tree_marginals`, what gtsam.Marginals does) or, for graphs too
ill-conditioned for it, a sparse QR of the whitened Jacobian (`recovered_marginals`). The same pass gives
every factor's joint covariance of its variables (they lie in one clique), which the noise-scale estimate
needs (noise_scales.py).
"""

from __future__ import annotations

from typing import Iterator

import gtsam
import numpy as np

from ..graph.evaluator import GraphEvaluator
from .factorization import eliminate


def frontal_count(keys: list[int], rows: int, dims: dict[int, int]) -> int:
    """How many of a conditional's keys are frontal (their dimensions add up to its R's rows)."""
    d = n = 0
    while d < rows:
        d += dims[keys[n]]
        n += 1
    return n


def tree_marginals(graph: GraphEvaluator | gtsam.NonlinearFactorGraph, values: gtsam.Values,
                   keys: set[int], linear: gtsam.GaussianFactorGraph | None = None) -> dict[int, np.ndarray]:
    """Marginal covariance (tangent space at `values`) of each key, from the Cholesky Bayes tree (of `linear`, the
    graph linearized at `values`, when given)."""
    linear = graph.linearize(values) if linear is None else linear
    return marginals_from_tree(linear.eliminateMultifrontal(), values, keys)


def recovered_marginals(graph: GraphEvaluator | gtsam.NonlinearFactorGraph, values: gtsam.Values, keys: set[int],
                        ordering: str = "colamd", linear: gtsam.GaussianFactorGraph | None = None
                        ) -> dict[int, np.ndarray]:
    """Marginal covariance (tangent space at `values`) of each key, from the QR Bayes tree."""
    linear = graph.linearize(values) if linear is None else linear
    return marginals_from_tree(eliminate(linear, True, ordering), values, keys)


def marginals_from_tree(tree: gtsam.GaussianBayesTree, values: gtsam.Values, keys: set[int]) -> dict[int, np.ndarray]:
    """Each key's marginal covariance (each key is frontal in one clique); a clique's joint covariance is
    dropped once all its children have theirs."""
    out: dict[int, np.ndarray] = {}
    for _, frontal, index, C in _top_down(tree, values, keep=False):
        for k in frontal:
            if k in keys:
                out[k] = C[index[k], index[k]].copy()
    return out


def clique_covariances(tree: gtsam.GaussianBayesTree, values: gtsam.Values
                       ) -> tuple[dict[int, int], dict[int, tuple[dict[int, slice], np.ndarray]]]:
    """(the clique each key is frontal in, each clique's (key -> rows, joint covariance of its frontal and
    separator variables)); cliques are named by their first frontal key."""
    clique_of: dict[int, int] = {}
    joint = {}
    for first, frontal, index, C in _top_down(tree, values, keep=True):
        clique_of.update(dict.fromkeys(frontal, first))
        joint[first] = (index, C)
    return clique_of, joint


def _top_down(tree: gtsam.GaussianBayesTree, values: gtsam.Values, keep: bool) -> Iterator:
    """The cliques parents first, each as (its first frontal key, its frontal keys, key -> rows, joint
    covariance of its frontal and separator variables). `keep=False` drops a clique's joint covariance once
    all its children have theirs."""
    from scipy.linalg.lapack import dtrtri  # the inverse of a triangular matrix, without scipy.linalg's checks
    dims = values.dims()
    cliques, parent_of = {}, {}
    for key in values.keys():
        clique = tree[key]
        first = clique.conditional().firstFrontalKey()
        if first not in cliques:
            cliques[first] = clique
            parent_of[first] = None if clique.isRoot() else clique.parent().conditional().firstFrontalKey()
    order, done = [], set()  # parents before children
    for c in cliques:
        chain = []
        while c is not None and c not in done:
            chain.append(c)
            c = parent_of[c]
        done.update(chain)
        order.extend(reversed(chain))
    children_left = {c: 0 for c in cliques}
    for c in cliques:
        if parent_of[c] is not None:
            children_left[parent_of[c]] += 1
    joint: dict[int, tuple[dict[int, slice], np.ndarray]] = {}
    for c in order:
        cond = cliques[c].conditional()
        keys, R = list(cond.keys()), cond.R()
        n = frontal_count(keys, R.shape[0], dims)
        frontal, separator = keys[:n], keys[n:]
        R_inv, info = dtrtri(R, lower=0)
        if info != 0:
            raise np.linalg.LinAlgError(f"a clique's R is singular (LAPACK dtrtri info {info})")
        sizes = [dims[k] for k in keys]
        starts = np.concatenate([[0], np.cumsum(sizes)]).astype(int)
        index = {k: slice(starts[i], starts[i + 1]) for i, k in enumerate(keys)}
        f = starts[n]
        if separator:
            parent = parent_of[c]
            rows, C_parent = joint[parent]
            sep = np.concatenate([np.arange(rows[k].start, rows[k].stop) for k in separator])
            C_SS = C_parent[sep][:, sep]
            X = R_inv @ cond.S()
            C = np.empty((starts[-1], starts[-1]))
            C[:f, :f] = R_inv @ R_inv.T + X @ C_SS @ X.T
            C[:f, f:] = -X @ C_SS
            C[f:, :f] = C[:f, f:].T
            C[f:, f:] = C_SS
            children_left[parent] -= 1
            if not keep and children_left[parent] == 0:
                del joint[parent]
        else:
            C = R_inv @ R_inv.T
        if keep or children_left[c]:
            joint[c] = (index, C)
        yield c, frontal, index, C


def joint_covariance(clique_of: dict[int, int], joint: dict, keys: list[int]) -> np.ndarray:
    """The joint covariance of `keys` (in that order), all of which some clique holds: the one where the
    first of them to be eliminated is frontal (a factor's keys always are, with the tree of its graph)."""
    for k in keys:
        index, C = joint[clique_of[k]]
        if all(j in index for j in keys):
            rows = np.concatenate([np.arange(index[j].start, index[j].stop) for j in keys])
            return C[np.ix_(rows, rows)]
    raise ValueError("no clique of the Bayes tree holds all these keys together")
