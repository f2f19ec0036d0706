"""The forward kinematics of chain.py and the marker residuals of residuals.py for N samples at once
(numpy; docs/models/serial_arm.md#speed). Same model, conventions and Jacobians:

    base_T_tool(q) = base_T_universe * prod_j [ P_j Exp(delta_j) Exp(S_j (q_j + dq_j)) ] * joint_T_tool

with P_j the URDF placement of joint j (reduced model, chain order) and S_j its unit twist (an axis of
rotation or of translation). Pinocchio reads the URDF once (SerialChain); the product is evaluated
here for every sample in a handful of array operations, where chain.py calls Pinocchio per sample.
Parameters may be shared by all samples (a pose (4, 4), a vector (w,)) or given per sample (a
leading axis N: a time-varying parameter).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from .lazy_pinocchio import pin

from fusionkit.api import lie
from .chain import PIN_TO_GTSAM, SerialChain
from .kinematics import Layout, Parameters, deflected, joint_deltas

EYE6 = np.eye(6)


@dataclass
class Poses:
    """Marker poses of N samples and, when asked for, d twist / d variable per sample (N, 6, width):
    the joint vector, then each layout variable (kinematics.marker_pose's blocks, batched)."""

    T: np.ndarray
    blocks: list[np.ndarray] | None = None


class BatchChain:
    """A SerialChain's product of exponentials along its tool's path: placements, joint twists, the map from the
    listed joint values to the path's (couplings) and the tool frame, as arrays."""

    def __init__(self, chain: SerialChain):
        model = chain.model
        self.n = chain.n
        self.path = list(chain.path)
        for parent, jid in zip([0] + self.path[:-1], self.path):
            if model.parents[jid] != parent:  # supports are a path: a safeguard against a model Pinocchio changed
                raise ValueError(f"joint {model.names[jid]!r} does not follow {model.names[parent]!r}: not a chain")
        listed = {jid: j for j, jid in enumerate(chain.jids)}
        coupled = {jid: c for c, jid in enumerate(chain.coupled_jids)}
        # the path joints' values v = q_listed @ values + value_offset (a listed joint: its own; coupled: the coupling)
        self.values = np.zeros((self.n, len(self.path)))
        self.value_offset = np.zeros(len(self.path))
        self.listed_at: dict[int, int] = {}  # listed joint index -> its position on the path
        for pos, jid in enumerate(self.path):
            if jid in listed:
                self.values[listed[jid], pos] = 1.0
                self.listed_at[listed[jid]] = pos
            else:
                self.values[:, pos] = chain.coupling[coupled[jid]]
                self.value_offset[pos] = chain.coupling_offset[coupled[jid]]
        self.placements = np.array([model.jointPlacements[jid].homogeneous for jid in self.path]).reshape(-1, 4, 4)
        for j, pos in self.listed_at.items():
            self.placements[pos] = chain.nominal[j].homogeneous
        self.twists = np.array([chain.unit_twist(jid) for jid in self.path]).reshape(-1, 6)
        self.tool = model.frames[chain.tool_id].placement.homogeneous
        self.base_T_universe = chain.base_T_universe

    def flange(self, q: np.ndarray, deltas: dict[int, np.ndarray], jacobians: bool = False):
        """base_T_tool (N, 4, 4) at joint values q (N, n; offsets added) with placement errors {joint:
        (6,) or (N, 6)}; with `jacobians` also d twist / d q (N, 6, n) and {joint: d twist / d delta_j
        (N, 6, 6)} (the tool frame's twist, as SerialChain.flange; zero for a joint off the tool's path)."""
        N = len(q)
        v = q @ self.values + self.value_offset
        delta_at = {self.listed_at[j]: d for j, d in deltas.items() if j in self.listed_at}
        A = np.broadcast_to(self.base_T_universe, (N, 4, 4))
        before, after = [], []
        for pos in range(len(self.path)):
            P = self.placements[pos]
            if pos in delta_at:
                P = P @ lie.exp(np.asarray(delta_at[pos], float))
            A = A @ P
            before.append(A)
            A = A @ lie.exp(v[:, pos, None] * self.twists[pos])
            after.append(A)
        T = A @ self.tool
        if not jacobians:
            return T, None, None
        T_inv = lie.inverse(T)
        J_path = np.zeros((N, 6, len(self.path)))
        for pos in range(len(self.path)):
            X = T_inv @ after[pos]  # Ad(X) S_j, written out: [R w; p x (R w) + R v]
            w, u = X[:, :3, :3] @ self.twists[pos, :3], X[:, :3, :3] @ self.twists[pos, 3:]
            J_path[:, :3, pos] = w
            J_path[:, 3:, pos] = np.cross(X[:, :3, 3], w) + u
        J = J_path @ self.values.T
        placement_blocks = {}
        for j, d in deltas.items():
            pos = self.listed_at.get(j)
            placement_blocks[j] = np.zeros((N, 6, 6)) if pos is None else \
                _times(lie.adjoint(T_inv @ before[pos]), lie.jr(np.asarray(d, float)))
        return T, J, placement_blocks


def _times(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a @ b for stacked a (N, r, k) and b shared (k, c) or stacked (N, k, c): one matrix product when shared."""
    if b.ndim == 2:
        return (a.reshape(-1, a.shape[-1]) @ b).reshape(a.shape[:-1] + b.shape[-1:])
    return a @ b


def batch_chain(chain: SerialChain) -> BatchChain:
    """The chain's BatchChain, made once per chain."""
    if getattr(chain, "_batch", None) is None:
        chain._batch = BatchChain(chain)
    return chain._batch


def marker_poses(chain: SerialChain, layout: Layout, q: np.ndarray, p: Parameters, jacobians: bool = False) -> Poses:
    """meas_T_marker for joint values q (N, n): kinematics.marker_pose for every sample. `p`: base and
    tool (4, 4) or (N, 4, 4), `offsets` and `compliances` lists of scalars or (N,) arrays, `placements` and
    `mass_compliances` of (w,) or (N, w)."""
    bc = batch_chain(chain)
    q = np.asarray(q, float)
    dq, deltas = joint_deltas(layout, p, chain.n)
    q_eff, dq_eff, tau, unit = deflected(chain, layout, q + dq, p, jacobians)
    F, J_f, placement_blocks = bc.flange(q_eff, deltas, jacobians)
    B = np.eye(4) if p.base is None else np.asarray(p.base, float)
    M = np.eye(4) if p.tool is None else np.asarray(p.tool, float)
    FM = F @ M
    T = B @ FM
    if not jacobians:
        return Poses(T)
    ad_tool = lie.adjoint(lie.inverse(M))
    J_m = ad_tool @ J_f
    J_q = J_m if dq_eff is None else J_m @ dq_eff
    N = len(q)
    blocks = [J_q]
    if layout.base:
        blocks.append(lie.adjoint(lie.inverse(FM)))
    if layout.tool:
        blocks.append(np.broadcast_to(EYE6 if layout.tool == "pose3" else EYE6[:, 3:],
                                      (N, 6, 6 if layout.tool == "pose3" else 3)))
    blocks += [J_q[:, :, [j]] for j in layout.offsets]
    blocks += [ad_tool @ placement_blocks[j][:, :, list(axes)] for j, axes in layout.placements]
    blocks += [J_m[:, :, [j]] * tau[:, None, j, None] for j in layout.compliances]
    blocks += [J_m[:, :, [j]] * unit[:, None, :, j] for j in layout.mass_compliances]
    return Poses(T, blocks)


def pose_residuals(poses: Poses, measured_inv: np.ndarray) -> tuple[np.ndarray, list[np.ndarray] | None]:
    """6-D tracker, every sample: e = Log(z^-1 T) and Jr^-1(e) times each block (residuals.tool_pose_residual)."""
    e = lie.log(measured_inv @ poses.T)
    if poses.blocks is None:
        return e, None
    j_inv = lie.jr_inv(e)
    return e, [j_inv @ b for b in poses.blocks]


def position_residuals(poses: Poses, measured: np.ndarray) -> tuple[np.ndarray, list[np.ndarray] | None]:
    """Laser tracker, every sample: e = t(T) - z and R_T times the translation rows of each block."""
    e = poses.T[:, :3, 3] - measured
    if poses.blocks is None:
        return e, None
    R = poses.T[:, :3, :3]
    return e, [R @ b[:, 3:] for b in poses.blocks]


def relative_residuals(a: Poses, b: Poses, measured_inv: np.ndarray) -> tuple[np.ndarray, list[np.ndarray] | None]:
    """Marker motion from a to b, every pair: e = Log(z^-1 Ta^-1 Tb); blocks: q_a, q_b, then each shared
    variable with both terms (residuals.relative_tool_pose_residual)."""
    D = lie.inverse(a.T) @ b.T
    e = lie.log(measured_inv @ D)
    if a.blocks is None:
        return e, None
    j_inv = lie.jr_inv(e)
    back = -j_inv @ lie.adjoint(lie.inverse(D))
    return e, [back @ a.blocks[0], j_inv @ b.blocks[0]] + [back @ x + j_inv @ y for x, y in zip(a.blocks[1:],
                                                                                                  b.blocks[1:])]
