"""What a solver returns: estimates, statistics, and per-key marginal covariances."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import gtsam
import numpy as np


@dataclass
class SolveResult:
    values: gtsam.Values
    solver: str
    initial_error: float
    final_error: float
    iterations: int
    seconds: float
    covariances: dict[int, np.ndarray] = field(default_factory=dict)
    step_latency: np.ndarray | None = None  # seconds per incremental update
    history: list[float] = field(default_factory=list)
    marginal: Callable[[int], np.ndarray] | None = None  # solver-native marginal covariance, if any
    warmup_seconds: float = 0.0  # incremental solvers: the batch-solved start-up segment

    def stats(self) -> dict:
        out = {"solver": self.solver, "iterations": self.iterations, "seconds": self.seconds,
               "initial_cost": self.initial_error, "final_cost": self.final_error,
               "cost_history": self.history}
        if self.step_latency is not None and len(self.step_latency):
            lat = self.step_latency * 1e3
            out["step_latency_ms"] = {"p50": float(np.percentile(lat, 50)), "p99": float(np.percentile(lat, 99)),
                                      "max": float(lat.max()), "steps": int(len(lat))}
            out["warmup_seconds"] = self.warmup_seconds
        return out
