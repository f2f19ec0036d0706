"""Checks before and after solving: unconstrained variables, divergence, large residuals."""

from __future__ import annotations

import re
from dataclasses import dataclass

import gtsam
import numpy as np

from ..errors import SolverError
from ..graph.builder import Problem
from .factorization import eliminate, elimination_order
from .rank import CHOLESKY_SUSPECT, RANK_TOLERANCE, rank_check, smallest_ratio, unconstrained_text

_KEY_IN_MESSAGE = re.compile(r"near variable\s+(\d+)")


def unconstrained_message(problem: Problem, exc: Exception) -> str | None:
    """GTSAM's indeterminate-system error raised during a solve (after check_constrained passed at the initial
    values) as a sentence naming the variable GTSAM names; None for other errors."""
    m = _KEY_IN_MESSAGE.search(str(exc))
    if m is None:
        return None
    return (f"GTSAM found the linear system indeterminate near variable {problem.keys.name_of(int(m.group(1)))} "
            "during the solve (the system at the initial values is determinate: a later linearization point lost "
            "a constraint, or Cholesky lost the digits): try solver.factorization: qr, better initial values, or "
            "a prior on that variable; a redescending robust kernel such as tukey gives no weight to residuals "
            "beyond its cutoff")


@dataclass
class CheckedSystem:
    """The system linearized at the initial values and eliminated (a batch solver's first step reuses both), by
    the factorization the solve is to use: QR where Cholesky failed on a determinate system (`warning` says so)."""

    linear: gtsam.GaussianFactorGraph
    tree: gtsam.GaussianBayesTree
    qr: bool
    warning: str | None = None

    @property
    def first(self) -> tuple[gtsam.GaussianFactorGraph, gtsam.GaussianBayesTree]:
        return self.linear, self.tree


def indeterminate(exc: RuntimeError) -> bool:
    """Whether `exc` is GTSAM's indeterminate-system error."""
    return _KEY_IN_MESSAGE.search(str(exc)) is not None


def check_constrained(problem: Problem, graph: gtsam.NonlinearFactorGraph, qr: bool = False,
                      ordering: str = "colamd", values: gtsam.Values | None = None,
                      instead: str = "solved by QR instead") -> CheckedSystem:
    """Every variable must appear in a factor, and the whitened Jacobian at `values` (default: the initial
    values) must have full rank, whatever the factorization (solve/rank.py): a direction no factor constrains is
    a SolverError naming the variables that move in it. Cholesky (`qr` False) that fails, or keeps too few
    digits, on a system of full rank is ill-conditioning, not a missing constraint: QR is used (`instead` says
    for what), and `warning` says so."""
    values = problem.initial if values is None else values
    used = set(graph.keyVector())
    for key in values.keys():
        if key not in used:
            raise SolverError(f"variable {problem.keys.name_of(key)} appears in no factor: add a factor that "
                              "measures it, or remove what declares it")
    linear = problem.evaluator().linearize(values)
    order = elimination_order(linear, ordering)
    try:
        tree = eliminate(linear, qr, order)
    except RuntimeError as exc:
        if not indeterminate(exc):
            raise
        tree = None
    if not qr and tree is not None and smallest_ratio(tree, linear, values) >= CHOLESKY_SUSPECT:
        return CheckedSystem(linear, tree, False)
    rank = rank_check(linear, values, tree if qr else None, order)
    if rank.deficiency:
        where = "" if values is problem.initial else "at the solver's estimate, "
        raise SolverError(where + unconstrained_text(problem.keys, rank, values.keys()))
    try:
        qr_tree = tree if qr and tree is not None else eliminate(linear, True, order)
    except RuntimeError as exc:
        if not indeterminate(exc):
            raise
        at = "the initial values" if values is problem.initial else "the estimate"
        raise SolverError(f"GTSAM's QR found the system at {at} indeterminate, but no direction of the "
                          f"whitened Jacobian is free to {RANK_TOLERANCE:g} (smallest column-scaled ratio "
                          f"{rank.smallest_ratio:.2g}): {unconstrained_message(problem, exc)}") from None
    if qr:
        return CheckedSystem(linear, qr_tree, True)
    what = ("declared the system indeterminate" if tree is None
            else "kept too few digits of it (it factors A^T A, squaring the condition number)")
    return CheckedSystem(linear, qr_tree, True, (
        f"GTSAM's Cholesky {what}, but the whitened Jacobian has full rank: ill-conditioned, not unconstrained "
        f"(condition number at least {rank.condition:.2g} in the variables' units, {1 / rank.smallest_ratio:.2g} "
        f"with every column scaled to one); {instead}; set solver.factorization: qr to skip the "
        "attempt, and check the sigmas if one is much tighter than its sensor"))


def residual_dimension(graph: gtsam.NonlinearFactorGraph) -> int:
    return int(sum(graph.at(i).dim() for i in range(graph.size())))


def check_solution(problem: Problem, graph: gtsam.NonlinearFactorGraph, values: gtsam.Values,
                   initial_error: float, final_error: float, max_cost_ratio: float,
                   allowed_rise: float = 1e-6) -> str | None:
    """Fail on divergence (non-finite cost, or a cost above the initial one by more than the
    relative `allowed_rise`); return why the chi-square gate refuses the solution (a large final
    residual), or None when it passes."""
    if not np.isfinite(final_error):
        raise SolverError("the solver diverged: the cost became non-finite; check initial values and sigmas")
    if final_error > initial_error * (1 + allowed_rise) and final_error > 1e-9:
        raise SolverError(f"the solver diverged: cost rose from {initial_error:.6g} to {final_error:.6g}")
    ratio = chi_square_per_dof(graph, values, final_error)
    if ratio is None or ratio <= max_cost_ratio:
        return None  # no redundancy to judge the fit by, or a fit the sigmas explain
    return (f"the solver stopped with a large residual: chi-square per degree of freedom {ratio:.3g} (about 1 is "
            f"expected; the limit is solver.max_cost_ratio={max_cost_ratio:g}); largest contributions: "
            f"{worst_entries(problem, values)}; check the sigmas, the data association, or the initial values")


def chi_square_per_dof(graph: gtsam.NonlinearFactorGraph, values: gtsam.Values, final_error: float) -> float | None:
    """2 * cost / (residual dimension - unknowns): about 1 when the sigmas fit the data; its square
    root is sigma0, the a-posteriori standard deviation of unit weight. None without redundancy."""
    dof = residual_dimension(graph) - values.dim()
    return 2.0 * final_error / dof if dof > 0 else None


def worst_entries(problem: Problem, values: gtsam.Values, n: int = 3) -> str:
    totals: dict[str, float] = {}
    for r, error in zip(problem.records, problem.evaluator().record_errors(values)):
        totals[r.label] = totals.get(r.label, 0.0) + error
    top = sorted(totals.items(), key=lambda kv: -kv[1])[:n]
    return ", ".join(f"{label} ({cost:.3g})" for label, cost in top)
