"""The marker pose in the measurement frame from joint values and kinematic parameters, with its
Jacobians (docs/models/serial_arm.md#forward-kinematics-with-parameters):

    meas_T_marker = B * F(q + dq + C tau(q + dq); delta) * M

B: the arm's base_frame in the measurement frame (pose3); F: the chain's base_T_tool with joint offsets
dq and placement errors delta (chain.py); C tau: each compliant joint's deflection under gravity, its compliance
(rad per N m; m per N if prismatic) times the gravity torque on it at the configuration (chain.gravity_torques:
the URDF's inertials, an optional payload); M: the marker in the tool frame (pose3, or a point3 p as M = (I, p)).
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
    entries gets the sum of both. `payload`: (mass kg, x, y, z m in the tool frame) of a known load at the tool,
    () for none (it adds to the gravity torques)."""

    base: bool = False
    tool: str = ""   # "" (identity), "pose3" or "point3"
    offsets: tuple[int, ...] = ()
    placements: tuple[tuple[int, tuple[int, ...]], ...] = ()
    compliances: tuple[int, ...] = ()
    payload: tuple[float, ...] = ()

    @property
    def widths(self) -> list[int]:
        """Tangent width of each variable, in key order."""
        return ([6] if self.base else []) + ([6 if self.tool == "pose3" else 3] if self.tool else []) + \
            [1] * len(self.offsets) + [len(axes) for _, axes in self.placements] + [1] * len(self.compliances)


@dataclass
class Parameters:
    """Values of a layout's variables: base and tool as 4x4 poses (None: identity)."""

    base: np.ndarray | None = None
    tool: np.ndarray | None = None
    offsets: np.ndarray = field(default_factory=lambda: np.zeros(0))
    placements: list[np.ndarray] = field(default_factory=list)
    compliances: np.ndarray = field(default_factory=lambda: np.zeros(0))


def parameters_of(layout: Layout, values: list) -> Parameters:
    """The layout's Parameters from its variables' values (Pose3, point, float, vector), in key order."""
    p, i = Parameters(), 0
    if layout.base:
        p.base, i = values[0].matrix(), 1
    if layout.tool == "pose3":
        p.tool = values[i].matrix()
    elif layout.tool:
        p.tool = np.eye(4)
        p.tool[:3, 3] = values[i]
    i += bool(layout.tool)
    p.offsets = np.array(values[i:i + len(layout.offsets)], float)
    i += len(layout.offsets)
    p.placements = [np.asarray(v, float) for v in values[i:i + len(layout.placements)]]
    p.compliances = np.array(values[i + len(layout.placements):], float)
    return p


def deflected(chain: SerialChain, layout: Layout, q: np.ndarray, p: Parameters,
              jacobians: bool = False) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
    """(q + C tau(q), d that / d q (N, n, n), tau (N, n)) for joint values q (N, n; offsets added): the compliant
    joints deflected by their compliance times the gravity torque on them; q itself (and None) without compliances.
    A compliance is shared by all samples (a scalar) or given per sample ((N,))."""
    if not layout.compliances:
        return q, None, None
    tau, dtau = chain.gravity_torques(q, layout.payload, jacobians)
    c = np.zeros(np.shape(q))
    for j, v in zip(layout.compliances, p.compliances):
        c[:, j] = c[:, j] + np.asarray(v, float)
    out = q + c * tau
    if not jacobians:
        return out, None, tau
    return out, np.eye(q.shape[1]) + c[:, :, None] * dtau, tau


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
    ...] (Pinocchio per sample: the reference the batched code is tested against)."""
    dq, deltas = joint_deltas(layout, p, chain.n)
    q_eff, dq_eff, tau = deflected(chain, layout, (np.asarray(q, float) + dq)[None], p, jacobians)
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
    return T, blocks
