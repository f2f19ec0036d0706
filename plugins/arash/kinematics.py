"""Forward kinematics of ARASH:ASiST's parallelogram remote-centre-of-motion (RCM) arm, in the two
documented conventions, with analytic Jacobians, the frame change between them and the closed-form
inverse kinematics (docs/models/arash.md).

Joints q = (phi, psi, d): phi (rad) turns the parallelogram about the axis through the base origin
and the RCM, psi (rad) is the parallelogram angle, d the insertion of the tool through the RCM.
Kinematic parameters k = (alpha, theta, l_1234): alpha (rad) offsets psi (beta = alpha + psi),
theta (rad) is the angle of the phi axis in the base frame, l_1234 the distance from the base
origin to the RCM along it.

- `thesis` (thesis eq. 3.7), lengths in metres:
      p = Rz(theta) (l_1234 e_x + d Rx(phi) [cos beta, sin beta, 0])
- `authors_code` (the authors' public calibration code), lengths in millimetres:
      p = l_1234 [sin theta, 0, cos theta] - d u,
      u = [cb st + sb cp ct,  sb sp,  cb ct - sb cp st]
  (cb = cos beta, sb = sin beta, cp = cos phi, sp = sin phi, ct = cos theta, st = sin theta).

Frame change: the same arm, the same angles; the authors' axes are the thesis's cycled
(x_code = y_thesis, y_code = z_thesis, z_code = x_thesis: `CODE_R_THESIS`, a proper rotation),
their lengths in mm, and their insertion counted the other way (d_code = -1000 d_thesis):
    p_code(phi, psi, d_code; alpha, theta, 1000 l) = 1000 CODE_R_THESIS p_thesis(phi, psi, d; alpha, theta, l).
"""

from __future__ import annotations

import numpy as np

CONVENTIONS = {"thesis": "m", "authors_code": "mm"}  # convention -> its length unit
MM_PER_M = 1000.0
CODE_R_THESIS = np.array([[0.0, 1.0, 0.0],
                          [0.0, 0.0, 1.0],
                          [1.0, 0.0, 0.0]])  # x_code = y_thesis, y_code = z_thesis, z_code = x_thesis


def tip_position(q: np.ndarray, k: np.ndarray, convention: str) -> np.ndarray:
    """Tool tip in the base frame (the convention's length unit) for joints q (..., 3) and
    parameters k (..., 3) = (alpha, theta, l_1234); shape (..., 3)."""
    return _tip(np.asarray(q, float), np.asarray(k, float), convention, False)[0]


def tip_jacobians(q: np.ndarray, k: np.ndarray, convention: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(p, dp/dq (3x3, columns phi, psi, d), dp/dk (3x3, columns alpha, theta, l_1234)) of one configuration."""
    return _tip(np.asarray(q, float), np.asarray(k, float), convention, True)


def _tip(q, k, convention, jacobians):
    phi, psi, d = q[..., 0], q[..., 1], q[..., 2]
    alpha, theta, length = k[..., 0], k[..., 1], k[..., 2]
    beta = alpha + psi
    cb, sb, cp, sp, ct, st = np.cos(beta), np.sin(beta), np.cos(phi), np.sin(phi), np.cos(theta), np.sin(theta)
    if convention == "thesis":
        # tool direction v = Rz(theta) Rx(phi) [cb, sb, 0]
        v = np.stack([ct * cb - st * cp * sb, st * cb + ct * cp * sb, sp * sb], axis=-1)
        p = length[..., None] * np.stack([ct, st, np.zeros_like(ct)], axis=-1) + d[..., None] * v
        if not jacobians:
            return p, None, None
        dv_dbeta = np.array([-ct * sb - st * cp * cb, -st * sb + ct * cp * cb, sp * cb])
        dv_dphi = np.array([st * sp * sb, -ct * sp * sb, cp * sb])
        d_theta = np.array([-p[1], p[0], 0.0])  # rotation about z
        d_length = np.array([ct, st, 0.0])
        jq = np.column_stack([d * dv_dphi, d * dv_dbeta, v])
    elif convention == "authors_code":
        u = np.stack([cb * st + sb * cp * ct, sb * sp, cb * ct - sb * cp * st], axis=-1)
        p = length[..., None] * np.stack([st, np.zeros_like(st), ct], axis=-1) - d[..., None] * u
        if not jacobians:
            return p, None, None
        du_dbeta = np.array([-sb * st + cb * cp * ct, cb * sp, -sb * ct - cb * cp * st])
        du_dphi = np.array([-sb * sp * ct, sb * cp, sb * sp * st])
        d_theta = np.array([p[2], 0.0, -p[0]])  # rotation about y
        d_length = np.array([st, 0.0, ct])
        jq = np.column_stack([-d * du_dphi, -d * du_dbeta, -u])
    else:
        raise ValueError(f"unknown convention {convention!r}; accepted: {', '.join(CONVENTIONS)}")
    jk = np.column_stack([jq[:, 1], d_theta, d_length])  # alpha enters as psi does
    return p, jq, jk


def code_from_thesis(q: np.ndarray, k: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Joints (..., 3) and parameters (..., 3) of the thesis convention (m) in the authors' (mm)."""
    q_code, k_code = np.array(q, float), np.array(k, float)
    q_code[..., 2] *= -MM_PER_M
    k_code[..., 2] *= MM_PER_M
    return q_code, k_code


def code_point_from_thesis(p: np.ndarray) -> np.ndarray:
    """A point or displacement (..., 3) in a thesis base frame (m) in the authors' frame (mm)."""
    return MM_PER_M * np.asarray(p, float) @ CODE_R_THESIS.T


def inverse_kinematics(p: np.ndarray, k: np.ndarray, insertion_sign: float) -> np.ndarray:
    """Thesis convention: the joints (..., 3) that put the tip at p (..., 3, m), with the insertion d of
    sign `insertion_sign` (-1: d <= 0, ARASH:ASiST's workspace in this convention) and
    sin(beta) >= 0 (the parallelogram's range)."""
    p, k = np.asarray(p, float), np.asarray(k, float)
    alpha, theta, length = k[..., 0], k[..., 1], k[..., 2]
    ct, st = np.cos(theta), np.sin(theta)
    # r = Rz(theta)^T p - l e_x = d [cb, cp sb, sp sb]
    r = np.stack([ct * p[..., 0] + st * p[..., 1] - length, -st * p[..., 0] + ct * p[..., 1], p[..., 2]], axis=-1)
    d = insertion_sign * np.linalg.norm(r, axis=-1)
    v = r / d[..., None]
    beta = np.arccos(np.clip(v[..., 0], -1.0, 1.0))
    phi = np.arctan2(v[..., 2], v[..., 1])
    return np.stack([phi, beta - alpha, d], axis=-1)
