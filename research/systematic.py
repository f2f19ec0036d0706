"""Classic systematic calibration of a differential drive (docs/models/wheels.md#baselines): pure
functions, no graph.

- `umbmark`: Borenstein & Feng's UMBmark (1996) correction factors E_b (axle length) and E_d (ratio
  of the wheel diameters) from the return-position errors of square runs driven clockwise and
  counter-clockwise.
- `fit_radii_and_axle`: the wheel radii and the axle length from wheel-angle increments and
  ground-truth poses at the ends of path segments, by the two linear least-squares stages of
  Antonelli, Chiaverini & Fusco (2005): the heading change first, then the displacement.

Frames: poses (x, y in m, theta in rad) in the robot's start frame, x forward, y left, theta
counter-clockwise.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class UMBmark:
    """UMBmark's result. alpha: the turn error of each 90-degree turn (rad, positive: the robot turns
    less than its odometry says); beta: the heading change of each straight leg (rad, counter-clockwise
    positive), R: that leg's radius of curvature (m); e_b = b_actual / b_nominal; e_d = D_right / D_left
    (actual, relative to the nominal ratio); the corrected axle length (m) and diameters (m)."""

    alpha: float
    beta: float
    radius: float
    e_b: float
    e_d: float
    axle_length: float
    diameter_right: float
    diameter_left: float


def umbmark(cw_errors: np.ndarray, ccw_errors: np.ndarray, side: float, axle_length: float,
            diameter_right: float, diameter_left: float) -> UMBmark:
    """UMBmark from final position errors (actual minus dead-reckoned, (n, 2) x, y in m) of n square
    runs with side `side` (m) driven clockwise and n counter-clockwise, starting along +x, and the
    nominal axle length and wheel diameters (m) the odometry used.

    To first order, alpha and beta move the clockwise end point by -2 L (beta + alpha) (1, 1) and the
    counter-clockwise one by 2 L (beta - alpha) (1, -1), so from the mean x errors:
        alpha = (x_cw + x_ccw) / (-4 L),   beta = (x_cw - x_ccw) / (-4 L),
        R = (L / 2) / sin(beta / 2),   E_b = (pi / 2) / (pi / 2 - alpha),
        E_d = (R + E_b b / 2) / (R - E_b b / 2)
    (with the corrected axle length E_b b in E_d, as the OptiOdom reference implementation does;
    Borenstein & Feng use the nominal b). The corrected diameters keep their mean when the nominal
    ones are equal: D_right = D_right_nominal * 2 / (1 + 1/E_d), D_left = D_left_nominal * 2 / (1 + E_d)."""
    x_cw, x_ccw = float(np.mean(np.asarray(cw_errors)[:, 0])), float(np.mean(np.asarray(ccw_errors)[:, 0]))
    alpha = (x_cw + x_ccw) / (-4.0 * side)
    beta = (x_cw - x_ccw) / (-4.0 * side)
    radius = (side / 2.0) / np.sin(beta / 2.0) if beta != 0.0 else np.inf
    e_b = (np.pi / 2.0) / (np.pi / 2.0 - alpha)
    b = e_b * axle_length
    e_d = 1.0 if np.isinf(radius) else (radius + b / 2.0) / (radius - b / 2.0)
    return UMBmark(alpha, beta, float(radius), e_b, e_d, b, diameter_right * 2.0 / (1.0 + 1.0 / e_d),
                   diameter_left * 2.0 / (1.0 + e_d))


@dataclass(frozen=True)
class Segment:
    """A stretch of path: per-step wheel-angle increments (rad) of the right and left wheel, and the
    true poses (x, y, theta) at its start and end, theta continuous (unwrapped) between them."""

    d_right: np.ndarray
    d_left: np.ndarray
    start: np.ndarray
    end: np.ndarray


def segments(d_right: np.ndarray, d_left: np.ndarray, poses: np.ndarray, length: int) -> list[Segment]:
    """Consecutive segments of `length` steps of one run: N increments and the N + 1 true poses at
    the samples around them (theta unwrapped here); a shorter remainder is dropped."""
    poses = np.column_stack([poses[:, :2], np.unwrap(poses[:, 2])])
    return [Segment(d_right[i:i + length], d_left[i:i + length], poses[i], poses[i + length])
            for i in range(0, len(d_right) - length + 1, length)]


@dataclass(frozen=True)
class WheelParameters:
    radius_right: float  # m
    radius_left: float   # m
    axle_length: float   # m


def fit_radii_and_axle(segs: list[Segment]) -> WheelParameters:
    """Wheel radii and axle length from segments, by two linear least-squares stages (Antonelli,
    Chiaverini & Fusco 2005):

    1. heading: theta_end - theta_start = c_R sum(d_right) - c_L sum(d_left), with c_R = r_R / A and
       c_L = r_L / A: one row per segment;
    2. scale: with the headings theta_k those c give from theta_start, each step moves the midpoint by
       A (c_R d_right_k + c_L d_left_k) / 2 along the exact arc (chord factor sinc, at the mean heading
       of the step), so x and y of each segment's end relative to its start are linear in A alone: two
       rows per segment; then r_R = c_R A, r_L = c_L A.

    Segments must turn both ways (or at different rates) for stage 1, and move for stage 2."""
    a1 = np.array([[s.d_right.sum(), -s.d_left.sum()] for s in segs])
    b1 = np.array([s.end[2] - s.start[2] for s in segs])
    (c_r, c_l), *_ = np.linalg.lstsq(a1, b1, rcond=None)
    rows, rhs = [], []
    for s in segs:
        dth = c_r * s.d_right - c_l * s.d_left
        mid = s.start[2] + np.concatenate([[0.0], np.cumsum(dth)[:-1]]) + 0.5 * dth
        step = 0.5 * (c_r * s.d_right + c_l * s.d_left) * np.sinc(dth / (2.0 * np.pi))
        rows += [np.sum(step * np.cos(mid)), np.sum(step * np.sin(mid))]
        rhs += [s.end[0] - s.start[0], s.end[1] - s.start[1]]
    rows, rhs = np.array(rows), np.array(rhs)
    axle = float(rows @ rhs / (rows @ rows))
    return WheelParameters(float(c_r * axle), float(c_l * axle), axle)
