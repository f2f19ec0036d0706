"""The fast static simulator of a suspended 4-cable robot with heavy cables: Newton's method on
the statics of statics.py (the same model as the calibration factors; exact Jacobians).

- inverse problem: end-effector position t and yaw -> equilibrium roll and pitch, reference
  force, every cable's forces and arc length. Four cables fix four of the six degrees of freedom:
  position and yaw are the inputs, roll and pitch settle (4 height equations, 4 unknowns).
- forward problem: the four arc lengths -> equilibrium pose and forces (8 equations: lengths and
  heights; 8 unknowns: pose and reference force).

The initial reference force is thesis eqs. 5.15-5.17: V = m g / 4, H = V / tan(alpha), alpha the
elevation of the reference cable's chord.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .statics import Equilibrium, SagRobot, equilibrium

TOLERANCE = 1e-9  # on the residual, in m (heights and lengths)
MAX_ITERATIONS = 50


class StaticsError(RuntimeError):
    """Newton's method found no equilibrium (e.g. a pose outside the static workspace)."""


@dataclass
class StaticPose:
    R: np.ndarray          # (3, 3) equilibrium orientation
    t: np.ndarray          # (3,) position (m)
    f_ref: np.ndarray      # (2,) reference cable (H, V) at the end-effector (N)
    state: Equilibrium     # every cable's forces, spans, arc lengths
    iterations: int

    @property
    def forces(self) -> np.ndarray:
        """(n,) tension of each cable at the end-effector, sqrt(H^2 + V^2) (N)."""
        return np.hypot(self.state.H, self.state.V)


def initial_reference_force(R: np.ndarray, t: np.ndarray, pulleys: np.ndarray, robot: SagRobot) -> np.ndarray:
    """Thesis eqs. 5.15-5.17: V0 = m g / 4, H0 = V0 / tan(alpha)."""
    i = robot.reference
    chord = pulleys[i] - (R @ robot.attachments[i] + t)
    alpha = np.arctan2(chord[2], np.hypot(chord[0], chord[1]))
    v0 = robot.weight / robot.n
    return np.array([v0 / np.tan(alpha), v0])


def euler_zyx(yaw: float, pitch: float, roll: float) -> np.ndarray:
    """R = Rz(yaw) Ry(pitch) Rx(roll), angles in rad (the thesis's finite-element data files give degrees)."""
    cy, sy, cp, sp, cr, sr = np.cos(yaw), np.sin(yaw), np.cos(pitch), np.sin(pitch), np.cos(roll), np.sin(roll)
    return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]])


def _add(u, step):
    return u + step


def _newton(residual_and_jacobian, u, retract=_add):
    """Damped Newton from state u (`retract(u, step)` applies a step): full steps, halved while
    they do not lower the residual norm. Returns (state, iterations)."""
    r, J = residual_and_jacobian(u)
    for it in range(1, MAX_ITERATIONS + 1):
        if np.abs(r).max() < TOLERANCE:
            return u, it - 1
        try:
            step = np.linalg.solve(J, -r)
        except np.linalg.LinAlgError:  # singular Jacobian: the least-squares step
            step = np.linalg.lstsq(J, -r, rcond=None)[0]
        norm, lam = np.linalg.norm(r), 1.0
        while lam > 1e-6:
            trial = retract(u, lam * step)
            try:
                r_new, J_new = residual_and_jacobian(trial)
            except np.linalg.LinAlgError:
                r_new = None
            if r_new is not None and np.all(np.isfinite(r_new)) and np.linalg.norm(r_new) < norm:
                break
            lam /= 2
        else:
            break
        u, r, J = trial, r_new, J_new
    if np.abs(r).max() < TOLERANCE * 1e3:
        return u, MAX_ITERATIONS
    raise StaticsError(f"no static equilibrium found (residual {np.abs(r).max():.3g} m)")


def inverse_pose(t: np.ndarray, pulleys: np.ndarray, robot: SagRobot, yaw: float = 0.0) -> StaticPose:
    """Equilibrium at position t (m) and yaw (rad): roll, pitch, forces and arc lengths."""
    t = np.asarray(t, float)

    def fn(u):
        roll, pitch = u[:2]
        R = euler_zyx(yaw, pitch, roll)
        eq = equilibrium(R, t, u[2:], pulleys, robot, jacobian=True, pulley_jacobian=False)
        # d/droll: R exp(eps e_x); d/dpitch: R exp(eps Rx(roll)^T e_y), Rx^T e_y = (0, cos, -sin)
        J_rot = eq.d_height[:, 0:3]
        J = np.column_stack([J_rot[:, 0], J_rot @ [0.0, np.cos(roll), -np.sin(roll)], eq.d_height[:, 6:8]])
        return eq.height_error, J

    u0 = np.concatenate([[0.0, 0.0], initial_reference_force(euler_zyx(yaw, 0, 0), t, pulleys, robot)])
    u, its = _newton(fn, u0)
    R = euler_zyx(yaw, u[1], u[0])
    return _checked(StaticPose(R, t, u[2:], equilibrium(R, t, u[2:], pulleys, robot), its))


def forward_pose(lengths: np.ndarray, pulleys: np.ndarray, robot: SagRobot, R0: np.ndarray,
                 t0: np.ndarray) -> StaticPose:
    """Equilibrium pose for the cable arc lengths (m), by Newton from the guess (R0, t0)."""
    from scipy.spatial.transform import Rotation
    lengths = np.asarray(lengths, float)

    def fn(state):
        eq = equilibrium(*state, pulleys, robot, jacobian=True, pulley_jacobian=False)
        return np.concatenate([eq.length - lengths, eq.height_error]), np.vstack([eq.d_length, eq.d_height])

    def retract(state, step):  # theta's rotation is a right perturbation, its translation world-frame
        R, t, f = state
        return R @ Rotation.from_rotvec(step[:3]).as_matrix(), t + step[3:6], f + step[6:8]

    state0 = (np.asarray(R0, float), np.asarray(t0, float), initial_reference_force(R0, t0, pulleys, robot))
    (R, t, f), its = _newton(fn, state0, retract)
    return _checked(StaticPose(R, t, f, equilibrium(R, t, f, pulleys, robot), its))


def _checked(pose: StaticPose) -> StaticPose:
    """A cable cannot push: every horizontal force must be positive."""
    slack = np.flatnonzero(pose.state.H <= 0)
    if len(slack):
        raise StaticsError(f"cable {int(slack[0])} would be slack at this pose (H = {pose.state.H[slack[0]]:.3g} N)")
    return pose
