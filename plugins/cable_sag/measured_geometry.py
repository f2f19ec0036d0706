"""Cable lengths with sag from the measured pose (`cable.catenary`; docs/models/cable_sag.md#sag-from-the-measured-pose).

At a pose (R, t) that is measured (motion capture), cable i runs from its pulley a_i to the attachment
p_i = R b_i + t: span L_i = |(a_i - p_i)_xy|, rise h_i = (a_i - p_i)_z. Its horizontal force H_i comes from the
straight-cable statics at that pose: the tensions tau that best balance the end-effector's weight m g (centre of mass
c) in the least-squares sense, sum_i tau_i [u_i; r_i x u_i] = -[m g; (R c) x m g] (u_i the unit chord towards the
pulley, r_i = R b_i), and H_i = tau_i |u_i,xy|. The catenary of weight w (N/m) through both ends with that H has
the vertical force V_i at the attachment for which it rises h_i (Newton on catenary.catenary's rise, from the
straight cable's V = H h / L), and its arc length l_i is the cable's length.

The orientation is the measured one: the statics only size the forces, they do not turn the robot. For w -> 0 the
catenary is the straight chord, l_i = |a_i - p_i| for any H: the rigid model exactly. The forces of the straight
statics differ from the catenary's by terms of the order of the sag over the span, which change the sag (a few
millimetres on light cables) by that relative amount. A cable the statics leave slack (tau_i <= 0) is given the
horizontal force MIN_TENSION_SHARE m g: the catenary is then deep, and the length residual says the model does not
hold there.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from fusionkit.api import cable_pull_wrenches, weight_wrench

from .catenary import catenary

NEWTON_STEPS = 8
STATICS_ROUNDS = 3  # statics with the chord's direction, then twice with the catenary's pull at the attachment
MIN_TENSION_SHARE = 1e-3


def balancing_tensions(W: np.ndarray, wrench: np.ndarray) -> np.ndarray:
    """Least-squares tensions (N, n) (N): W^T tau as close to -wrench as the cables can pull."""
    normal = np.einsum("kni,kmi->knm", W, W)
    return np.linalg.solve(normal, -np.einsum("kni,ki->kn", W, wrench)[..., None])[..., 0]


class Hung(NamedTuple):
    """Cables at N poses: arc lengths (N, n) (m), the wrench they leave unbalanced (N, 6) (N, N m), and each
    cable's pull on the end-effector at its attachment, horizontal (towards the pulley) and vertical (N, n) (N)."""

    lengths: np.ndarray
    unbalanced: np.ndarray
    horizontal: np.ndarray
    vertical: np.ndarray


def hanging(R: np.ndarray, t: np.ndarray, pulleys: np.ndarray, attachments: np.ndarray, com, weight, w) -> Hung:
    """The arc lengths, the wrench left unbalanced and the pulls (Hung) of cables of weight w (N/m)
    from pulleys (N, n, 3) to the attachments of poses R (N, 3, 3), t (N, 3), the end-effector weighing `weight`
    (N) with centre of mass `com` (m, body frame); w, weight (N,) or scalars, com (N, 3) or (3,)."""
    n_poses = len(R)
    weight = np.broadcast_to(np.asarray(weight, float), (n_poses,))
    arms = np.einsum("kij,nj->kni", R, attachments)  # R b_i
    chord = pulleys - (arms + t[:, None, :])
    wrench = weight_wrench(R, com, weight)
    span = np.maximum(np.hypot(chord[..., 0], chord[..., 1]), 1e-9)
    rise = chord[..., 2]
    level = chord * np.array([1.0, 1.0, 0.0]) / span[..., None]  # s_i: horizontal unit vector towards the pulley
    w = np.broadcast_to(np.asarray(w, float).reshape(-1, 1), span.shape)
    directions = chord / np.linalg.norm(chord, axis=2, keepdims=True)
    for _ in range(STATICS_ROUNDS):  # the pull's direction at the attachment: the chord first, then the catenary's
        tension = balancing_tensions(cable_pull_wrenches(arms, directions), wrench)
        H = np.maximum(tension * np.hypot(directions[..., 0], directions[..., 1]),
                       MIN_TENSION_SHARE * weight[:, None])
        V = H * rise / span
        for _ in range(NEWTON_STEPS):
            _, reached, _, d_rise = catenary(H, V, span, w, jacobian=True)
            V = V - (reached - rise) / d_rise[..., 1]
        pull = H[..., None] * level + V[..., None] * np.array([0.0, 0.0, 1.0])
        directions = pull / np.linalg.norm(pull, axis=2, keepdims=True)
    forces = np.linalg.norm(pull, axis=2)
    unbalanced = np.einsum("kni,kn->ki", cable_pull_wrenches(arms, directions), forces) + wrench
    return Hung(catenary(H, V, span, w)[0], unbalanced, H, V)


def catenary_lengths(R: np.ndarray, t: np.ndarray, pulleys: np.ndarray, attachments: np.ndarray, com, weight,
                     w) -> np.ndarray:
    """The arc lengths (N, n) (m) of `hanging`."""
    return hanging(R, t, pulleys, attachments, com, weight, w)[0]
