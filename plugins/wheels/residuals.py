"""Residuals of the wheel factors with analytic Jacobians (docs/models/wheels.md#factors).

Per-step residuals are predicted minus measured readings, in the sensor's own units (a wheel's angle, the
gyro's integrated reading): so they do not change along the directions the readings cannot tell apart
(all lengths scaled together; headings, axle length and gyro scale scaled together), and the priors alone
set the intrinsics there. They are scalar functions of two planar poses a, b (x, y in m, theta in rad) and a few
intrinsics: a solver calls each factor on its own, and for a one-row residual plain float arithmetic
costs less than numpy's per-call overhead. Pose Jacobians are in GTSAM's Pose2 tangent (body frame,
[x, y, theta]).

The motion between consecutive states is read as one arc: xi = Log(a^-1 b) = (forward travel, lateral
travel, heading change w) of the axle midpoint at a constant body velocity. With (tx, ty) the
translation of a^-1 b and alpha(w) = (w/2) cot(w/2):

    xi_x = alpha(w) tx + (w/2) ty,    xi_y = -(w/2) tx + alpha(w) ty.

A point of the axle at lateral offset y then travels xi_x - y w forward.
"""

from __future__ import annotations

import math

import numpy as np


def _alpha(w: float) -> tuple[float, float]:
    """alpha(w) = (w/2) cot(w/2) and its derivative (series below |w| = 0.01)."""
    if abs(w) < 1e-2:
        w2 = w * w
        return 1.0 - w2 / 12.0 - w2 * w2 / 720.0, -w / 6.0 - w2 * w / 180.0 - w2 * w2 * w / 5040.0
    h = 0.5 * w
    s = math.sin(h)
    cot = math.cos(h) / s
    return h * cot, 0.5 * (cot - h / (s * s))


def wrap(angle: float) -> float:
    """The angle in [-pi, pi)."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


class Arc:
    """The motion a^-1 b of two Pose2 (each (x, y, theta)) and the derivatives of functions of it."""

    __slots__ = ("tx", "ty", "w", "al", "dal")

    def __init__(self, a, b):
        ax, ay, at = a
        c, s = math.cos(at), math.sin(at)
        dx, dy = b[0] - ax, b[1] - ay
        self.tx, self.ty = c * dx + s * dy, c * dy - s * dx
        self.w = wrap(b[2] - at)
        self.al, self.dal = _alpha(self.w)

    @property
    def forward(self) -> float:
        """xi_x (m)."""
        return self.al * self.tx + 0.5 * self.w * self.ty

    @property
    def lateral(self) -> float:
        """xi_y (m)."""
        return self.al * self.ty - 0.5 * self.w * self.tx

    def pose_rows(self, gx: float, gy: float, gw: float) -> tuple[np.ndarray, np.ndarray]:
        """d f / d (tangent of a) and d f / d (tangent of b), (1, 3) each, of a function f with partial
        derivatives gx, gy, gw in tx, ty, w: d t / d a_xy = -I, d t / d a_theta = (ty, -tx),
        d w / d a_theta = -1; d t / d b_xy = Rot(w), d w / d b_theta = 1."""
        cw, sw = math.cos(self.w), math.sin(self.w)
        return (np.array([[-gx, -gy, gx * self.ty - gy * self.tx - gw]]),
                np.array([[gx * cw + gy * sw, gy * cw - gx * sw, gw]]))


def encoder_residual(a, b, radius: float, lateral: float, angle: float, jacobians: bool = False, slip: float = 0.0):
    """Wheel of `radius` at lateral position `lateral` (m, towards the left wheel) measured turning by `angle`
    (rad) between poses a and b, the wheels turning by `slip` (rad) more than the body (a driven wheel's turn
    slip, e.g. sliding in a fast turn): e = (xi_x - lateral * (w + slip)) / radius - angle, the predicted
    turn minus the measured one (rad). With `jacobians`: (e, [d/da, d/db, d/dradius, d/dlateral, d/dslip])
    as (1, n) arrays."""
    arc = Arc(a, b)
    travel = arc.forward - lateral * (arc.w + slip)
    e = travel / radius - angle
    if not jacobians:
        return e, None
    inv = 1.0 / radius
    ha, hb = arc.pose_rows(inv * arc.al, inv * 0.5 * arc.w, inv * (arc.dal * arc.tx + 0.5 * arc.ty - lateral))
    return e, [ha, hb, np.array([[-travel * inv * inv]]), np.array([[-(arc.w + slip) * inv]]),
               np.array([[-lateral * inv]])]


def gyro_residual(a, b, scale: float, bias: float, integral: float, dt: float, jacobians: bool = False):
    """The gyro reading integrated over the interval (`integral`, rad in the gyro's units) against the
    heading change w of poses a, b: the true rate is scale * reading + bias, so the predicted integral is
    (w - bias * dt) / scale; e = that - integral (rad, the gyro's units). Jacobians: d/da, d/db, d/dscale,
    d/dbias."""
    turn = wrap(b[2] - a[2]) - bias * dt
    e = turn / scale - integral
    if not jacobians:
        return e, None
    inv = 1.0 / scale
    return e, [np.array([[0.0, 0.0, -inv]]), np.array([[0.0, 0.0, inv]]), np.array([[-turn * inv * inv]]),
               np.array([[-dt * inv]])]


def lateral_residual(a, b, jacobians: bool = False):
    """No sideways motion of the axle midpoint: e = xi_y (m). Jacobians: d/da, d/db."""
    arc = Arc(a, b)
    if not jacobians:
        return arc.lateral, None
    return arc.lateral, list(arc.pose_rows(-0.5 * arc.w, arc.al, arc.dal * arc.ty - 0.5 * arc.tx))


def over_read(e: float, sigma: float, direction: int, k: float) -> tuple[float, float]:
    """An encoder residual e (rad; model sigma `sigma`) with reading over-runs down-weighted. `direction` is
    the sign of the wheel's measured turn (0 for a wheel that did not clearly turn); u = -direction e /
    sigma > 0 means the wheel turned further than the motion explains (spinning, slipping, climbing).
    Over-runs cost the Cauchy loss (k^2/2) log(1 + u^2/k^2), everything else u^2/2; the residual is
    returned as sigma * sqrt(2 cost) with the original sign, so its square is the cost. Returns (the
    residual, d residual / d e).

    With q = u / k: rho = k sqrt(log(1 + q^2)) and d residual / d e = u / ((1 + q^2) rho). Beyond q = 1 both
    are written in r = 1/q (log(1 + q^2) = 2 log q + log(1 + r^2), u / (1 + q^2) = k r / (1 + r^2)), so no
    q^2 is formed: it overflows for q above 1e154 (a solver far from the data, e.g. an incremental one
    that diverged), where the loss itself is a modest 2 k^2 log q."""
    sigma = float(sigma)  # plain float arithmetic (a numpy scalar sigma would make every step below numpy's)
    u = -direction * e / sigma
    if u <= 1e-6:  # (the loss is u^2/2 to 1e-12 relative below this)
        return e, 1.0
    q = u / k
    if q <= 1.0:
        rho = k * math.sqrt(math.log1p(q * q))
        return -direction * sigma * rho, u / ((1.0 + q * q) * rho)
    r = 1.0 / q
    rho = k * math.sqrt(2.0 * math.log(q) + math.log1p(r * r))
    return -direction * sigma * rho, k * r / ((1.0 + r * r) * rho)
