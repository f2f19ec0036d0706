"""SE(2) in GTSAM's conventions for many planar poses at once (numpy, leading axis N): poses are
(N, 3) [x, y, theta] (m, m, rad), twists (N, 3) [vx, vy, w] as `gtsam.Pose2.Expmap` takes them and
perturb a pose on the right, X Exp(d); Jr is GTSAM's `Pose2.ExpmapDerivative` and Jr^-1 its
`LogmapDerivative`. Composed angles are not wrapped (gtsam.Pose2 wraps them when built); `log` wraps.
The closed forms divide by the turn angle; below SMALL they are replaced by their Taylor series."""

from __future__ import annotations

import numpy as np

SMALL = 1e-2  # rad: below it the series (to w^5), exact to about 1 ulp; above it the closed forms (cancellation ~1e-11)


def _rotate(theta: np.ndarray, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    c, s = np.cos(theta), np.sin(theta)
    return c * x - s * y, s * x + c * y


def compose(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a b (N, 3)."""
    x, y = _rotate(a[..., 2], b[..., 0], b[..., 1])
    return np.stack([a[..., 0] + x, a[..., 1] + y, a[..., 2] + b[..., 2]], axis=-1)


def inverse(p: np.ndarray) -> np.ndarray:
    """p^-1 (N, 3)."""
    x, y = _rotate(-p[..., 2], p[..., 0], p[..., 1])
    return np.stack([-x, -y, -p[..., 2]], axis=-1)


def between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a^-1 b (N, 3)."""
    x, y = _rotate(-a[..., 2], b[..., 0] - a[..., 0], b[..., 1] - a[..., 1])
    return np.stack([x, y, b[..., 2] - a[..., 2]], axis=-1)


def adjoint(p: np.ndarray) -> np.ndarray:
    """Ad(p) (N, 3, 3): p Exp(d) p^-1 = Exp(Ad(p) d); [[c, -s, y], [s, c, -x], [0, 0, 1]]."""
    c, s = np.cos(p[..., 2]), np.sin(p[..., 2])
    out = np.zeros(p.shape[:-1] + (3, 3))
    out[..., 0, 0], out[..., 0, 1], out[..., 0, 2] = c, -s, p[..., 1]
    out[..., 1, 0], out[..., 1, 1], out[..., 1, 2] = s, c, -p[..., 0]
    out[..., 2, 2] = 1.0
    return out


def _coefficients(w: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(sin w / w, (1 - cos w) / w, (w - sin w) / w^2, (1 - cos w) / w^2), with series below SMALL."""
    small = np.abs(w) < SMALL
    a = np.where(small, 1.0, w)
    s, c, w2 = np.sin(a), np.cos(a), w ** 2
    w4 = w2 * w2
    return (np.where(small, 1.0 - w2 / 6.0 + w4 / 120.0, s / a),
            np.where(small, w * (0.5 - w2 / 24.0 + w4 / 720.0), (1.0 - c) / a),
            np.where(small, w * (1.0 / 6.0 - w2 / 120.0 + w4 / 5040.0), (a - s) / a ** 2),
            np.where(small, 0.5 - w2 / 24.0 + w4 / 720.0, (1.0 - c) / a ** 2))


def exp(d: np.ndarray) -> np.ndarray:
    """Exp of twists (N, 3) -> poses (N, 3): translation V(w) [vx, vy], V = [[f, -g], [g, f]]."""
    f, g, _, _ = _coefficients(d[..., 2])
    vx, vy = d[..., 0], d[..., 1]
    return np.stack([f * vx - g * vy, g * vx + f * vy, d[..., 2]], axis=-1)


def log(p: np.ndarray) -> np.ndarray:
    """Log of poses (N, 3) -> twists (N, 3), the angle wrapped to [-pi, pi]: V(w)^-1 [x, y]."""
    w = np.arctan2(np.sin(p[..., 2]), np.cos(p[..., 2]))
    f, g, _, _ = _coefficients(w)
    n = f ** 2 + g ** 2
    x, y = p[..., 0], p[..., 1]
    return np.stack([(f * x + g * y) / n, (-g * x + f * y) / n, w], axis=-1)


def jr(d: np.ndarray) -> np.ndarray:
    """Right Jacobian (N, 3, 3) at twists d: Exp(d + e) = Exp(d) Exp(Jr e) to first order."""
    f, g, k, m = _coefficients(d[..., 2])
    vx, vy = d[..., 0], d[..., 1]
    out = np.zeros(d.shape[:-1] + (3, 3))
    out[..., 0, 0], out[..., 0, 1], out[..., 0, 2] = f, g, vx * k - vy * m
    out[..., 1, 0], out[..., 1, 1], out[..., 1, 2] = -g, f, vx * m + vy * k
    out[..., 2, 2] = 1.0
    return out


def jr_inv(d: np.ndarray) -> np.ndarray:
    """Jr^-1 (N, 3, 3): the derivative of Log at Exp(d) in right perturbations. Jr = [[A, b], [0, 1]] with
    A = [[f, g], [-g, f]], so Jr^-1 = [[A^-1, -A^-1 b], [0, 1]], A^-1 = A^T / (f^2 + g^2)."""
    J = jr(d)
    f, g = J[..., 0, 0], J[..., 0, 1]
    n = f ** 2 + g ** 2
    a_inv = np.zeros(d.shape[:-1] + (2, 2))
    a_inv[..., 0, 0], a_inv[..., 0, 1], a_inv[..., 1, 0], a_inv[..., 1, 1] = f / n, -g / n, g / n, f / n
    out = np.zeros_like(J)
    out[..., :2, :2] = a_inv
    out[..., :2, 2] = -np.einsum("...ij,...j->...i", a_inv, J[..., :2, 2])
    out[..., 2, 2] = 1.0
    return out
