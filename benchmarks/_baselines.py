"""Hand-written GTSAM loops the benchmarks compare fusionkit against, on the same graphs. They use
gtsam and numpy only, no fusionkit helper: the factors, their times and the initial values come
from the built problem as plain data (`problem_data`)."""

from __future__ import annotations

import time
from itertools import groupby

import gtsam
import numpy as np

STATIC = float("-inf")  # the time of a variable that is not a per-state one


def problem_data(problem) -> tuple[list[tuple[float, gtsam.NonlinearFactor]], dict[int, float], gtsam.Values]:
    """(time, factor) per factor, the time of every key (-inf: static) and the initial values of a
    built fusionkit problem, as plain data."""
    return [(r.time, r.factor) for r in problem.records], dict(problem.key_time), problem.initial


def _steps(factors: list[tuple[float, gtsam.NonlinearFactor]]) -> list[tuple[float, gtsam.NonlinearFactorGraph, list[int]]]:
    """(time, graph, keys first seen) per distinct factor time, in time order."""
    seen: set[int] = set()
    out = []
    for t, group in groupby(sorted(factors, key=lambda f: f[0]), key=lambda f: f[0]):
        graph, new = gtsam.NonlinearFactorGraph(), []
        for _, factor in group:
            graph.add(factor)
            for k in factor.keys():
                if k not in seen:
                    seen.add(k)
                    new.append(k)
        out.append((t, graph, new))
    return out


def _batch_start(steps: list, initial: gtsam.Values, seconds: float) -> tuple[gtsam.NonlinearFactorGraph,
                                                                             gtsam.Values, float, list]:
    """The steps up to `seconds` after the first timed one merged and solved by GTSAM's LM:
    (graph, solution, last merged time, the remaining steps)."""
    end = next(t for t, _, _ in steps if np.isfinite(t)) + seconds
    graph, keys, last = gtsam.NonlinearFactorGraph(), [], STATIC
    rest = []
    for t, factors, new in steps:
        if t <= end:
            graph.push_back(factors)
            keys += new
            last = t
        else:
            rest.append((t, factors, new))
    params = gtsam.LevenbergMarquardtParams()
    params.setRelativeErrorTol(1e-6)
    params.setAbsoluteErrorTol(1e-9)
    params.setMaxIterations(100)
    return graph, gtsam.LevenbergMarquardtOptimizer(graph, initial.extract(keys), params).optimize(), last, rest


def hand_fixed_lag(factors: list[tuple[float, gtsam.NonlinearFactor]], key_time: dict[int, float],
                   initial: gtsam.Values, settings: dict) -> np.ndarray:
    """Per-step seconds (update + calculateEstimate, what a real-time user waits for) of a minimal
    IncrementalFixedLagSmoother loop: the same lag, relinearization threshold and factorization as
    `settings`, the first settings["warmup"] seconds solved as one batch first. Static keys are
    re-stamped at every step so they stay in the window."""
    p = gtsam.ISAM2Params()
    p.setRelinearizeThreshold(settings.get("relinearize_threshold", 0.01))
    p.relinearizeSkip = 1
    p.setFactorization("CHOLESKY" if settings.get("factorization") == "cholesky" else "QR")
    smoother = gtsam.IncrementalFixedLagSmoother(settings["lag"], p)
    static = [k for k, t in key_time.items() if t == STATIC]
    first, values, t0, steps = _batch_start(_steps(factors), initial, settings["warmup"])
    smoother.update(first, values, {k: t0 if key_time[k] == STATIC else key_time[k] for k in values.keys()})
    latency = []
    for t, graph, new in steps:
        stamps = {k: t for k in static}
        stamps.update({k: key_time[k] for k in new if key_time[k] != STATIC})
        new_values = initial.extract(new)
        tic = time.perf_counter()
        smoother.update(graph, new_values, stamps)
        smoother.calculateEstimate()
        latency.append(time.perf_counter() - tic)
    return np.asarray(latency)
