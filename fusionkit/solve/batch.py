"""Batch solvers: Levenberg-Marquardt, Gauss-Newton, Dogleg over the whole graph."""

from __future__ import annotations

import time
from typing import Callable

import gtsam

from ..graph.builder import Problem
from .checks import check_constrained, unconstrained_message
from .result import SolveResult
from ..errors import SolverError

METHODS = {
    "lm": (gtsam.LevenbergMarquardtParams, gtsam.LevenbergMarquardtOptimizer),
    "gn": (gtsam.GaussNewtonParams, gtsam.GaussNewtonOptimizer),
    "dogleg": (gtsam.DoglegParams, gtsam.DoglegOptimizer),
}


def solve_batch(problem: Problem, settings: dict, progress: Callable[[int, float], None] | None = None) -> SolveResult:
    """Iterate the chosen optimizer until the relative/absolute cost decrease is below tolerance."""
    graph = problem.graph()
    check_constrained(problem, graph)
    method = settings.get("method", "lm")
    params_cls, optimizer_cls = METHODS[method]
    params = params_cls()
    params.setRelativeErrorTol(settings.get("relative_tolerance", 1e-6))
    params.setAbsoluteErrorTol(settings.get("absolute_tolerance", 1e-9))
    max_iterations = settings.get("max_iterations", 100)
    params.setMaxIterations(max_iterations)
    start = time.perf_counter()
    try:
        optimizer = optimizer_cls(graph, problem.initial, params)
        history = [optimizer.error()]
        for it in range(1, max_iterations + 1):
            optimizer.iterate()
            history.append(optimizer.error())
            if progress:
                progress(it, history[-1])
            if gtsam.checkConvergence(params, history[-2], history[-1]):
                break
            if method == "lm" and optimizer.lambda_() >= params.getlambdaUpperBound():
                break
    except RuntimeError as exc:
        msg = unconstrained_message(problem, exc)
        if msg is None:
            raise
        raise SolverError(msg) from None
    seconds = time.perf_counter() - start
    return SolveResult(optimizer.values(), f"batch-{method}", history[0], history[-1], len(history) - 1,
                       seconds, history=history)
