"""Driven-wheel odometry preintegrated between two states (docs/models/wheels.md#preintegrated-odometry).

Between states i and j the wheel stream has samples s = 1..n with angle increments a_s (right) and b_s
(left), rad. With the intrinsics theta = (r_L, r_R, A) every sample is an arc of forward travel
d_s = (r_R a_s + r_L b_s) / 2 and heading change delta_s = (r_R a_s - r_L b_s) / A, and the motion
over the window is their composition

    Delta(theta) = Exp(d_1, 0, delta_1) * ... * Exp(d_n, 0, delta_n)
                 = (sum_s l_s (cos m_s, sin m_s), sum_s delta_s),

with the chord l_s = d_s sin(delta_s/2) / (delta_s/2) and the chord's heading m_s = psi_s + delta_s/2
(psi_s: the heading before sample s). All windows are integrated at once, at the nominal intrinsics
theta0, together with J = d Delta / d theta in Delta's tangent (Delta(theta0 + dtheta) = Delta(theta0)
Exp(J dtheta) to first order) and the covariance of Delta from per-sample noise: wheel travel
(sigma, m/sqrt(s)) and sideways slip (lateral_sigma, m/sqrt(s)) in each sample's arc, carried to the
window's end by the right Jacobian of the arc and the adjoint of the rest of the window.
A factor then uses Delta(theta0) Exp(J (theta - theta0)) for the current intrinsics, as IMU
preintegration does for its biases.
"""

from __future__ import annotations

from dataclasses import dataclass

import gtsam
import numpy as np


@dataclass(frozen=True)
class Windows:
    """F preintegrated windows: delta (F, 3) = x, y (m), heading change (rad) at `nominal` (r_L, r_R, A);
    jacobian (F, 3, 3) d tangent / d (r_L, r_R, A); covariance (F, 3, 3) in the tangent of delta."""

    nominal: np.ndarray
    delta: np.ndarray
    jacobian: np.ndarray
    covariance: np.ndarray


def _chord_factor(h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """c = sin(h)/h of h = delta/2, and d c / d delta."""
    small = np.abs(h) < 1e-4
    hs = np.where(small, 1.0, h)
    dc = np.where(small, 0.5 * (-h / 3.0 + h ** 3 / 30.0), 0.5 * (hs * np.cos(hs) - np.sin(hs)) / hs ** 2)
    return np.sinc(h / np.pi), dc


def _adjoints(x: np.ndarray, y: np.ndarray, psi: np.ndarray) -> np.ndarray:
    """(n, 3, 3) Pose2 adjoint maps [[c, -s, y], [s, c, -x], [0, 0, 1]]."""
    c, s = np.cos(psi), np.sin(psi)
    out = np.zeros((len(psi), 3, 3))
    out[:, 0, 0], out[:, 0, 1], out[:, 0, 2] = c, -s, y
    out[:, 1, 0], out[:, 1, 1], out[:, 1, 2] = s, c, -x
    out[:, 2, 2] = 1.0
    return out


def _right_jacobians(d: np.ndarray, turn: np.ndarray) -> np.ndarray:
    """(n, 3, 3) right Jacobians of Pose2.Expmap at (d, 0, turn): Exp(u + n) = Exp(u) Exp(Jr n) to first order."""
    small = np.abs(turn) < 1e-4
    a = np.where(small, 1.0, turn)
    sa, ca = np.sin(a), np.cos(a)
    f = np.where(small, 1.0 - turn ** 2 / 6.0, sa / a)                         # sin(a) / a
    g = np.where(small, turn / 2.0 - turn ** 3 / 24.0, (1.0 - ca) / a)         # (1 - cos(a)) / a
    k = np.where(small, turn / 6.0 - turn ** 3 / 120.0, (a - sa) / a ** 2)     # (a - sin(a)) / a^2
    m = np.where(small, 0.5 - turn ** 2 / 24.0, (1.0 - ca) / a ** 2)           # (1 - cos(a)) / a^2
    out = np.zeros((len(d), 3, 3))
    out[:, 0, 0], out[:, 0, 1], out[:, 0, 2] = f, g, d * k
    out[:, 1, 0], out[:, 1, 1], out[:, 1, 2] = -g, f, d * m
    out[:, 2, 2] = 1.0
    return out


def preintegrate(window: np.ndarray, left: np.ndarray, right: np.ndarray, dt: np.ndarray, nominal,
                 sigma: float, lateral_sigma: float) -> Windows:
    """Windows of samples: `window` (S,) the window index of each sample (0..F-1, non-decreasing, every
    window at least one sample), `left`/`right` the wheel angle increments (rad), dt the sample
    intervals (s), `nominal` (r_L, r_R, A) in m."""
    r_l, r_r, axle = (float(v) for v in nominal)
    starts = np.flatnonzero(np.r_[True, np.diff(window) > 0])

    def before(x: np.ndarray) -> np.ndarray:  # sum over the earlier samples of the same window
        c = np.cumsum(x, axis=0) - x
        return c - c[starts][window]

    d = 0.5 * (r_r * right + r_l * left)
    turn = (r_r * right - r_l * left) / axle
    d_d = np.column_stack([0.5 * left, 0.5 * right, np.zeros_like(left)])    # d d / d (r_L, r_R, A)
    d_turn = np.column_stack([-left / axle, right / axle, -turn / axle])
    psi, d_psi = before(turn), before(d_turn)
    c, dc = _chord_factor(0.5 * turn)
    chord, d_chord = d * c, c[:, None] * d_d + (d * dc)[:, None] * d_turn
    m, d_m = psi + 0.5 * turn, d_psi + 0.5 * d_turn
    u, u_perp = np.column_stack([np.cos(m), np.sin(m)]), np.column_stack([-np.sin(m), np.cos(m)])
    step = chord[:, None] * u
    d_step = u[:, :, None] * d_chord[:, None, :] + chord[:, None, None] * u_perp[:, :, None] * d_m[:, None, :]
    p, d_p = np.add.reduceat(step, starts), np.add.reduceat(d_step, starts)
    heading, d_heading = np.add.reduceat(turn, starts), np.add.reduceat(d_turn, starts)
    cos_h, sin_h = np.cos(heading), np.sin(heading)
    rot_t = np.stack([np.column_stack([cos_h, sin_h]), np.column_stack([-sin_h, cos_h])], axis=1)  # R(heading)^T
    jacobian = np.concatenate([rot_t @ d_p, d_heading[:, None, :]], axis=1)
    # noise of each sample's arc (d, sideways, delta): wheel travels n_R, n_L (sigma^2 dt each), slip
    q = np.column_stack([0.5 * sigma ** 2 * dt, lateral_sigma ** 2 * dt, 2.0 * sigma ** 2 * dt / axle ** 2])
    after = before(step) + step  # the pose after each sample, in the window's start frame
    g = _adjoints(after[:, 0], after[:, 1], psi + turn) @ _right_jacobians(d, turn)
    summed = np.add.reduceat((g * q[:, None, :]) @ np.transpose(g, (0, 2, 1)), starts)
    end_inv = _adjoints(-(rot_t[:, 0] * p).sum(1), -(rot_t[:, 1] * p).sum(1), -heading)
    covariance = end_inv @ summed @ np.transpose(end_inv, (0, 2, 1))
    return Windows(np.array([r_l, r_r, axle]), np.column_stack([p, heading]), jacobian, covariance)


def preintegrated_residual(xi: gtsam.Pose2, xj: gtsam.Pose2, theta: np.ndarray, delta: gtsam.Pose2,
                           jacobian: np.ndarray, nominal: np.ndarray, whiten: np.ndarray, jacobians: bool = False):
    """Whitened e = W Log((delta Exp(J (theta - theta0)))^-1 xi^-1 xj) (W: the inverse Cholesky factor of
    the window's covariance). With `jacobians`: (e, [d/dxi, d/dxj, d/dr_L, d/dr_R, d/dA])."""
    if not jacobians:
        moved = delta.compose(gtsam.Pose2.Expmap(jacobian @ (theta - nominal)))
        return whiten @ gtsam.Pose2.Logmap(moved.between(xi.between(xj))), None
    h_exp, h_i, h_j, h_d, h_b, h_log = (np.zeros((3, 3), order="F") for _ in range(6))
    moved = delta.compose(gtsam.Pose2.Expmap(jacobian @ (theta - nominal), h_exp))
    e = gtsam.Pose2.Logmap(moved.between(xi.between(xj, h_i, h_j), h_d, h_b), h_log)
    outer = whiten @ h_log
    to_b, d_theta = outer @ h_b, outer @ h_d @ h_exp @ jacobian
    return whiten @ e, [to_b @ h_i, to_b @ h_j] + [d_theta[:, [c]] for c in range(3)]
