"""Hand-written GTSAM loops the benchmarks compare fusionkit against, on the same graphs."""

from __future__ import annotations

import time

import gtsam
import numpy as np

from fusionkit.solve.incremental import time_steps, value_subset, warm_start


def hand_fixed_lag(problem, settings: dict) -> np.ndarray:
    """Per-step seconds of a minimal IncrementalFixedLagSmoother loop over the same time steps
    (the same lag, relinearization threshold, factorization and warm-up as `settings`)."""
    p = gtsam.ISAM2Params()
    p.setRelinearizeThreshold(settings.get("relinearize_threshold", 0.01))
    p.relinearizeSkip = 1
    p.setFactorization("CHOLESKY" if settings.get("factorization") == "cholesky" else "QR")
    smoother = gtsam.IncrementalFixedLagSmoother(settings["lag"], p)
    static = [k for k, t in problem.key_time.items() if t == float("-inf")]
    first, values, t0, steps = warm_start(problem, list(time_steps(problem)), settings.get("warmup", 0.0))
    stamps = {k: (t0 if problem.key_time[k] == float("-inf") else problem.key_time[k]) for k in values.keys()}
    smoother.update(first, values, stamps)
    latency = []
    for t, factors, new in steps:
        stamp = {k: t for k in static}
        stamp.update({k: problem.key_time[k] for k in new})
        vals = value_subset(problem, new)
        tic = time.perf_counter()
        smoother.update(factors, vals, stamp)
        latency.append(time.perf_counter() - tic)
    return np.asarray(latency)
