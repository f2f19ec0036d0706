"""A forward pass over the states for initial values (docs/models/epuck.md#initial-values): each
pose predicted from the previous one by the commanded motion (velocity model mean and covariance,
propagated as an EKF does), then corrected by that state's IR readings -- Gauss-Newton on the
state alone, the prediction as its prior: an iterated EKF. Dead reckoning drifts by centimetres in a
minute, more than the IR sensors' 7 cm reach can tolerate; the filtered start stays within
millimetres, where the batch solution's basin is."""

from __future__ import annotations

import gtsam
import numpy as np

from .irfactor import IrModelContext, ReadingSet

ITERATIONS = 3
MAX_HALVINGS = 6
TOLERANCE = 1e-6  # m and rad: a smaller step ends the iterations


def correct(pose: gtsam.Pose2, P: np.ndarray, readings: ReadingSet, model: IrModelContext) -> tuple:
    """The pose minimizing xi^T P^-1 xi / 2 + |e(pose Exp(xi))|^2 / 2 (step halving keeps the cost
    falling) and its covariance."""
    info = np.linalg.inv(P)
    ones, zeros = np.ones(len(readings.sensor)), np.zeros(len(readings.sensor))

    def at(xi):
        p = pose.retract(xi)
        e, J, _, _ = model.residual(np.array([p.x(), p.y(), p.theta()]), readings, ones, zeros, jacobians=True)
        return e, J, 0.5 * (xi @ info @ xi + e @ e)

    xi = np.zeros(3)
    e, J, cost = at(xi)
    for _ in range(ITERATIONS):
        A = info + J.T @ J
        step = np.linalg.solve(A, -(info @ xi + J.T @ e))
        if np.max(np.abs(step)) < TOLERANCE:
            break
        for _ in range(MAX_HALVINGS):
            e_new, J_new, cost_new = at(xi + step)
            if cost_new < cost:
                break
            step *= 0.5
        else:
            break
        xi, e, J, cost = xi + step, e_new, J_new, cost_new
    return pose.retract(xi), np.linalg.inv(info + J.T @ J)


def forward_pass(start: gtsam.Pose2, increments: list, readings: list, model: IrModelContext | None,
                 P0: np.ndarray) -> list[gtsam.Pose2]:
    """Poses of every state: `increments[k - 1]` = (mean motion, covariance) from state k - 1 to k;
    `readings[k]` the state's ReadingSet or None."""
    pose, P = start, P0
    out = []
    for k, r in enumerate(readings):
        if k > 0:
            delta, cov = increments[k - 1]
            Ad = delta.inverse().AdjointMap()
            pose, P = pose.compose(delta), Ad @ P @ Ad.T + cov
        if model is not None and r is not None:
            pose, P = correct(pose, P, r, model)
        out.append(pose)
    return out
