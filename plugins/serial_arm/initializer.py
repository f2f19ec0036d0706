"""`arm.hand_eye`: initial base and marker poses of a serial arm from its tracked marker poses
(docs/models/serial_arm.md#initial-base-and-marker).

Every sample i gives T_i = B F_i M: T_i the measured marker pose, F_i the flange pose at the joint
states (the encoder readings) with the current joint offsets and placement errors (the description's
nominal values), B the base in the measurement frame, M the marker in the flange. With X = M^-1 and Y = B this is the
robot-world/hand-eye equation T_i X = Y F_i, solved in closed form by Kronecker products [Shah 2013]:

1. rotations: R_Ti R_X = R_Y R_Fi is linear in (vec R_X, vec R_Y):
   (I (x) R_Ti) vec R_X - (R_Fi^T (x) I) vec R_Y = 0 for every i; the right singular vector of the
   smallest singular value of the stacked 9N x 18 matrix, scaled to determinant one and projected onto SO(3) (nearest rotation by SVD);
2. translations: R_Ti t_X + t_Ti = R_Y t_Fi + t_Y, linear least squares in (t_X, t_Y).

With only one of B and M unknown (the description has no base or no tool), it is the mean of
T_i (F_i M)^-1 or (B F_i)^-1 T_i: the translations' mean and the rotations' chordal mean. The result
is a starting point for the solver, not an estimate: it weighs rotation and translation errors
arbitrarily and ignores the other kinematic errors.
"""

from __future__ import annotations

import gtsam
import numpy as np

from fusionkit.api import POSE_COLUMNS, TOLERANCE_SCHEMA, Initializer, Spec, nearest

from .batch import marker_poses
from .factors import TOOL_FRAME, check_arm_entry, entry_arm, entry_layout, pose_matrices
from .kinematics import Layout, Parameters
from .model import marker_of, tool_frames

NAME = {"type": "string"}
DEGENERATE = 1e-6  # relative singular value below which the rotations leave a second solution open


class Degenerate(ValueError):
    """The poses do not determine B and M (too few configurations, or rotations about one axis only)."""


def nearest_rotation(A: np.ndarray) -> np.ndarray:
    """The rotation closest to A (3x3) in the Frobenius norm."""
    U, _, Vt = np.linalg.svd(A)
    return U @ np.diag([1.0, 1.0, np.linalg.det(U @ Vt)]) @ Vt


def mean_pose(T: np.ndarray) -> np.ndarray:
    """Chordal mean of poses (N, 4, 4): the nearest rotation to the mean rotation matrix, the mean translation."""
    out = np.eye(4)
    out[:3, :3] = nearest_rotation(T[:, :3, :3].mean(axis=0))
    out[:3, 3] = T[:, :3, 3].mean(axis=0)
    return out


def hand_eye(T: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(B, M) with T_i ~ B F_i M for poses T, F (N, 4, 4), closed form [Shah 2013]; Degenerate when
    the rotations leave more than one solution."""
    N = len(T)
    if N < 3:
        raise Degenerate(f"{N} configuration(s)")
    eye = np.eye(3)
    RT, RF = T[:, :3, :3], F[:, :3, :3]
    # vec() stacks columns: vec(A X) = (I (x) A) vec(X), vec(Y B) = (B^T (x) I) vec(Y)
    K = np.concatenate([np.einsum("ab,nij->naibj", eye, RT).reshape(N, 9, 9),
                        -np.einsum("nji,ab->niajb", RF, eye).reshape(N, 9, 9)], axis=2).reshape(9 * N, 18)
    _, s, Vt = np.linalg.svd(K, full_matrices=False)
    if s[-2] < DEGENERATE * s[0]:
        raise Degenerate(f"{N} configuration(s)")
    v = Vt[-1]
    X, Y = v[:9].reshape(3, 3, order="F"), v[9:].reshape(3, 3, order="F")
    scale = np.sign(np.linalg.det(X)) * abs(np.linalg.det(X)) ** (-1 / 3)
    RX, RY = nearest_rotation(scale * X), nearest_rotation(scale * Y)
    A = np.concatenate([RT, np.broadcast_to(-eye, (N, 3, 3))], axis=2).reshape(3 * N, 6)
    b = (np.einsum("ij,nj->ni", RY, F[:, :3, 3]) - T[:, :3, 3]).reshape(-1)
    t, _, rank, _ = np.linalg.lstsq(A, b, rcond=None)
    if rank < 6:
        raise Degenerate(f"{N} configuration(s)")
    Xinv, B = np.eye(4), np.eye(4)
    Xinv[:3, :3], Xinv[:3, 3] = RX, t[:3]
    B[:3, :3], B[:3, 3] = RY, t[3:]
    return B, np.linalg.inv(Xinv)


class HandEye(Initializer):
    name = "arm.hand_eye"
    summary = ("initial base and marker poses of a serial_arm from a 6-D tracker's marker poses and the joint states: "
               "closed-form robot-world/hand-eye solve T_i = B F_i M (Shah 2013)")
    robot_fields = ("robot",)
    stream_fields = ("stream",)
    schema = {"type": "object",
              "properties": {"robot": NAME, "stream": NAME, "base": NAME, "tool": NAME, "tool_frame": TOOL_FRAME,
                             "tolerance": TOLERANCE_SCHEMA},
              "required": ["robot", "stream"], "additionalProperties": False}

    def check(self, spec: Spec, scope) -> None:
        """A serial_arm with a pose3 base or tool (the entry's, else the description's) and a pose stream."""
        desc = check_arm_entry(spec, scope)
        kin = desc.extra.get("kinematics") or {}
        marker = marker_of(desc.extra, spec.get("tool_frame") or tool_frames(desc.extra)[0])
        if not spec.get("base", kin.get("base")) and not spec.get("tool", marker):
            raise spec.error("robot", f"robot {spec['robot']!r} has neither a base nor a tool parameter "
                             "(kinematics.base, kinematics.tool): nothing to initialize")
        scope.require_columns(spec, "stream", POSE_COLUMNS)

    def initialize(self, ctx, spec: Spec) -> None:
        robot = spec["robot"]
        arm = entry_arm(ctx.robot(robot), spec)
        layout, variables = entry_layout(arm, spec, "pose3" if spec.get("tool", arm.tool) else "")
        stream = ctx.stream(spec["stream"])
        match = nearest(ctx.state_set(robot, spec).t, stream.t, spec["tolerance"])
        ks = match.state.tolist()
        unknown = variables[:layout.base + bool(layout.tool)]  # base and/or tool
        flange = Layout(False, "", layout.offsets, layout.placements)
        known = [self._value(ctx, robot, name, index, ks) for name, index in variables[len(unknown):]]
        p = Parameters(offsets=known[:len(flange.offsets)], placements=known[len(flange.offsets):])
        q = np.array([ctx.initial_value(key) for key in ctx.state_keys(robot, ks)], float).reshape(len(ks), -1)
        F = marker_poses(arm.chain, flange, q, p).T
        T = pose_matrices(stream.pose_array()[match.row])
        try:
            B, M = self._solve(layout, T, F)
        except Degenerate as exc:
            raise spec.error("stream", f"stream {stream.name!r}: the marker poses of {exc} at the robot's states do "
                             "not determine the base and the marker: they need three or more configurations "
                             "whose rotations are not all about one axis") from None
        found = ([B] if layout.base else []) + ([M] if layout.tool else [])
        for (name, index), value in zip(unknown, found):
            for key in {ctx.parameter(robot, name, index, k) for k in ks}:  # one key unless time-varying
                ctx.set_initial(key, gtsam.Pose3(value))

    @staticmethod
    def _value(ctx, robot: str, name: str, index: int | None, ks: list[int]):
        """An offset's or placement's current value; a time-varying one's at each sample (stacked)."""
        if not ctx.robot(robot).parameters[name].time_varying:
            return ctx.initial_value(ctx.parameter(robot, name, index))
        return np.array([ctx.initial_value(ctx.parameter(robot, name, index, k)) for k in ks])

    @staticmethod
    def _solve(layout: Layout, T: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(B, M): both unknown, or one of them when the description has no tool (M = I) or no base (B = I)."""
        if layout.base and layout.tool:
            return hand_eye(T, F)
        if not len(T):
            raise Degenerate("0 configuration(s)")
        if layout.base:
            return mean_pose(T @ np.linalg.inv(F)), np.eye(4)
        return np.eye(4), mean_pose(np.linalg.inv(F) @ T)


INITIALIZERS = [HandEye]
