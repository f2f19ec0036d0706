"""Checks before and after solving: unconstrained variables, divergence, large residuals."""

from __future__ import annotations

import re

import gtsam
import numpy as np

from ..errors import SolverError
from ..graph.builder import Problem
from .factorization import eliminate

_KEY_IN_MESSAGE = re.compile(r"near variable\s+(\d+)")


def _indeterminate_key(exc: Exception) -> int | None:
    m = _KEY_IN_MESSAGE.search(str(exc))
    return int(m.group(1)) if m else None


def unconstrained_message(problem: Problem, exc: Exception, key: int | None = None) -> str | None:
    """Turn GTSAM's indeterminate-system error into a sentence naming the variable (`key` if given)."""
    key = _indeterminate_key(exc) if key is None else key
    if key is None:
        return None
    name = problem.keys.name_of(key)
    return (f"variable {name} is not constrained by the factors (the system is indeterminate near it): "
            "add a prior or a measurement that fixes it, e.g. a pose.origin or pose.absolute factor for "
            "the first pose, or a prior sigma for a calibration parameter; or improve the initial values (a "
            "redescending robust kernel such as tukey gives no weight to residuals beyond its cutoff)")


def _first_of_family(problem: Problem, linear: gtsam.GaussianFactorGraph, key: int) -> int:
    """GTSAM names the variable it eliminated last, often the far end of a floating chain (cam/pose[148]).
    When the family's first variable (cam/pose[0]) is indeterminate too, name that one instead."""
    try:
        family, index = problem.keys.decode(key)
    except KeyError:
        return key
    first = family.key(0)
    if index == 0 or not problem.initial.exists(first):
        return key
    try:
        linear.eliminateSequential(gtsam.Ordering.ColamdConstrainedLastGaussianFactorGraph(linear, [first]))
    except RuntimeError as exc:
        if _indeterminate_key(exc) == first:
            return first
    return key


def check_constrained(problem: Problem, graph: gtsam.NonlinearFactorGraph, qr: bool = False,
                      ordering: str = "colamd") -> tuple[gtsam.GaussianFactorGraph, gtsam.GaussianBayesTree]:
    """Every variable must appear in a factor, and the linearized system must be determinate
    (to Cholesky, or with `qr` to QR elimination). Returns the system linearized at the initial values
    and its elimination, which a batch solver's first step reuses."""
    used = set(graph.keyVector())
    for key in problem.initial.keys():
        if key not in used:
            raise SolverError(f"variable {problem.keys.name_of(key)} appears in no factor: add a factor that "
                              "measures it, or remove what declares it")
    linear = problem.evaluator().linearize(problem.initial)
    try:
        return linear, eliminate(linear, qr, ordering)
    except RuntimeError as exc:
        key = _indeterminate_key(exc)
        if key is None:
            raise
        raise SolverError(unconstrained_message(problem, exc, _first_of_family(problem, linear, key))) from None


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
