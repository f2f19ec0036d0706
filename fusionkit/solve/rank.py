"""The rank of a linearized problem: directions no factor constrains (gauge freedoms), found from the whitened
Jacobian A itself whatever the factorization, and told apart from ill-conditioning.

QR of A (GTSAM's multifrontal EliminateQR, in the elimination order) gives R with A = QR. For each scalar
column j, |R_jj| / ||A e_j|| is the sine of the angle between column j and the span of the columns eliminated
before it: independent of every variable's units (a column scaled scales R's column alike), 0 when column j
is a combination of those, and at least 1 / cond(A D^-1) otherwise (D: the column norms). Measured: a missing
pose.origin (an SE(2) gauge) gives 1e-15; every healthy shipped config has all columns above 1e-4, and a gyro
sigma of 1e-12 rad/s, absurd but determinate, 5e-3. Below RANK_TOLERANCE a column is suspect.

QR without pivoting can flag a column that is itself fine (the deficient column's row of R then carries a later
column), so the suspects only say where to look: every variable without a suspect column is eliminated first
(their columns are independent), and the factor left on the suspects' variables is their Schur complement,
whose column-scaled singular values below RANK_TOLERANCE are the null directions. Each is carried back to all
variables by back-substitution with the right-hand side removed (A x = 0).

Cholesky factors A^T A into the same R but keeps half the digits (its error on |R_jj| is about sqrt(eps) ||A e_j||),
and GTSAM's declares a frontal block indeterminate when the last two diagonal entries of its R differ by 2^12 or
more (gtsam/base/cholesky.cpp, choleskyPartial), a test that depends on the variables' units: on a well-posed
problem with a tight sigma (a 1e-4 rad/s gyro beside millimetre wheel encoders, smallest ratio 1.7e-4) it fails
where QR solves. A Cholesky ratio below CHOLESKY_SUSPECT, or a failed Cholesky, is therefore decided by QR.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import gtsam
import numpy as np

from ..graph.keys import STATE, KeyRegistry
from .covariance_recovery import frontal_count
from .factorization import eliminate
from .levenberg import hessian_diagonal

REGULARIZATION = 1e-12  # a prior of this weight, relative to each column's norm, on every variable (see regularized)
RANK_TOLERANCE = 1e-9  # |R_jj| / ||A e_j||, and the Schur complement's scaled singular values, below which: no rank
CHOLESKY_SUSPECT = 1e-6  # a Cholesky ratio below this is looked at again by QR (Cholesky's error: ~sqrt(eps))
PARTICIPATES = 1e-6  # a variable takes part in a null direction: its largest component above this share of the largest


@dataclass
class RankCheck:
    """What the whitened Jacobian at a point says of its rank."""

    unknowns: int  # scalar columns of A
    smallest_ratio: float  # min |R_jj| / ||A e_j||: 1 / this bounds the column-scaled condition number from below
    condition: float  # max |R_jj| / min |R_jj|: a lower bound of cond(A) in the variables' own units (Cholesky: squared)
    null_directions: list[dict[int, np.ndarray]] = field(default_factory=list)  # key -> tangent step; A x = 0

    @property
    def deficiency(self) -> int:
        return len(self.null_directions)


def column_norms(linear: gtsam.GaussianFactorGraph, values: gtsam.Values) -> dict[int, np.ndarray]:
    """||A e_j|| of every scalar column, per key (sorted-key order is the sparse Jacobian's)."""
    keys = sorted(values.keys())
    dims = values.dims()
    sizes = [dims[k] for k in keys]
    norms = np.sqrt(hessian_diagonal(linear, int(sum(sizes))))
    starts = np.concatenate([[0], np.cumsum(sizes)]).astype(int)
    return {k: norms[starts[i]:starts[i + 1]] for i, k in enumerate(keys)}


def diagonal_of(tree: gtsam.GaussianBayesTree, values: gtsam.Values) -> dict[int, np.ndarray]:
    """|R_jj| of every scalar column, per key, from the Bayes tree's conditionals."""
    dims = values.dims()
    out: dict[int, np.ndarray] = {}
    for key in values.keys():
        if key in out:
            continue
        cond = tree[key].conditional()
        keys, R = list(cond.keys()), cond.R()
        diag = np.abs(np.diag(R))
        start = 0
        for k in keys[:frontal_count(keys, R.shape[0], dims)]:
            out[k] = diag[start:start + dims[k]]
            start += dims[k]
    return out


def ratios(tree: gtsam.GaussianBayesTree, norms: dict[int, np.ndarray], values: gtsam.Values
           ) -> tuple[dict[int, np.ndarray], dict[int, np.ndarray]]:
    """(|R_jj| / ||A e_j|| per key, |R_jj| per key); a column of zeros has ratio 0."""
    diag = diagonal_of(tree, values)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = {k: np.where(norms[k] > 0, d / np.where(norms[k] > 0, norms[k], 1.0), 0.0) for k, d in diag.items()}
    return ratio, diag


def regularized(linear: gtsam.GaussianFactorGraph, values: gtsam.Values, norms: dict[int, np.ndarray]
                ) -> gtsam.GaussianFactorGraph:
    """`linear` with a prior of weight REGULARIZATION ||A e_j|| on every column j (1 on a column of zeros): GTSAM's
    QR refuses a block with fewer rows than unknowns (a floating chain's last pose), and with these rows it never
    lacks any; a ratio or singular value moves by about REGULARIZATION, far below RANK_TOLERANCE."""
    out = linear.clone()
    for key in values.keys():
        scale = np.where(norms[key] > 0, norms[key], 1.0) * REGULARIZATION
        out.add(gtsam.JacobianFactor(key, np.diag(scale), np.zeros(len(scale)), gtsam.noiseModel.Unit.Create(len(scale))))
    return out


def rank_check(linear: gtsam.GaussianFactorGraph, values: gtsam.Values, tree: gtsam.GaussianBayesTree | None = None,
               ordering: str | gtsam.Ordering = "colamd") -> RankCheck:
    """The rank of `linear` (variables at `values`) from its QR Bayes tree (`tree`; without one, that of the
    regularized system, eliminated here)."""
    norms = column_norms(linear, values)
    linear = regularized(linear, values, norms)
    tree = eliminate(linear, True, ordering) if tree is None else tree
    ratio, diag = ratios(tree, norms, values)
    all_ratios = np.concatenate(list(ratio.values()))
    all_diag = np.concatenate(list(diag.values()))
    positive = all_diag[all_diag > 0]
    condition = float(positive.max() / positive.min()) if len(positive) == len(all_diag) else np.inf
    check = RankCheck(len(all_ratios), float(all_ratios.min()), condition)
    suspects = [k for k, r in ratio.items() if r.min() < RANK_TOLERANCE]
    if suspects:
        check.null_directions = null_directions(linear, values, suspects, norms)
    return check


def smallest_ratio(tree: gtsam.GaussianBayesTree, linear: gtsam.GaussianFactorGraph, values: gtsam.Values) -> float:
    """min |R_jj| / ||A e_j|| of a Bayes tree (QR's or Cholesky's)."""
    ratio, _ = ratios(tree, column_norms(linear, values), values)
    return float(min(r.min() for r in ratio.values()))


def null_directions(linear: gtsam.GaussianFactorGraph, values: gtsam.Values, suspects: list[int],
                    norms: dict[int, np.ndarray]) -> list[dict[int, np.ndarray]]:
    """A basis of A's null space (key -> tangent step), found on the `suspects`' variables (module docstring)."""
    others = [k for k in values.keys() if k not in set(suspects)]
    ordering = gtsam.Ordering()
    for k in suspects:
        ordering.push_back(k)
    if others:
        net, remaining = linear.eliminatePartialSequential(others, gtsam.EliminateQR)
    else:
        net, remaining = gtsam.GaussianBayesNet(), linear
    dims = values.dims()
    width = sum(dims[k] for k in suspects)
    A = remaining.jacobian(ordering)[0] if remaining.size() else np.zeros((0, width))
    scale = np.concatenate([norms[k] for k in suspects])
    scale = np.where(scale > 0, scale, 1.0)
    A = A / scale if A.shape[0] else np.zeros((1, width))
    _, s, vt = np.linalg.svd(A, full_matrices=True)
    s = np.concatenate([s, np.zeros(width - len(s))])
    directions = []
    starts = np.concatenate([[0], np.cumsum([dims[k] for k in suspects])]).astype(int)
    for i in np.flatnonzero(s < RANK_TOLERANCE):
        step = vt[i] / scale
        given = gtsam.VectorValues()
        zero = gtsam.VectorValues()
        for j, k in enumerate(suspects):
            given.insert(k, step[starts[j]:starts[j + 1]])
            zero.insert(k, np.zeros(dims[k]))
        direction = {k: step[starts[j]:starts[j + 1]] for j, k in enumerate(suspects)}
        if others:  # x_rest(given) - x_rest(0): the back-substitution with the right-hand side removed
            moved, still = net.optimize(given), net.optimize(zero)
            for k in others:
                direction[k] = moved.at(k) - still.at(k)
        directions.append(direction)
    return directions


def index_ranges(indices: list[int]) -> str:
    """[0, 1, 2, 5] -> '0..2, 5'."""
    parts, start = [], None
    for a, b in zip(indices, indices[1:] + [None]):
        start = a if start is None else start
        if b != a + 1:
            parts.append(f"{start}" if start == a else f"{start}..{a}")
            start = None
    return ", ".join(parts)


def _moving(keys: KeyRegistry, direction: dict[int, np.ndarray]) -> list[tuple]:
    """(family, its members that move, which tangent axes move) of a direction, by family."""
    largest = max(float(np.abs(v).max()) for v in direction.values())
    moving = [k for k, v in direction.items() if np.abs(v).max() > PARTICIPATES * largest]
    out = []
    for family, members in keys.group(moving):
        axes = np.zeros(family.vartype.dim, dtype=bool)
        for k in members:
            axes |= np.abs(direction[k]) > PARTICIPATES * largest
        out.append((family, tuple(members), axes))
    return out


def _family_text(keys: KeyRegistry, family, members: tuple, axes: np.ndarray, total: int) -> str:
    """`robot/pose[0..399] (all 400; tx, ty, rz)`, `cam/vo_scale`, `robot/pose[120..140] (21 of 400; tx)`."""
    names = ", ".join(a for a, m in zip(family.vartype.names()[1], axes) if m)
    if not family.indexed:
        return family.label() + (f" ({names})" if family.vartype.dim > 1 else "")
    count = f"all {total}" if len(members) == total else f"{len(members)} of {total}"
    return f"{family.label()}[{index_ranges([keys.decode(k)[1] for k in members])}] ({count}; {names})"


def _groups(keys: KeyRegistry, directions: list[dict[int, np.ndarray]]) -> list[tuple[int, list[tuple]]]:
    """Directions that move the same variables, told once: (how many, _moving with the union of their axes)."""
    groups: dict[tuple, list] = {}
    for direction in directions:
        moving = _moving(keys, direction)
        signature = tuple((family.id, members) for family, members, _ in moving)
        if signature in groups:
            groups[signature][0] += 1
            for (_, _, axes), (_, _, more) in zip(groups[signature][1], moving):
                axes |= more
        else:
            groups[signature] = [1, moving]
    return [(count, moving) for count, moving in groups.values()]


def _fix(keys: KeyRegistry, family, members: tuple, axes: np.ndarray, total: int) -> str:
    """What would fix a family's moving variables: a prior on a floating trajectory's first state, a measurement
    for states the rest does not reach, a prior sigma for a parameter."""
    if family.kind != STATE:
        return f"a prior sigma for {family.label()} in the robot description, or a measurement of it"
    if len(members) < total:
        return (f"a measurement of {family.label()}[{index_ranges([keys.decode(k)[1] for k in members])}] or a factor "
                "tying them to the other states")
    names = ", ".join(a for a, m in zip(family.vartype.names()[1], axes) if m)
    return (f"a prior or an absolute measurement of the first state {family.label(0)} ({names}), e.g. a pose.origin "
            "or pose.absolute factor")


def unconstrained_text(keys: KeyRegistry, check: RankCheck, variables) -> str:
    """One sentence: how many directions no factor constrains, which of `variables` move in them (by family,
    directions moving the same variables told once with the union of their axes), and what would fix them."""
    totals = {family.id: len(members) for family, members in keys.group(list(variables))}
    groups = _groups(keys, check.null_directions)
    texts, fixes = [], {}
    for count, moving in groups:
        texts.append(" with ".join(_family_text(keys, f, m, a, totals[f.id]) for f, m, a in moving)
                     + (f": {count} directions" if count > 1 else ""))
        fixes.update(dict.fromkeys(_fix(keys, f, m, a, totals[f.id]) for f, m, a in moving))
    shown = "; ".join(texts[:4]) + (f"; and {len(texts) - 4} more groups" if len(texts) > 4 else "")
    n = check.deficiency
    return (f"the factors leave {n} direction{'s' if n > 1 else ''} of the {check.unknowns} unknowns unconstrained "
            f"(the whitened Jacobian is rank-deficient: |R_jj| / ||A e_j|| below {RANK_TOLERANCE:g}); moving without "
            f"changing any residual: {shown}; add " + "; or ".join(list(fixes)[:4]))
