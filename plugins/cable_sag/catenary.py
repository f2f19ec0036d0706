"""The inextensible heavy cable (catenary, thesis eqs. 5.1-5.4;
docs/models/cable_sag.md#catenary), in a form that stays
finite and accurate for long heavy cables, near-vertical cables and small horizontal forces.

A cable of weight w (N/m) pulls the end-effector with a horizontal force H > 0 (towards the
pulley) and a vertical force V (up). Going from the attachment point towards the pulley the
tension is (H, V + w s) after an arc length s; its span L (horizontal distance to the pulley) and
its rise (height of the pulley above the attachment) then give

    length l = (L / H) (V C(beta) + T0 S(beta)),   rise = (L / H) (T0 C(beta) + V S(beta)),

with beta = w L / H, T0 = sqrt(H^2 + V^2), S(beta) = sinh(beta) / beta and
C(beta) = (cosh(beta) - 1) / beta = 2 sinh^2(beta / 2) / beta. This is thesis eqs. 5.1-5.4 rewritten:
their C1, C2 subtract two numbers of the size of cosh(w x / H) + w z_a / H, which cancel
catastrophically when H is small, and overflow for long heavy cables; here only beta enters a
hyperbolic function, no large terms cancel, and w -> 0 gives the straight cable
(l = L T0 / H, rise = L V / H). beta is capped at BETA_MAX (a cable that would need e^300 times
its span): the values stay finite for an optimizer that strays there.
"""

from __future__ import annotations

import numpy as np

SERIES_BELOW = 0.05  # |beta| below which S, C and their derivatives come from their Taylor series
BETA_MAX = 300.0


def _shape(beta: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """S, C and their derivatives dS/dbeta, dC/dbeta (element-wise)."""
    b = np.clip(np.asarray(beta, float), -BETA_MAX, BETA_MAX)
    small = np.abs(b) < SERIES_BELOW
    bs = np.where(small, 1.0, b)  # a safe divisor where the closed forms are used
    sh, ch = np.sinh(b), np.cosh(b)
    S, C = sh / bs, 2 * np.sinh(b / 2) ** 2 / bs
    dS, dC = (ch - S) / bs, (sh - C) / bs
    if small.any():
        b2 = b * b
        S = np.where(small, 1 + b2 / 6 + b2 * b2 / 120 + b2 ** 3 / 5040, S)
        C = np.where(small, b / 2 + b * b2 / 24 + b * b2 * b2 / 720 + b * b2 ** 3 / 40320, C)
        dS = np.where(small, b / 3 + b * b2 / 30 + b * b2 * b2 / 840 + b * b2 ** 3 / 45360, dS)
        dC = np.where(small, 0.5 + b2 / 8 + b2 * b2 / 144 + b2 ** 3 / 5760, dC)
    return S, C, dS, dC


def catenary(H, V, L, w, jacobian: bool = False):
    """Arc length and rise of cables with end forces (H, V) (N), span L (m), weight w (N/m).

    Arrays broadcast. With `jacobian`, also returns d(length)/d(H, V, L) and d(rise)/d(H, V, L)
    as arrays of shape (..., 3)."""
    H, V, L = np.asarray(H, float), np.asarray(V, float), np.asarray(L, float)
    a = L / H
    beta = w * a
    T0 = np.hypot(H, V)
    S, C, dS, dC = _shape(beta)
    P = V * C + T0 * S
    Q = T0 * C + V * S
    length, rise = a * P, a * Q
    if not jacobian:
        return length, rise
    capped = np.abs(beta) >= BETA_MAX
    dS, dC = np.where(capped, 0.0, dS), np.where(capped, 0.0, dC)
    # d/dH: beta_H = -beta / H, a_H = -a / H, T0_H = H / T0; d/dV: T0_V = V / T0; d/dL: beta_L = w / H, a_L = 1 / H
    bH, bL = -beta / H, w / H
    P_H = (V * dC + T0 * dS) * bH + (H / T0) * S
    Q_H = (T0 * dC + V * dS) * bH + (H / T0) * C
    P_V = C + (V / T0) * S
    Q_V = (V / T0) * C + S
    P_L = (V * dC + T0 * dS) * bL
    Q_L = (T0 * dC + V * dS) * bL
    d_length = np.stack([-a / H * P + a * P_H, a * P_V, P / H + a * P_L], axis=-1)
    d_rise = np.stack([-a / H * Q + a * Q_H, a * Q_V, Q / H + a * Q_L], axis=-1)
    return length, rise, d_length, d_rise


def catenary_spec_form(H: float, V: float, L: float, w: float, z_pulley: float) -> tuple[float, float]:
    """Thesis eqs. 5.1-5.4 as printed (x from the pulley, z_i(0) = z_pulley): (arc length, height of the
    attachment point z_i(L)). For cross-checking `catenary` where these are computable."""
    C1 = (H / w) * np.arcsinh(-V / H) - L
    C2 = np.cosh(C1 * w / H) - (w / H) * z_pulley
    z_end = (H / w) * (np.cosh((w / H) * (L + C1)) - C2)
    length = (H / w) * (np.sinh((w / H) * (L + C1)) - np.sinh((w / H) * C1))
    return float(length), float(z_end)
