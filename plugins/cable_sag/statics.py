"""Statics of a suspended 4-cable robot with heavy cables, through one reference cable (thesis
eqs. 5.5-5.11; docs/models/cable_sag.md#statics-through-a-reference-cable), with exact Jacobians.

At a static pose (R, t) cable i leaves its pulley a_i and holds the end-effector at
p_i = R b_i + t. Its vertical plane has the horizontal unit vector s_i = (p_i - a_i)_xy / L_i
(from the pulley towards the attachment), span L_i = |(p_i - a_i)_xy| and rise
h_i = (a_i - p_i)_z. The cable pulls the end-effector with -H_i s_i + V_i e_z; with r_i = R b_i,
its wrench column pair is (eq. 5.8)

    J_i^T = [ -s_i         e_z
              -r_i x s_i   r_i x e_z ],

and gravity needs w = m g [e_z; (R c) x e_z] (5.6; the centre of mass c rotates with the body).
Given the reference cable's forces f_ref = (H_ref, V_ref), the other three follow from the 6x6
system (5.11) f_res = (J_res^T)^-1 (w - J_ref^T f_ref). Each cable's catenary (catenary.py) then
gives its arc length l_i (5.4) and the rise it would reach, whose mismatch with h_i is the
attachment-height error (5.13).

Derivatives are carried forward through every step (exact, no finite differences) with respect to
theta = [dR (3, right perturbation R exp(dR)), dt (3, world frame), H_ref, V_ref,
a_0 (3), ..., a_{n-1} (3)].
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from .catenary import catenary

N_CABLES = 4


@dataclass(frozen=True)
class SagRobot:
    """What the statics need: attachments b_i (n, 3) and centre of mass c (3) in the end-effector
    frame (m), end-effector weight m g (N), cable weight per length (N/m), reference cable."""

    attachments: np.ndarray
    com: np.ndarray
    weight: float
    cable_weight: float
    reference: int = 0

    @property
    def n(self) -> int:
        return len(self.attachments)

    @property
    def dim(self) -> int:
        """Length of theta: rotation, translation, reference force, pulleys."""
        return 8 + 3 * self.n

    @cached_property
    def others(self) -> np.ndarray:
        """The cables whose forces the statics solve for."""
        return np.array([i for i in range(self.n) if i != self.reference])

    @cached_property
    def attachment_skews(self) -> np.ndarray:
        return _skews(self.attachments)

    @cached_property
    def geometry_seed(self) -> np.ndarray:
        """d(p_i - a_i)/d(translation, pulleys) part of the geometry Jacobian, (n, 3, dim)."""
        D = np.zeros((self.n, 3, self.dim))
        D[:, :, 3:6] = np.eye(3)
        for i in range(self.n):
            D[i, :, 8 + 3 * i:11 + 3 * i] = -np.eye(3)
        return D


@dataclass
class Equilibrium:
    """Per cable (n,): forces at the end-effector, span, rise, arc length, height error; with
    Jacobians, d_length and d_height (n, dim) with respect to theta."""

    H: np.ndarray
    V: np.ndarray
    span: np.ndarray
    rise: np.ndarray
    length: np.ndarray
    height_error: np.ndarray
    d_length: np.ndarray | None = None
    d_height: np.ndarray | None = None


def skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def _skews(points: np.ndarray) -> np.ndarray:
    """(n, 3, 3): skew(p_i) for each row."""
    out = np.zeros((len(points), 3, 3))
    out[:, 0, 1], out[:, 0, 2], out[:, 1, 2] = -points[:, 2], points[:, 1], -points[:, 0]
    out[:, 1, 0], out[:, 2, 0], out[:, 2, 1] = points[:, 2], -points[:, 1], points[:, 0]
    return out


def equilibrium(R: np.ndarray, t: np.ndarray, f_ref: np.ndarray, pulleys: np.ndarray, robot: SagRobot,
                jacobian: bool = False, pulley_jacobian: bool = True) -> Equilibrium:
    """Forces, spans, lengths and height errors of all cables at pose (R, t) (see module doc).
    Without `pulley_jacobian` the Jacobians stop at theta[:8] (pose and force: the simulator's)."""
    n, ref = robot.n, robot.reference
    m = robot.dim if pulley_jacobian else 8
    r = robot.attachments @ R.T                      # (n, 3) R b_i
    d = r + t - pulleys                              # (n, 3) p_i - a_i
    span = np.hypot(d[:, 0], d[:, 1])
    s = np.zeros((n, 3))
    s[:, :2] = d[:, :2] / span[:, None]
    rise = -d[:, 2]
    rc = R @ robot.com
    wrench = robot.weight * np.array([0.0, 0.0, 1.0, rc[1], -rc[0], 0.0])      # [e_z; rc x e_z]
    r_x_s = np.column_stack([-r[:, 2] * s[:, 1], r[:, 2] * s[:, 0], r[:, 0] * s[:, 1] - r[:, 1] * s[:, 0]])
    col_h = np.concatenate([-s, -r_x_s], axis=1)                                # (n, 6)
    col_v = np.zeros((n, 6))                                                    # [e_z; r x e_z]
    col_v[:, 2], col_v[:, 3], col_v[:, 4] = 1.0, r[:, 1], -r[:, 0]
    others = robot.others
    A = np.empty((6, 2 * len(others)))
    A[:, 0::2], A[:, 1::2] = col_h[others].T, col_v[others].T
    rhs = wrench - col_h[ref] * f_ref[0] - col_v[ref] * f_ref[1]
    A_inv = np.linalg.inv(A)
    x = A_inv @ rhs
    H, V = np.empty(n), np.empty(n)
    H[ref], V[ref] = f_ref
    H[others], V[others] = x[0::2], x[1::2]
    if not jacobian:
        length, model_rise = catenary(H, V, span, robot.cable_weight)
        return Equilibrium(H, V, span, rise, length, model_rise - rise)

    # derivatives of the geometry with respect to theta, (n, 3, m)
    Dr = np.zeros((n, 3, m))
    Dr[:, :, 0:3] = -np.einsum("ab,ibc->iac", R, robot.attachment_skews)
    Dd = Dr + robot.geometry_seed[:, :, :m]
    Dspan = np.einsum("ik,ikm->im", s[:, :2], Dd[:, :2])
    Ds = np.zeros((n, 3, m))
    Ds[:, :2] = (Dd[:, :2] - s[:, :2, None] * Dspan[:, None, :]) / span[:, None, None]
    Drise = -Dd[:, 2]
    # col_h = [-s; -(r x s)], col_v = [e_z; r x e_z]
    Dcol_h = np.concatenate([-Ds, np.einsum("iab,ibm->iam", _skews(s), Dr) - np.einsum("iab,ibm->iam", _skews(r), Ds)],
                            axis=1)
    Dcol_v = np.zeros((n, 6, m))
    Dcol_v[:, 3], Dcol_v[:, 4] = Dr[:, 1], -Dr[:, 0]  # D(r x e_z) = (Dr_y, -Dr_x, 0)
    Drc = -R @ skew(robot.com)
    Dwrench = np.zeros((6, m))
    Dwrench[3, 0:3], Dwrench[4, 0:3] = robot.weight * Drc[1], -robot.weight * Drc[0]
    Drhs = Dwrench - Dcol_h[ref] * f_ref[0] - Dcol_v[ref] * f_ref[1]
    Drhs[:, 6] -= col_h[ref]
    Drhs[:, 7] -= col_v[ref]
    DA_x = np.einsum("jam,j->am", Dcol_h[others], x[0::2]) + np.einsum("jam,j->am", Dcol_v[others], x[1::2])
    Dx = A_inv @ (Drhs - DA_x)
    DH, DV = np.zeros((n, m)), np.zeros((n, m))
    DH[ref, 6], DV[ref, 7] = 1.0, 1.0
    DH[others], DV[others] = Dx[0::2], Dx[1::2]
    length, model_rise, dl, dh = catenary(H, V, span, robot.cable_weight, jacobian=True)
    d_length = dl[:, 0:1] * DH + dl[:, 1:2] * DV + dl[:, 2:3] * Dspan
    d_height = dh[:, 0:1] * DH + dh[:, 1:2] * DV + dh[:, 2:3] * Dspan - Drise
    return Equilibrium(H, V, span, rise, length, model_rise - rise, d_length, d_height)
