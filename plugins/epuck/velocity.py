"""The velocity motion model of Probabilistic Robotics [Thrun, Burgard and Fox 2005, sec. 5.3]
(docs/models/epuck.md#velocity-motion-model), in SI units.

A command (v, omega) (m/s, rad/s) held for dt (s) moves a robot along an arc. The executed speeds
are noisy, v_hat = v + e_v, omega_hat = omega + e_w, and a final rotation gamma_hat is added, with
standard deviations

    sigma_v = alpha1 |v| + alpha2 |omega|      (alpha1: -, alpha2: m/rad)
    sigma_w = alpha3 |v| + alpha4 |omega|      (alpha3: rad/m, alpha4: -)
    sigma_g = alpha5 |v| + alpha6 |omega|      (alpha5: rad/m, alpha6: -)

The book's arc x' = x - v/w sin(theta) + v/w sin(theta + w dt), ... is the Pose2 exponential of the
body twist tau = (v dt, 0, omega dt): X' = X Exp(tau) Rot(gamma dt). To first order in the noise,
Exp(tau + delta) = Exp(tau) Exp(Jr(tau) delta) with Jr the right Jacobian of SE(2), so the body-frame
motion has covariance

    Sigma = Jr diag((sigma_v dt)^2, 0, (sigma_w dt)^2) Jr^T + diag(0, 0, (sigma_g dt)^2),

which depends on the command only (in the world frame it turns with the heading: the EKF's
V M V^T of the book's Table 7.2). Consecutive commands compose by the adjoint. Jr is fusionkit.api.se2's
(its entries' series below a small turn angle make a straight line exact).
"""

from __future__ import annotations

import gtsam
import numpy as np

from fusionkit.api import se2, unicycle_increment

def control_sigmas(v: np.ndarray, omega: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """(N, 3) standard deviations (sigma_v, sigma_w, sigma_g) of the executed controls (alpha: 4 or 6)."""
    a = np.zeros(6)
    a[:len(alpha)] = alpha
    av, aw = np.abs(np.asarray(v, float)), np.abs(np.asarray(omega, float))
    return np.column_stack([a[0] * av + a[1] * aw, a[2] * av + a[3] * aw, a[4] * av + a[5] * aw])


def step_covariance(v: float, omega: float, dt: float, sigmas: np.ndarray) -> np.ndarray:
    """Body-frame covariance (3x3, GTSAM's Pose2 tangent) of one command held for dt."""
    Jr = se2.jr(np.array([[v * dt, 0.0, omega * dt]]))[0]
    M = np.diag([(sigmas[0] * dt) ** 2, 0.0, (sigmas[1] * dt) ** 2])
    return Jr @ M @ Jr.T + np.diag([0.0, 0.0, (sigmas[2] * dt) ** 2])


def preintegrate(v: np.ndarray, omega: np.ndarray, dt: np.ndarray, alpha: np.ndarray) -> tuple[gtsam.Pose2, np.ndarray]:
    """The mean body-frame motion of commands (v, omega) each held for its dt, and its covariance."""
    sig = control_sigmas(v, omega, alpha)
    cov = np.zeros((3, 3))
    for vk, wk, h, s in zip(np.asarray(v, float), np.asarray(omega, float), np.asarray(dt, float), sig):
        Ad = gtsam.Pose2.Expmap(np.array([vk * h, 0.0, wk * h])).inverse().AdjointMap()
        cov = Ad @ cov @ Ad.T + step_covariance(vk, wk, h, s)
    return unicycle_increment(np.asarray(v, float), np.asarray(omega, float), np.asarray(dt, float)), cov


def sample_motion(pose: np.ndarray, v: float, omega: float, dt: float, alpha: np.ndarray,
                  rng: np.random.Generator) -> np.ndarray:
    """One draw of the book's sample_motion_model_velocity from pose (x, y, theta): the arc of noisy
    speeds held for dt, then the final rotation."""
    sv, sw, sg = control_sigmas([v], [omega], alpha)[0]
    vh, wh, gh = v + rng.normal(0.0, sv), omega + rng.normal(0.0, sw), rng.normal(0.0, sg)
    step = gtsam.Pose2.Expmap(np.array([vh * dt, 0.0, wh * dt]))
    out = gtsam.Pose2(*pose).compose(step).compose(gtsam.Pose2(0.0, 0.0, gh * dt))
    return np.array([out.x(), out.y(), out.theta()])
