"""Levenberg-Marquardt (and Gauss-Newton, lambda = 0) iterated from Python on GTSAM's linear algebra.

Why not `gtsam.LevenbergMarquardtOptimizer`: inside it every Python `CustomFactor` call receives a
fresh copy of the whole `Values` (pybind11 copies `const Values&` arguments that have no Python
owner), so each call costs O(number of variables). Linearizing the graph from Python passes the
Python-owned `Values` by reference instead. Measured on the quickstart (750 poses, 749 Python
factors): 0.22 s here vs 0.8 s in GTSAM's optimizer for the same iterates and final cost.
Damping is Marquardt's (GTSAM's `diagonalDamping`): lambda times the diagonal of the Gauss-Newton
Hessian, so variables of very different information (poses vs pulleys with mm-level sigmas)
are damped alike.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import gtsam
import numpy as np


@dataclass
class DampingSettings:
    lambda_initial: float = 1e-5
    lambda_factor: float = 10.0
    lambda_upper: float = 1e5
    lambda_lower: float = 0.0
    min_diagonal: float = 1e-6
    max_diagonal: float = 1e32


def hessian_diagonal(linear: gtsam.GaussianFactorGraph, total_dim: int) -> np.ndarray:
    """diag(A^T A) over all variables, ordered by sorted key (the sparse Jacobian's column order)."""
    _, cols, vals = linear.sparseJacobian_()
    cols = cols.astype(int) - 1
    keep = cols < total_dim  # the last column is the right-hand side
    return np.bincount(cols[keep], weights=vals[keep] ** 2, minlength=total_dim)


class Damping:
    """Builds the damped system: Marquardt rows sqrt(lambda * diag) per variable, made in one numpy pass."""

    def __init__(self, values: gtsam.Values, settings: DampingSettings):
        zero = values.zeroVectors()
        self.keys = sorted(values.keys())
        self.dims = [zero.at(k).shape[0] for k in self.keys]
        self.offsets = np.concatenate([[0], np.cumsum(self.dims)])
        self.settings = settings
        self.units = {d: gtsam.noiseModel.Unit.Create(d) for d in set(self.dims)}
        self.zeros = {d: np.zeros(d) for d in set(self.dims)}

    def damped(self, linear: gtsam.GaussianFactorGraph, diagonal: np.ndarray, lam: float) -> gtsam.GaussianFactorGraph:
        roots = np.sqrt(lam * np.clip(diagonal, self.settings.min_diagonal, self.settings.max_diagonal))
        out = linear.clone()
        for key, dim, start in zip(self.keys, self.dims, self.offsets):
            out.add(gtsam.JacobianFactor(key, np.diag(roots[start:start + dim]), self.zeros[dim], self.units[dim]))
        return out


def _converged(before: float, after: float, rtol: float, atol: float) -> bool:
    decrease = before - after
    return after <= atol or abs(decrease) <= atol or abs(decrease) <= rtol * before


def levenberg_marquardt(graph: gtsam.NonlinearFactorGraph, initial: gtsam.Values, rtol: float, atol: float,
                        max_iterations: int, damping: DampingSettings | None,
                        progress: Callable[[int, float], None] | None = None) -> tuple[gtsam.Values, list[float]]:
    """Minimize graph.error; `damping=None` gives plain Gauss-Newton. Returns (values, cost history)."""
    values, cost = initial, graph.error(initial)
    history = [cost]
    damper = Damping(values, damping) if damping else None
    lam = damping.lambda_initial if damping else 0.0
    for it in range(1, max_iterations + 1):
        linear = graph.linearize(values)
        diagonal = hessian_diagonal(linear, int(damper.offsets[-1])) if damper else None
        while True:
            delta = (damper.damped(linear, diagonal, lam) if damper else linear).optimize()
            candidate = values.retract(delta)
            new_cost = graph.error(candidate)
            if damping is None or new_cost <= cost:
                break
            lam *= damping.lambda_factor
            if lam > damping.lambda_upper:
                return values, history  # no step decreases the cost: a minimum (or stuck)
        if damping:
            lam = max(lam / damping.lambda_factor, damping.lambda_lower)
        done = _converged(cost, new_cost, rtol, atol)
        values, cost = candidate, new_cost
        history.append(cost)
        if progress:
            progress(it, cost)
        if done or not np.isfinite(cost):
            break
    return values, history
