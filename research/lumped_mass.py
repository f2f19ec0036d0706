"""An independent discretized model of the heavy cables, to validate the catenary statics: each
cable is a chain of N rigid links whose weight w h (h = length / N) is lumped at the link
midpoints, solved for static equilibrium with a general root finder -- no hyperbolic functions,
no reference-cable elimination, no analytic Jacobians.

A chain held at the end-effector by (H, V) (the force the cable exerts there: H towards the
pulley, V up) carries the tension (H, V + w h (j + 1/2)) in link j counted from the end-effector;
each link lies along its tension, so the far end sits at

    span = h sum_j H / |T_j|,   rise = h sum_j (V + w h (j + 1/2)) / |T_j|.

The whole robot: unknown pose (rotation vector, position) and every cable's (H_i, V_i); equations:
every chain ends at its pulley (span and rise, 2 per cable) and the end-effector's forces and
moments balance its weight (6). Errors against the continuous catenary fall as 1 / N^2.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import root
from scipy.spatial.transform import Rotation

from fusionkit_plugins.cable_sag.statics import SagRobot

SEGMENTS = 2000


def chain_end(H: float, V: float, length: float, w: float, segments: int = SEGMENTS) -> tuple[float, float]:
    """(span, rise) of the far end of a chain of `length` (m) and weight w (N/m) under (H, V) (N)."""
    h = length / segments
    Vj = V + w * h * (np.arange(segments) + 0.5)
    T = np.hypot(H, Vj)
    return float(h * np.sum(H / T)), float(h * np.sum(Vj / T))


def chain_forces(length: float, span: float, rise: float, w: float, guess=(1.0, 1.0),
                 segments: int = SEGMENTS) -> np.ndarray:
    """(H, V) that make a chain of `length` reach (span, rise)."""
    sol = root(lambda f: np.subtract(chain_end(f[0], f[1], length, w, segments), (span, rise)), guess,
               method="hybr", options={"xtol": 1e-13})
    if not sol.success:
        raise RuntimeError(f"chain equilibrium not found: {sol.message}")
    return sol.x


def _equations(x: np.ndarray, lengths: np.ndarray, pulleys: np.ndarray, robot: SagRobot, segments: int):
    R, t = Rotation.from_rotvec(x[:3]).as_matrix(), x[3:6]
    H, V = x[6::2], x[7::2]
    r = robot.attachments @ R.T
    d = r + t - pulleys
    span = np.hypot(d[:, 0], d[:, 1])
    s = np.column_stack([d[:, :2] / span[:, None], np.zeros(len(d))])
    ends = np.array([chain_end(H[i], V[i], lengths[i], robot.cable_weight, segments) for i in range(len(d))])
    forces = -H[:, None] * s + V[:, None] * np.array([0.0, 0.0, 1.0])
    gravity = np.array([0.0, 0.0, -robot.weight])
    net_force = forces.sum(axis=0) + gravity
    net_moment = np.cross(r, forces).sum(axis=0) + np.cross(R @ robot.com, gravity)
    scale = robot.weight  # forces in units of the weight, so every equation is O(1)
    return np.concatenate([ends[:, 0] - span, ends[:, 1] + d[:, 2], net_force / scale, net_moment / scale])


def lumped_forward_pose(lengths: np.ndarray, pulleys: np.ndarray, robot: SagRobot, R0: np.ndarray,
                        t0: np.ndarray, f0: np.ndarray, segments: int = SEGMENTS):
    """Equilibrium of the whole robot with chain cables: (R, t, H (n,), V (n,)), from a guess."""
    x0 = np.concatenate([Rotation.from_matrix(R0).as_rotvec(), t0, np.ravel(f0)])
    sol = root(_equations, x0, args=(np.asarray(lengths, float), pulleys, robot, segments), method="hybr",
               options={"xtol": 1e-12})
    if not sol.success:
        raise RuntimeError(f"lumped-mass equilibrium not found: {sol.message}")
    x = sol.x
    return Rotation.from_rotvec(x[:3]).as_matrix(), x[3:6], x[6::2], x[7::2]
