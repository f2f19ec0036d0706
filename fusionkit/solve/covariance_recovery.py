"""Marginal covariances from a Bayes tree by top-down recovery, for graphs too ill-conditioned for
GTSAM's marginals (which re-eliminate by Cholesky): the tree comes from a sparse QR of the whitened
Jacobian, and each clique's conditional R x_F + S x_S = d gives the joint covariance of its variables
from its separator's, which its parent holds (running intersection):

    C_SS from the parent,  X = R^-1 S,  C_FF = R^-1 R^-T + X C_SS X^T,  C_FS = -X C_SS.

One pass from the roots down, each clique's work cubic in its own size: time and memory linear in the
number of cliques, where a dense QR of the whole Jacobian is cubic in the size of the problem. The same
pass gives every factor's joint covariance of its variables (they lie in one clique), which the noise-scale
estimate needs (noise_scales.py).
"""

from __future__ import annotations

import gtsam
import numpy as np

from ..graph.evaluator import GraphEvaluator
from .factorization import eliminate
from .marginals import frontal_count


def recovered_marginals(graph: GraphEvaluator | gtsam.NonlinearFactorGraph, values: gtsam.Values, keys: set[int],
                        ordering: str = "colamd") -> dict[int, np.ndarray]:
    """Marginal covariance (tangent space at `values`) of each key, from the QR Bayes tree."""
    clique_of, joint = clique_covariances(eliminate(graph.linearize(values), True, ordering), values)
    out: dict[int, np.ndarray] = {}
    for k in keys:
        index, C = joint[clique_of[k]]
        out[k] = C[index[k], index[k]].copy()
    return out


def clique_covariances(tree: gtsam.GaussianBayesTree, values: gtsam.Values
                       ) -> tuple[dict[int, int], dict[int, tuple[dict[int, slice], np.ndarray]]]:
    """(the clique each key is frontal in, each clique's (key -> rows, joint covariance of its frontal and
    separator variables)); cliques are named by their first frontal key."""
    import scipy.linalg
    dims = values.zeroVectors()
    cliques, parent_of, clique_of = {}, {}, {}
    for key in values.keys():
        clique = tree[key]
        first = clique.conditional().firstFrontalKey()
        clique_of[key] = first
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
    joint: dict[int, tuple[dict[int, slice], np.ndarray]] = {}
    for c in order:
        cond = cliques[c].conditional()
        n = frontal_count(cond, dims)
        frontal, separator = list(cond.keys()[:n]), list(cond.keys()[n:])
        R_inv = scipy.linalg.solve_triangular(cond.R(), np.eye(cond.R().shape[0]))
        sizes = [dims.at(k).shape[0] for k in frontal + separator]
        starts = np.concatenate([[0], np.cumsum(sizes)]).astype(int)
        index = {k: slice(starts[i], starts[i + 1]) for i, k in enumerate(frontal + separator)}
        f = starts[n]
        if separator:
            rows, C_parent = joint[parent_of[c]]
            sep = np.concatenate([np.arange(rows[k].start, rows[k].stop) for k in separator])
            C_SS = C_parent[np.ix_(sep, sep)]
            X = R_inv @ cond.S()
            C = np.empty((starts[-1], starts[-1]))
            C[:f, :f] = R_inv @ R_inv.T + X @ C_SS @ X.T
            C[:f, f:] = -X @ C_SS
            C[f:, :f] = C[:f, f:].T
            C[f:, f:] = C_SS
        else:
            C = R_inv @ R_inv.T
        joint[c] = (index, C)
    return clique_of, joint


def joint_covariance(clique_of: dict[int, int], joint: dict, keys: list[int]) -> np.ndarray:
    """The joint covariance of `keys` (in that order), all of which some clique holds: the one where the
    first of them to be eliminated is frontal (a factor's keys always are, with the tree of its graph)."""
    for k in keys:
        index, C = joint[clique_of[k]]
        if all(j in index for j in keys):
            rows = np.concatenate([np.arange(index[j].start, index[j].stop) for j in keys])
            return C[np.ix_(rows, rows)]
    raise ValueError("no clique of the Bayes tree holds all these keys together")
