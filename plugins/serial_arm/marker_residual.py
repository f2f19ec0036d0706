"""The marker factors of one config entry as one vectorized residual (docs/models/serial_arm.md#speed): the
forward kinematics and residuals of vectorized_kinematics.py for every sample at once. An entry's factors read more than three
variables (joints, base, marker, offsets, placements, compliances), so fusionkit linearizes them one by one as
CustomFactors, and its instance cache evaluates them all in one call per pass (fusionkit.api.pass_token).

Variables, in key order: the joint vector (two for `relative`: the pair's), then the layout's (kinematics.Layout);
data: `measured`, per sample the inverse measured pose (pose, relative; (N, 4, 4)) or the measured position
((N, 3)).
"""

from __future__ import annotations

import numpy as np

from fusionkit.api import POINT3, POSE3, SCALAR, VectorizedResidual, vector_type

from . import vectorized_kinematics
from .kinematics import Layout, parameters_from_arrays

KINDS = ("pose", "position", "relative")


def variable_types(n: int, layout: Layout, kind: str) -> tuple:
    """The residual's variable types: joint vector(s) of n joints, then the layout's variables."""
    tool = {"pose3": (POSE3,), "point3": (POINT3,)}.get(layout.tool, ())
    return ((vector_type(n),) * (2 if kind == "relative" else 1) + (POSE3,) * layout.base + tool
            + (SCALAR,) * len(layout.offsets) + tuple(vector_type(len(axes)) for _, axes in layout.placements)
            + (SCALAR,) * len(layout.compliances) + (vector_type(len(layout.lumped)),) * len(layout.mass_compliances))


def shared(a: np.ndarray) -> np.ndarray:
    """A variable's values (N, ...) as one value when every sample has the same (a static parameter: its
    exponential or adjoint is then computed once, not N times), else as they are."""
    return a[0] if len(a) > 1 and (a == a[0]).all() else a


def marker_residual(chain, layout: Layout, kind: str) -> VectorizedResidual:
    """The residual of an entry's marker factors: a 6-D pose (Log(z^-1 T)), a 3-D position (t(T) - z), or the
    motion between two configurations (Log(z^-1 T_a^-1 T_b))."""
    assert kind in KINDS
    joints = 2 if kind == "relative" else 1

    def function(x: list[np.ndarray], data: dict[str, np.ndarray], jacobians: bool):
        p = parameters_from_arrays(layout, [shared(a) for a in x[joints:]])
        if kind == "relative":
            a = vectorized_kinematics.marker_poses(chain, layout, x[0], p, jacobians)
            b = vectorized_kinematics.marker_poses(chain, layout, x[1], p, jacobians)
            e, blocks = vectorized_kinematics.relative_residuals(a, b, data["measured"])
        else:
            poses = vectorized_kinematics.marker_poses(chain, layout, x[0], p, jacobians)
            e, blocks = (vectorized_kinematics.pose_residuals if kind == "pose" else vectorized_kinematics.position_residuals)(poses, data["measured"])
        return (e, blocks) if jacobians else e
    return VectorizedResidual(f"arm.{kind}", variable_types(chain.n, layout, kind), 3 if kind == "position" else 6,
                              function)
