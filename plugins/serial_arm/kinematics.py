"""The marker pose in the measurement frame from joint values and kinematic parameters, with its
Jacobians (docs/models/serial_arm.md#forward-kinematics-with-parameters):

    meas_T_marker = B * F(q + dq + C tau(q + dq) + sum_i P_i tau_i(q + dq); delta) * M

B: the arm's base_frame in the measurement frame (pose3); F: the chain's base_T_tool with joint offsets
dq and placement errors delta (chain.py); C tau: each compliant joint's deflection under gravity, its compliance
(rad per N m; m per N if prismatic) times the gravity torque on it at the configuration (chain.gravity_torques:
the URDF's inertials, an optional payload); P_i tau_i: where the URDF's inertials are missing or wrong, lumped
masses instead, each joint's product of compliance and mass i (rad/(N m) x kg) times the torque of 1 kg at lumped
point i (chain.unit_mass_torques); M: the marker in the tool frame (pose3, or a point3 p as M = (I, p)).
Twists are GTSAM's (right perturbation, [rotation, translation]).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .chain import SerialChain
from fusionkit.api import lie


@dataclass(frozen=True)
class Layout:
    """The kinematic-parameter variables a factor reads after its joint vector(s), in key order: the
    base, the tool, one scalar per offset (its joint index), one vector per placement (its joint index
    and axes in GTSAM's tangent order), one scalar per compliance (its joint index). A joint in two placement
    entries gets the sum of both. `payload`: (frame, mass kg, x, y, z m in that frame) of a known load, () for none
    (it adds to the gravity torques). Then one vector per mass-compliance element (its joint index): its products
    with the masses at the `lumped` points (frame, x, y, z)."""

    base: bool = False
    tool: str = ""   # "" (identity), "pose3" or "point3"
    offsets: tuple[int, ...] = ()
    placements: tuple[tuple[int, tuple[int, ...]], ...] = ()
    compliances: tuple[int, ...] = ()
    payload: tuple = ()
    mass_compliances: tuple[int, ...] = ()
    lumped: tuple = ()

    @property
    def widths(self) -> list[int]:
        """Tangent width of each variable, in key order."""
        return ([6] if self.base else []) + ([6 if self.tool == "pose3" else 3] if self.tool else []) + \
            [1] * len(self.offsets) + [len(axes) for _, axes in self.placements] + [1] * len(self.compliances) + \
            [len(self.lumped)] * len(self.mass_compliances)


@dataclass
class Parameters:
    """Values of a layout's variables: base and tool as 4x4 poses (None: identity)."""

    base: np.ndarray | None = None
    tool: np.ndarray | None = None
    offsets: np.ndarray = field(default_factory=lambda: np.zeros(0))
    placements: list[np.ndarray] = field(default_factory=list)
    compliances: np.ndarray = field(default_factory=lambda: np.zeros(0))
    mass_compliances: list[np.ndarray] = field(default_factory=list)


def parameters_from_arrays(layout: Layout, x: list) -> Parameters:
    """The layout's Parameters from its variables in array form, in key order: a pose (4, 4), a point (3,) (made a
    pose), a scalar, a vector; each may carry a leading axis N (one value per sample)."""
    p, i = Parameters(), 0
    if layout.base:
        p.base, i = x[0], 1
    if layout.tool == "point3":
        p.tool = np.zeros(np.shape(x[i])[:-1] + (4, 4))
        p.tool[..., :3, :3], p.tool[..., :3, 3], p.tool[..., 3, 3] = np.eye(3), x[i], 1.0
    elif layout.tool:
        p.tool = x[i]
    i += bool(layout.tool)
    groups = []
    for count in (len(layout.offsets), len(layout.placements), len(layout.compliances), len(layout.mass_compliances)):
        groups.append(list(x[i:i + count]))
        i += count
    p.offsets, p.placements, p.compliances, p.mass_compliances = groups
    return p


def parameters_of(layout: Layout, values: list) -> Parameters:
    """The layout's Parameters from its variables' values (Pose3, point, float, vector), in key order."""
    p = parameters_from_arrays(layout, [v.matrix() if hasattr(v, "matrix") else np.asarray(v, float) for v in values])
    p.offsets, p.compliances = np.array(p.offsets, float), np.array(p.compliances, float)
    return p


def deflected(chain: SerialChain, layout: Layout, q: np.ndarray, p: Parameters, jacobians: bool = False) -> tuple:
    """(q + C tau(q) + sum_i P_i tau_i(q), d that / d q (N, n, n), tau (N, n), tau_i (N, M, n)) for joint values q
    (N, n; offsets added): the compliant joints deflected under gravity; q itself (and Nones) without compliances.
    A compliance is shared by all samples (a scalar) or given per sample ((N,)); a mass-compliance vector (M,) or
    (N, M)."""
    if not layout.compliances and not layout.mass_compliances:
        return q, None, None, None
    out = np.array(q, float)
    d = np.repeat(np.eye(q.shape[1])[None], len(q), axis=0) if jacobians else None
    tau = unit = None
    if layout.compliances:
        tau, dtau = chain.gravity_torques(q, layout.payload, jacobians)
        c = np.zeros(np.shape(q))
        for j, v in zip(layout.compliances, p.compliances):
            c[:, j] = c[:, j] + np.asarray(v, float)
        out += c * tau
        if jacobians:
            d += c[:, :, None] * dtau
    if layout.mass_compliances:
        unit, dunit = chain.unit_mass_torques(q, layout.lumped, jacobians)  # (N, M, n)
        for j, v in zip(layout.mass_compliances, p.mass_compliances):
            v = np.broadcast_to(np.asarray(v, float), (len(q), len(layout.lumped)))
            out[:, j] += np.einsum("nm,nm->n", v, unit[:, :, j])
            if jacobians:
                d[:, j, :] += np.einsum("nm,nmk->nk", v, dunit[:, :, j, :])
    return out, d, tau, unit


def joint_deltas(layout: Layout, p: Parameters, n: int) -> tuple[np.ndarray, dict[int, np.ndarray]]:
    """(joint offsets of all n joints, {joint: placement twist}) from the layout's values; each value is
    shared by all samples (a scalar, a (w,) vector) or given per sample (a leading axis N)."""
    dq = np.zeros(n)
    for j, v in zip(layout.offsets, p.offsets):
        dq = dq + np.eye(n)[j] * np.asarray(v, float)[..., None]
    deltas: dict[int, np.ndarray] = {}
    for (j, axes), v in zip(layout.placements, p.placements):
        v = np.asarray(v, float)
        full = np.zeros(v.shape[:-1] + (6,))
        full[..., list(axes)] = v
        deltas[j] = deltas[j] + full if j in deltas else full
    return dq, deltas


def marker_pose(chain: SerialChain, layout: Layout, q: np.ndarray, p: Parameters,
                jacobians: bool = False) -> tuple[np.ndarray, list[np.ndarray] | None]:
    """meas_T_marker (4x4) and, with `jacobians`, d twist / d variable for the joint vector then each layout
    variable: [6 x n, (base 6x6), (tool 6x6 | 6x3), offsets 6x1 ..., placements 6 x len(axes) ..., compliances 6x1
    ..., mass compliances 6 x M ...] (Pinocchio per sample: the reference the batched code is tested against)."""
    dq, deltas = joint_deltas(layout, p, chain.n)
    q_eff, dq_eff, tau, unit = deflected(chain, layout, (np.asarray(q, float) + dq)[None], p, jacobians)
    flange = chain.flange(q_eff[0], deltas, jacobians)
    B = np.eye(4) if p.base is None else p.base
    M = np.eye(4) if p.tool is None else p.tool
    T = B @ flange.T @ M
    if not jacobians:
        return T, None
    ad_tool = lie.adjoint(lie.inverse(M))  # a twist of the flange seen at the marker
    J_f = ad_tool @ flange.joints
    J_q = J_f if dq_eff is None else J_f @ dq_eff[0]
    blocks = [J_q]
    if layout.base:
        blocks.append(lie.adjoint(lie.inverse(flange.T @ M)))
    if layout.tool:
        blocks.append(np.eye(6) if layout.tool == "pose3" else np.eye(6)[:, 3:])
    blocks += [J_q[:, [j]] for j in layout.offsets]
    blocks += [ad_tool @ flange.placements[j][:, list(axes)] for j, axes in layout.placements]
    blocks += [J_f[:, [j]] * tau[0, j] for j in layout.compliances]
    blocks += [J_f[:, [j]] * unit[0, :, j] for j in layout.mass_compliances]
    return T, blocks
