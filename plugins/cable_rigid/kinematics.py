"""Forward kinematics of a cable robot from its encoders (thesis eq. 4.1 solved for the pose).

With n < 6 cables the pose is not determined by the lengths alone; the forward kinematics here
solves for the position at a given orientation (the one a controller commands or assumes, identity
by default), which is what "forward kinematics alone" means for an under-constrained robot: it
cannot see a swing that keeps the cable lengths (the thesis's sequence 01;
docs/models/cable_rigid.md#forward-kinematics-baseline).
"""

from __future__ import annotations

import numpy as np

MAX_ITERATIONS = 30
TOLERANCE = 1e-12  # m: largest position step at convergence


def suspended_start(pulleys: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """(K, 3) starting positions below the pulleys: under their centroid, as deep as the mean
    squared cable length allows (the lower of the two mirror solutions of a suspended robot)."""
    centre = pulleys.mean(axis=0)
    horizontal = np.sum((pulleys[:, :2] - centre[:2]) ** 2, axis=1)
    depth = np.sqrt(np.clip(np.mean(lengths ** 2 - horizontal, axis=1), 1e-6, None))
    start = np.tile(centre, (len(lengths), 1))
    start[:, 2] -= depth
    return start


def forward_kinematics(pulleys: np.ndarray, offsets: np.ndarray, attachments: np.ndarray, z: np.ndarray,
                       rotations: np.ndarray | None = None, stretch: np.ndarray | None = None
                       ) -> tuple[np.ndarray, np.ndarray]:
    """Positions (K, 3) minimizing sum_i (||R_k b_i + p_k - a_i|| - l*_ik)^2 per pose, with
    l*_ik = (z_ik - l0_i) / (1 - stretch_ik) (thesis eq. 4.1, or 4.2 with stretch = T/EA); and the rms
    length residual (K,) in m. pulleys a_i (n, 3), offsets l0_i (n,), attachments b_i (n, 3) in
    the end-effector frame, z (K, n) encoder readings, rotations (K, 3, 3) (default identity).
    Gauss-Newton on all poses at once, from `suspended_start`."""
    z = np.atleast_2d(np.asarray(z, float))
    lengths = z - offsets
    if stretch is not None:
        lengths = lengths / (1.0 - stretch)
    arms = np.broadcast_to(attachments, (len(z),) + attachments.shape) if rotations is None else \
        np.einsum("kij,cj->kci", rotations, attachments)
    anchors = pulleys[None] - arms  # p must lie at distance l*_i from a_i - R b_i
    pos = suspended_start(pulleys, lengths)
    for _ in range(MAX_ITERATIONS):
        d = pos[:, None, :] - anchors
        dist = np.linalg.norm(d, axis=2)
        r = dist - lengths
        J = d / dist[..., None]
        step = np.linalg.solve(np.einsum("kci,kcj->kij", J, J), np.einsum("kci,kc->ki", J, r)[..., None])[..., 0]
        pos = pos - step
        if np.abs(step).max() < TOLERANCE:
            break
    residual = np.linalg.norm(pos[:, None, :] - anchors, axis=2) - lengths
    return pos, np.sqrt(np.mean(residual ** 2, axis=1))
