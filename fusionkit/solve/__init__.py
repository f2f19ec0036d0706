"""Solvers (batch LM/GN/Dogleg, iSAM2, fixed-lag) and marginal covariances."""

from __future__ import annotations

import numpy as np

from ..graph.builder import Problem
from ..progress import Progress
from .batch import solve_batch
from .checks import check_constrained, check_solution, chi_square_per_dof, indeterminate, residual_dimension
from .covariance_recovery import recovered_marginals, tree_marginals
from .health import health
from .noise_check import noise_check
from .prior_check import prior_check
from .factorization import resolved_ordering
from .incremental import solve_fixed_lag, solve_isam2
from .result import SolveResult, SolveWarning

FIXED_LAG_ALLOWED_RISE = 9.0  # relative: a fixed-lag median factor cost ten times the initial one is divergence


def solve(problem: Problem, settings: dict, marginal_keys: set[int],
          progress: Progress | None = None) -> SolveResult:
    """Solve with the configured solver, check the solution, and attach covariances of `marginal_keys`.
    `settings`: the `solver:` section with its defaults (config.loader.solver_settings)."""
    kind = settings["type"]
    settings = {**settings, "ordering": resolved_ordering(settings["ordering"], problem.evaluator().largest_degree())}
    if progress:
        progress.stage(f"solving ({kind})")
    if kind == "batch":
        result = solve_batch(problem, settings, progress)
    elif kind == "isam2":
        result = solve_isam2(problem, settings, progress)
    else:
        result = solve_fixed_lag(problem, settings, progress, marginal_keys)
    graph = problem.graph()
    # a fixed-lag smoother does not minimize the whole graph (states keep the estimate they had when
    # they left the window): its full-graph cost may exceed a good initial one -- a few factors across the
    # window's edge at the moment a sensor came back after a dropout can hold most of it -- and its
    # chi-square is not judged unless asked for; a tenfold rise of the cost and of its median factor's is
    # divergence
    lagged = kind == "fixed_lag"
    allowed_rise = FIXED_LAG_ALLOWED_RISE if lagged else 1e-6
    if lagged and result.final_error > result.initial_error * (1 + allowed_rise):
        before, after = (float(np.median(problem.evaluator().record_errors(v))) for v in (problem.initial, result.values))
        if after <= before * (1 + allowed_rise):
            allowed_rise = np.inf  # a rise held by a few factors: not divergence
    result.rejection = check_solution(problem, graph, result.values, result.initial_error, result.final_error,
                                      settings["max_cost_ratio"], allowed_rise)
    result.chi2_per_dof = chi_square_per_dof(graph, result.values, result.final_error)
    warnings, why = health(problem, result.values, settings, result.revisions, result.static_snapshots)
    if result.chi2_per_dof is not None:
        dof = residual_dimension(graph) - result.values.dim()
        warnings = noise_check(problem, result.values, result.chi2_per_dof * dof, dof, settings) + warnings
    result.warnings += warnings
    result.rejection = result.rejection or why
    if settings["marginals"] and kind != "fixed_lag":
        if progress:
            progress.stage(f"marginal covariances of {len(marginal_keys)} variables")
        if kind == "batch":
            result.linear = problem.evaluator().linearize(result.values)
        if kind == "batch" and result.factorization == "qr":
            result.covariances = recovered_marginals(problem.evaluator(), result.values, marginal_keys, settings["ordering"],
                                                     result.linear)
        else:
            result.covariances = marginal_covariances(problem, result, marginal_keys, settings["ordering"])
        result.warnings += prior_check(problem, result.values, result.covariances)
        if settings["a_posteriori_sigmas"] and result.chi2_per_dof is not None:
            result.covariances = {k: c * result.chi2_per_dof for k, c in result.covariances.items()}
            result.sigmas_scaled = True
    return result


def marginal_covariances(problem: Problem, result: SolveResult, keys: set[int],
                         ordering: str = "colamd") -> dict[int, np.ndarray]:
    """Marginal covariance (tangent space at the estimate) of each key. Where Cholesky finds the system at the
    estimate indeterminate, its rank decides: a direction the factors leave free there is a SolverError naming it;
    at full rank the covariances come from QR, and an `ill_conditioned` warning says so."""
    if not keys:
        return {}
    try:
        if result.marginal is None:
            return tree_marginals(problem.evaluator(), result.values, keys, result.linear)
        return {k: np.asarray(result.marginal(k)) for k in keys}
    except RuntimeError as exc:
        if not indeterminate(exc):
            raise
    checked = check_constrained(problem, problem.graph(), False, ordering, result.values,
                                instead="the covariances at the estimate come from QR instead")
    if checked.warning:
        result.warnings.append(SolveWarning("ill_conditioned", f"at the estimate: {checked.warning}"))
    return recovered_marginals(problem.evaluator(), result.values, keys, ordering, result.linear)
