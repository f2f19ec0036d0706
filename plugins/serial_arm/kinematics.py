"""The marker pose in the measurement frame from joint values and kinematic parameters, with its
Jacobians (docs/models/serial_arm.md#forward-kinematics-with-parameters):

    meas_T_marker = B * F(q + dq; delta) * M

B: the arm's base_frame in the measurement frame (pose3); F: the chain's base_T_tool with joint offsets
dq and placement errors delta (chain.py); M: the marker in the tool frame (pose3, or a point3 p as
M = (I, p)). Twists are GTSAM's (right perturbation, [rotation, translation]).
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
    and axes in GTSAM's tangent order). A joint in two placement entries gets the sum of both."""

    base: bool = False
    tool: str = ""   # "" (identity), "pose3" or "point3"
    offsets: tuple[int, ...] = ()
    placements: tuple[tuple[int, tuple[int, ...]], ...] = ()

    @property
    def widths(self) -> list[int]:
        """Tangent width of each variable, in key order."""
        return ([6] if self.base else []) + ([6 if self.tool == "pose3" else 3] if self.tool else []) + \
            [1] * len(self.offsets) + [len(axes) for _, axes in self.placements]


@dataclass
class Parameters:
    """Values of a layout's variables: base and tool as 4x4 poses (None: identity)."""

    base: np.ndarray | None = None
    tool: np.ndarray | None = None
    offsets: np.ndarray = field(default_factory=lambda: np.zeros(0))
    placements: list[np.ndarray] = field(default_factory=list)


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
    p.placements = [np.asarray(v, float) for v in values[i + len(layout.offsets):]]
    return p


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
    """meas_T_marker (4x4) and, with `jacobians`, d twist / d variable for the joint vector then each
    layout variable: [6 x n, (base 6x6), (tool 6x6 | 6x3), offsets 6x1 ..., placements 6 x len(axes) ...]."""
    dq, deltas = joint_deltas(layout, p, chain.n)
    flange = chain.flange(np.asarray(q, float) + dq, deltas, jacobians)
    B = np.eye(4) if p.base is None else p.base
    M = np.eye(4) if p.tool is None else p.tool
    T = B @ flange.T @ M
    if not jacobians:
        return T, None
    ad_tool = lie.adjoint(lie.inverse(M))  # a twist of the flange seen at the marker
    J_q = ad_tool @ flange.joints
    blocks = [J_q]
    if layout.base:
        blocks.append(lie.adjoint(lie.inverse(flange.T @ M)))
    if layout.tool:
        blocks.append(np.eye(6) if layout.tool == "pose3" else np.eye(6)[:, 3:])
    blocks += [J_q[:, [j]] for j in layout.offsets]
    blocks += [ad_tool @ flange.placements[j][:, list(axes)] for j, axes in layout.placements]
    return T, blocks
