"""A cable leaving a swivelling pulley of radius rho (docs/models/cable_rigid.md#pulley-radius): part of the core's
cable robot model (public as fusionkit.api.pulley_cables), shared by the cable families and the length predictor.

The cable arrives at the swivel point A travelling along the swivel axis u, wraps over a pulley of radius
rho that turns about u to face the attachment point P, and leaves it at the tangent point T. In the pulley's
plane (radial unit e towards P, and u), with C = A + rho e the pulley's centre, A is at angle pi from C and
the cable runs clockwise (at A its direction is +u). With x = |(P - A)_perp| - rho, y = (P - A).u and
D = sqrt(x^2 + y^2) > rho, the tangent point is at the angle phi = atan2(y, x) +- acos(rho / D) whose
clockwise tangent points at P, and

    length = rho * wrap + sqrt(D^2 - rho^2),   wrap = (pi - phi) mod 2 pi.

The length's gradient in P is the unit vector n of the free cable (T to P) -- the wrap's change and the
tangent point's cancel to first order -- and in A it is -n (moving the pulley is moving P the other way).
With rho = 0 this is ||P - A||, the rigid model.
"""

from __future__ import annotations

import numpy as np


def pulley_cables(P: np.ndarray, A: np.ndarray, rho: float, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(lengths (N,), free-cable unit vectors n (N, 3)) from swivel points A to attachment points P (N, 3),
    over pulleys of radius rho turning about the unit axis u (the incoming cable's direction)."""
    P, A = np.atleast_2d(np.asarray(P, float)), np.atleast_2d(np.asarray(A, float))
    u = np.asarray(u, float) / np.linalg.norm(u)
    d = P - A
    if rho == 0.0:
        length = np.linalg.norm(d, axis=1)
        return length, d / length[:, None]
    y = d @ u
    radial = d - y[:, None] * u
    r = np.linalg.norm(radial, axis=1)
    side = np.cross(u, [1.0, 0.0, 0.0] if abs(u[0]) < 0.9 else [0.0, 1.0, 0.0])  # any horizontal direction
    e = np.where((r > 1e-9)[:, None], radial / np.maximum(r, 1e-12)[:, None], side / np.linalg.norm(side))
    x = r - rho
    D = np.hypot(x, y)
    if np.any(D <= rho):
        raise ValueError("an attachment point lies inside a pulley's circle (closer to its centre than its radius)")
    theta, alpha = np.arctan2(y, x), np.arccos(rho / D)
    free = np.sqrt(D ** 2 - rho ** 2)
    best_length, best_n = None, None
    for phi in (theta + alpha, theta - alpha):
        T = A + rho * e + rho * (np.cos(phi)[:, None] * e + np.sin(phi)[:, None] * u)
        tangent = np.sin(phi)[:, None] * e - np.cos(phi)[:, None] * u  # clockwise at phi
        n = (P - T) / free[:, None]
        wrap = np.mod(np.pi - phi, 2 * np.pi)
        ok = np.sum(n * tangent, axis=1) > 0
        length = rho * wrap + free
        best_length = np.where(ok, length, best_length) if best_length is not None else np.where(ok, length, np.nan)
        best_n = np.where(ok[:, None], n, best_n) if best_n is not None else np.where(ok[:, None], n, np.nan)
    return best_length, best_n
