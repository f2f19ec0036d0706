"""Batch solvers over the whole graph: Levenberg-Marquardt and Gauss-Newton (iterated from Python,
see levenberg.py for why) and GTSAM's Dogleg."""

from __future__ import annotations

import time
from typing import Callable

import gtsam

from ..errors import SolverError
from ..graph.builder import Problem
from .checks import check_constrained, unconstrained_message
from .factorization import linear_settings
from .levenberg import DampingSettings, levenberg_marquardt
from .result import SolveResult, SolveWarning


def _dogleg(graph, initial, rtol, atol, max_iterations, progress, qr, ordering):
    params = gtsam.DoglegParams()
    if qr:
        params.setLinearSolverType("MULTIFRONTAL_QR")
    if ordering == "metis":
        params.setOrderingType("METIS")
    params.setRelativeErrorTol(rtol)
    params.setAbsoluteErrorTol(atol)
    params.setMaxIterations(max_iterations)
    optimizer = gtsam.DoglegOptimizer(graph, initial, params)
    history = [optimizer.error()]
    for it in range(1, max_iterations + 1):
        optimizer.iterate()
        history.append(optimizer.error())
        if progress:
            progress(it, history[-1])
        if gtsam.checkConvergence(params, history[-2], history[-1]):
            break
    return optimizer.values(), history


def solve_batch(problem: Problem, settings: dict, progress: Callable[[int, float], None] | None = None) -> SolveResult:
    """Iterate the chosen method until the relative/absolute cost decrease is below tolerance."""
    graph = problem.graph()
    qr, ordering = linear_settings(settings)
    checked = check_constrained(problem, graph, qr, ordering)  # the first LM/GN step reuses its elimination
    qr = checked.qr  # QR where Cholesky failed on a determinate system
    method = settings["method"]
    rtol, atol = settings["relative_tolerance"], settings["absolute_tolerance"]
    max_iterations = settings["max_iterations"]
    start = time.perf_counter()
    try:
        if method == "dogleg":
            values, history = _dogleg(graph, problem.initial, rtol, atol, max_iterations, progress, qr, ordering)
        else:
            damping = DampingSettings.of(settings) if method == "lm" else None
            values, history = levenberg_marquardt(problem.evaluator(), problem.initial, rtol, atol, max_iterations, damping,
                                                  progress, qr, ordering, checked.first)
    except RuntimeError as exc:
        msg = unconstrained_message(problem, exc)
        if msg is None:
            raise
        raise SolverError(msg) from None
    seconds = time.perf_counter() - start
    result = SolveResult(values, f"batch-{method}", history[0], history[-1], len(history) - 1, seconds,
                         history=history, factorization="qr" if qr else "cholesky")
    if checked.warning:
        result.warnings.append(SolveWarning("ill_conditioned", checked.warning))
    return result
