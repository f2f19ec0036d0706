"""What a solver returns: estimates, statistics, and per-key marginal covariances."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import gtsam
import numpy as np


@dataclass
class SolveWarning:
    """A check that needs no ground truth found something a user must see (report.json `warnings`, the summary):
    `name` says which check, `span` the time in seconds it concerns, if any."""

    name: str
    message: str
    span: tuple[float, float] | None = None

    def to_json(self) -> dict:
        out = {"name": self.name, "message": self.message}
        if self.span is not None:
            out["t_start"], out["t_end"] = float(self.span[0]), float(self.span[1])
        return out

    def text(self) -> str:
        where = "" if self.span is None else f" (t = {self.span[0]:.2f} .. {self.span[1]:.2f} s)"
        return f"warning [{self.name}]{where}: {self.message}"


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
    chi2_per_dof: float | None = None  # 2 cost / degrees of freedom; None without redundancy
    rejection: str | None = None  # why a check (chi-square gate, incremental health) refused the solution; None: accepted
    sigmas_scaled: bool = False  # covariances multiplied by sigma0^2 (solver.a_posteriori_sigmas)
    noise_scales: dict[str, dict] | None = None  # `noise_scale: estimate` entries (solve/noise_scales.py)
    factorization: str = "cholesky"  # the one the solve used (QR where Cholesky failed on a determinate system)
    warnings: list[SolveWarning] = field(default_factory=list)
    swaps: dict = field(default_factory=dict)  # incremental: LinearContainers.swap_statistics()
    revisions: list = field(default_factory=list)  # incremental: health.Revision per time step
    # fixed-lag: (time, the smoother's whole estimate then) once per lag, when a health-check window is complete
    static_snapshots: list[tuple[float, gtsam.Values]] = field(default_factory=list)
    linear: gtsam.GaussianFactorGraph | None = None  # the graph linearized at `values` (the covariances' system)

    @property
    def sigma0(self) -> float | None:
        """A-posteriori standard deviation of unit weight: sqrt(chi-square per degree of freedom)."""
        return None if self.chi2_per_dof is None else float(np.sqrt(self.chi2_per_dof))

    def stats(self) -> dict:
        out = {"solver": self.solver, "iterations": self.iterations, "seconds": self.seconds,
               "initial_cost": self.initial_error, "final_cost": self.final_error,
               "cost_history": self.history, "status": "rejected" if self.rejection else "accepted",
               "chi2_per_dof": self.chi2_per_dof, "sigma0": self.sigma0, "sigmas_scaled_by_sigma0": self.sigmas_scaled,
               "factorization": self.factorization, "warnings": [w.to_json() for w in self.warnings]}
        if self.rejection:
            out["rejection"] = self.rejection
        if self.noise_scales:
            out["noise_scales"] = self.noise_scales
        if self.step_latency is not None and len(self.step_latency):
            lat = self.step_latency * 1e3
            out["step_latency_ms"] = {"p50": float(np.percentile(lat, 50)), "p99": float(np.percentile(lat, 99)),
                                      "max": float(lat.max()), "steps": int(len(lat))}
            out["warmup_seconds"] = self.warmup_seconds
        if self.swaps:
            out["relinearized_python_factors"] = self.swaps
        return out
