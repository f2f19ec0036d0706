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

import math
from dataclasses import dataclass

import numpy as np

from fusionkit.api import se2


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


def _arcs(left: np.ndarray, right: np.ndarray, r_l: float, r_r: float, axle: float):
    """Each sample's forward travel d and heading change delta (rad), and their derivatives in (r_L, r_R, A)."""
    d = 0.5 * (r_r * right + r_l * left)
    turn = (r_r * right - r_l * left) / axle
    d_d = np.column_stack([0.5 * left, 0.5 * right, np.zeros_like(left)])
    d_turn = np.column_stack([-left / axle, right / axle, -turn / axle])
    return d, d_d, turn, d_turn


def _chords(d, d_d, turn, d_turn, psi, d_psi) -> tuple[np.ndarray, np.ndarray]:
    """Each sample's chord (S, 2) in the frame its heading psi is measured in, and its derivative (S, 2, 3)."""
    c, dc = _chord_factor(0.5 * turn)
    chord, d_chord = d * c, c[:, None] * d_d + (d * dc)[:, None] * d_turn
    m, d_m = psi + 0.5 * turn, d_psi + 0.5 * d_turn
    u, u_perp = np.column_stack([np.cos(m), np.sin(m)]), np.column_stack([-np.sin(m), np.cos(m)])
    step = chord[:, None] * u
    d_step = u[:, :, None] * d_chord[:, None, :] + chord[:, None, None] * u_perp[:, :, None] * d_m[:, None, :]
    return step, d_step


@dataclass(frozen=True)
class Reckoning:
    """Dead reckoning from the identity pose over S samples: position (S + 1, 2), m, and heading (S + 1,),
    rad, after each sample (row 0: the start), and their derivatives (S + 1, 2, 3) and (S + 1, 3) in
    (r_L, r_R, A)."""

    position: np.ndarray
    heading: np.ndarray
    d_position: np.ndarray
    d_heading: np.ndarray


def dead_reckon(left: np.ndarray, right: np.ndarray, theta) -> Reckoning:
    """The exact composition of the samples' arcs (wheel angle increments left/right, rad) at intrinsics
    theta = (r_L, r_R, A), m, with its analytic derivative."""
    r_l, r_r, axle = (float(v) for v in theta)
    d, d_d, turn, d_turn = _arcs(left, right, r_l, r_r, axle)
    heading = np.concatenate([[0.0], np.cumsum(turn)])
    d_heading = np.concatenate([np.zeros((1, 3)), np.cumsum(d_turn, axis=0)])
    step, d_step = _chords(d, d_d, turn, d_turn, heading[:-1], d_heading[:-1])
    position = np.concatenate([np.zeros((1, 2)), np.cumsum(step, axis=0)])
    d_position = np.concatenate([np.zeros((1, 2, 3)), np.cumsum(d_step, axis=0)])
    return Reckoning(position, heading, d_position, d_heading)


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

    d, d_d, turn, d_turn = _arcs(left, right, r_l, r_r, axle)
    psi, d_psi = before(turn), before(d_turn)
    step, d_step = _chords(d, d_d, turn, d_turn, psi, d_psi)
    p, d_p = np.add.reduceat(step, starts), np.add.reduceat(d_step, starts)
    heading, d_heading = np.add.reduceat(turn, starts), np.add.reduceat(d_turn, starts)
    cos_h, sin_h = np.cos(heading), np.sin(heading)
    rot_t = np.stack([np.column_stack([cos_h, sin_h]), np.column_stack([-sin_h, cos_h])], axis=1)  # R(heading)^T
    jacobian = np.concatenate([rot_t @ d_p, d_heading[:, None, :]], axis=1)
    # noise of each sample's arc (d, sideways, delta): wheel travels n_R, n_L (sigma^2 dt each), slip
    q = np.column_stack([0.5 * sigma ** 2 * dt, lateral_sigma ** 2 * dt, 2.0 * sigma ** 2 * dt / axle ** 2])
    after = before(step) + step  # the pose after each sample, in the window's start frame
    zeros = np.zeros_like(d)
    g = se2.adjoint(np.column_stack([after, psi + turn])) @ se2.jr(np.column_stack([d, zeros, turn]))
    summed = np.add.reduceat((g * q[:, None, :]) @ np.transpose(g, (0, 2, 1)), starts)
    end_inv = se2.adjoint(se2.inverse(np.column_stack([p, heading])))
    covariance = end_inv @ summed @ np.transpose(end_inv, (0, 2, 1))
    return Windows(np.array([r_l, r_r, axle]), np.column_stack([p, heading]), jacobian, covariance)


def _coefficients(w: float) -> tuple[float, float, float, float]:
    """(sin w / w, (1 - cos w) / w, (w - sin w) / w^2, (1 - cos w) / w^2), with series below se2.SMALL."""
    if abs(w) < se2.SMALL:
        w2 = w * w
        w4 = w2 * w2
        return (1.0 - w2 / 6.0 + w4 / 120.0, w * (0.5 - w2 / 24.0 + w4 / 720.0), w * (1.0 / 6.0 - w2 / 120.0 + w4 / 5040.0),
                0.5 - w2 / 24.0 + w4 / 720.0)
    s, c = math.sin(w), math.cos(w)
    return s / w, (1.0 - c) / w, (w - s) / (w * w), (1.0 - c) / (w * w)


def _between(a, b) -> tuple[float, float, float]:
    """a^-1 b of Pose2 (x, y, theta) tuples."""
    c, s = math.cos(a[2]), math.sin(a[2])
    dx, dy = b[0] - a[0], b[1] - a[1]
    return c * dx + s * dy, -s * dx + c * dy, b[2] - a[2]


def _adjoint_inverse(p) -> tuple:
    """Ad(p^-1) of a Pose2 (x, y, theta): [[c, s, x s - y c], [-s, c, x c + y s], [0, 0, 1]]."""
    c, s = math.cos(p[2]), math.sin(p[2])
    return (c, s, p[0] * s - p[1] * c), (-s, c, p[0] * c + p[1] * s), (0.0, 0.0, 1.0)


def _product(a, b) -> tuple:
    """a b of 3x3 matrices as row tuples."""
    (a00, a01, a02), (a10, a11, a12), (a20, a21, a22) = a
    (b00, b01, b02), (b10, b11, b12), (b20, b21, b22) = b
    return ((a00 * b00 + a01 * b10 + a02 * b20, a00 * b01 + a01 * b11 + a02 * b21, a00 * b02 + a01 * b12 + a02 * b22),
            (a10 * b00 + a11 * b10 + a12 * b20, a10 * b01 + a11 * b11 + a12 * b21, a10 * b02 + a11 * b12 + a12 * b22),
            (a20 * b00 + a21 * b10 + a22 * b20, a20 * b01 + a21 * b11 + a22 * b21, a20 * b02 + a21 * b12 + a22 * b22))


def preintegrated_residual(xi, xj, theta, delta, jacobian, nominal, whiten, jacobians: bool = False):
    """Whitened e = W Log(M^-1 xi^-1 xj), M = Delta Exp(u), u = J (theta - theta0) (W: the inverse Cholesky factor
    of the window's covariance; e in sigmas), for one window: poses xi, xj and delta as (x, y, theta), theta and
    theta0 = (r_L, r_R, A), J and W 3x3 as row tuples. With `jacobians`: (e, [d/dxi, d/dxj, d/dr_L, d/dr_R, d/dA]);
    with B = xi^-1 xj, E = M^-1 B: de/dxj = W Jr^-1(Log E), de/dxi = -W Jr^-1 Ad(B^-1), de/dtheta = -W Jr^-1
    Ad(E^-1) Jr(u) J. Scalar arithmetic: GTSAM's incremental solvers call the factor one at a time, where numpy's
    per-call overhead would dominate."""
    d0, d1, d2 = theta[0] - nominal[0], theta[1] - nominal[1], theta[2] - nominal[2]
    (j00, j01, j02), (j10, j11, j12), (j20, j21, j22) = jacobian
    u0, u1, u2 = j00 * d0 + j01 * d1 + j02 * d2, j10 * d0 + j11 * d1 + j12 * d2, j20 * d0 + j21 * d1 + j22 * d2
    f, g, k, m = _coefficients(u2)
    c, s = math.cos(delta[2]), math.sin(delta[2])
    ex, ey = f * u0 - g * u1, g * u0 + f * u1  # Exp(u)'s translation
    moved = (delta[0] + c * ex - s * ey, delta[1] + s * ex + c * ey, delta[2] + u2)
    b = _between(xi, xj)
    error = _between(moved, b)
    w = math.atan2(math.sin(error[2]), math.cos(error[2]))
    ef, eg, ek, em = _coefficients(w)
    n = ef * ef + eg * eg
    log = ((ef * error[0] + eg * error[1]) / n, (-eg * error[0] + ef * error[1]) / n, w)
    e = np.array([w0 * log[0] + w1 * log[1] + w2 * log[2] for w0, w1, w2 in whiten])
    if not jacobians:
        return e, None
    b0, b1 = log[0] * ek - log[1] * em, log[0] * em + log[1] * ek  # Jr(log)'s last column
    to_log = _product(whiten, ((ef / n, -eg / n, -(ef * b0 - eg * b1) / n),
                               (eg / n, ef / n, -(eg * b0 + ef * b1) / n), (0.0, 0.0, 1.0)))
    jr_u = ((f, g, u0 * k - u1 * m), (-g, f, u0 * m + u1 * k), (0.0, 0.0, 1.0))
    d_theta = _product(_product(_product(to_log, _adjoint_inverse(error)), jr_u), jacobian)
    d_xi = _product(to_log, _adjoint_inverse(b))
    blocks = np.array([r_i + r_j + r_t for r_i, r_j, r_t in zip(d_xi, to_log, d_theta)])  # negated below
    blocks[:, :3] *= -1.0
    blocks[:, 6:] *= -1.0
    return e, [blocks[:, :3], blocks[:, 3:6], blocks[:, 6:7], blocks[:, 7:8], blocks[:, 8:9]]
