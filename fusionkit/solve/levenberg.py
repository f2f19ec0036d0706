"""Levenberg-Marquardt (and Gauss-Newton, lambda = 0) iterated from Python on GTSAM's linear algebra.

Why not `gtsam.LevenbergMarquardtOptimizer`: inside it every Python `CustomFactor` call receives a
fresh copy of the whole `Values` (pybind11 copies `const Values&` arguments that have no Python
owner), so each call costs O(number of variables). Linearizing the graph from Python passes the
Python-owned `Values` by reference instead. Measured on the quickstart (750 poses, 749 Python
factors): 0.22 s here vs 0.8 s in GTSAM's optimizer for the same iterates and final cost.
Damping (`solver.damping`): `marquardt` (default, GTSAM's `diagonalDamping`) adds lambda times the
diagonal of the Gauss-Newton Hessian, so variables of very different information (poses vs pulleys with
mm-level sigmas) are damped alike; `levenberg` (GTSAM's default) adds lambda times the identity (in each
variable's whitened tangent units). Neither serves every problem (measured): on the sagging-cable
calibration (pulleys 100 m out, forces in kN) Levenberg's stops after 2 iterations far from the solution
(configs/cable_sag_large.yaml: cost 9e11, refused) where Marquardt's converges in 19 (cost 54.3); across the 8-s camera dropout of IMU +
VO (pose.imu_vo) Marquardt's crawls (100 iterations without converging, ATE 4.1 m: a soft direction under
a stiff diagonal is damped as much as the stiff ones) where Levenberg's converges in 6 (ATE 0.43 m, as
GTSAM's optimizer).

Gauss-Newton first: lambda starts at 0 and returns to 0 once it has fallen below
lambda_initial / 100; a step that raises the cost switches damping on at lambda_initial and
multiplies it by lambda_factor until the cost falls. On weakly observed problems (a swinging cable
robot seen by drifting VO: pulleys and tilts share a shallow, curved valley) a damped start
settles into the valley's floor and then crawls along it (70 iterations measured), while the
undamped steps cross it in 6.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import gtsam
import numpy as np

from ..graph.evaluator import GraphEvaluator
from .factorization import elimination_order, eliminate


@dataclass
class DampingSettings:
    lambda_initial: float = 1e-5
    lambda_factor: float = 10.0
    lambda_upper: float = 1e5
    lambda_lower: float = 0.0
    min_diagonal: float = 1e-6
    max_diagonal: float = 1e32
    scaled: bool = True  # Marquardt: lambda * diag(J^T J); False: Levenberg, lambda * I

    @classmethod
    def of(cls, settings: dict) -> "DampingSettings":
        """The damping a `solver:` section asks for (`damping: marquardt | levenberg`)."""
        return cls(scaled=settings["damping"] == "marquardt")


def hessian_diagonal(linear: gtsam.GaussianFactorGraph, total_dim: int) -> np.ndarray:
    """diag(A^T A) over all variables, ordered by sorted key (the sparse Jacobian's column order)."""
    _, cols, vals = linear.sparseJacobian_()
    cols = cols.astype(int) - 1
    keep = cols < total_dim  # the last column is the right-hand side
    return np.bincount(cols[keep], weights=vals[keep] ** 2, minlength=total_dim)


class Damping:
    """Builds the damped system: rows sqrt(lambda * diag) per variable (Levenberg: diag = 1), made in one
    numpy pass."""

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


def levenberg_marquardt(graph: GraphEvaluator | gtsam.NonlinearFactorGraph, initial: gtsam.Values, rtol: float, atol: float,
                        max_iterations: int, damping: DampingSettings | None,
                        progress: Callable[[int, float], None] | None = None,
                        qr: bool = False, ordering: str = "colamd",
                        first: tuple[gtsam.GaussianFactorGraph, gtsam.GaussianBayesTree] | None = None,
                        ) -> tuple[gtsam.Values, list[float]]:
    """Minimize graph.error (`graph`: fusionkit's GraphEvaluator, or a gtsam graph); `damping=None` gives
    plain Gauss-Newton; `qr` solves each linear system by QR instead of Cholesky, eliminated in `ordering`
    (colamd, metis). `first`: the system
    linearized at `initial` and its elimination in the same way (checks.check_constrained's), which the
    first iteration then reuses instead of computing them again (the same numbers). Returns
    (values, cost history)."""
    values, cost = initial, graph.error(initial)
    history = [cost]
    damper = Damping(values, damping) if damping else None
    lam = 0.0
    order = None  # the systems of all iterations share one structure: one elimination order serves all
    for it in range(1, max_iterations + 1):
        linear, tree = first if it == 1 and first is not None else (graph.linearize(values), None)
        order = order or elimination_order(linear, ordering)
        diagonal = None
        while True:
            if lam > 0 and diagonal is None:
                diagonal = hessian_diagonal(linear, int(damper.offsets[-1])) if damping.scaled \
                    else np.ones(int(damper.offsets[-1]))
            try:
                if lam == 0 and tree is not None:  # the undamped system, already eliminated
                    delta = tree.optimize()
                else:
                    delta = eliminate(damper.damped(linear, diagonal, lam) if lam > 0 else linear, qr, order).optimize()
            except RuntimeError:  # an undamped system can be singular where the damped one is not
                if not damper or lam > 0:
                    raise
                lam = damping.lambda_initial
                continue
            candidate = values.retract(delta)
            new_cost = graph.error(candidate)
            if damping is None or new_cost <= cost:
                break
            lam = damping.lambda_initial if lam == 0 else lam * damping.lambda_factor
            if lam > damping.lambda_upper:
                return values, history  # no step decreases the cost: a minimum (or stuck)
        if damping and lam > 0:
            lam = max(lam / damping.lambda_factor, damping.lambda_lower)
            if lam < damping.lambda_initial / 100:
                lam = 0.0
        done = _converged(cost, new_cost, rtol, atol)
        values, cost = candidate, new_cost
        history.append(cost)
        if progress:
            progress(it, cost)
        if done or not np.isfinite(cost):
            break
    return values, history
