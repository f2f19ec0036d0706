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

`arm.point_markers` starts the base and point markers from positions only (every arm.tool_position entry of the
robot, one marker per tool frame): z_i = B F_i m, the base B by Kabsch given the markers, each marker m by linear
least squares given the base, alternately.
"""

from __future__ import annotations

import gtsam
import numpy as np

from fusionkit.api import Initializer, NAME_SCHEMA as NAME, POSE_COLUMNS, Spec, TOLERANCE_SCHEMA, nearest

from .vectorized_kinematics import marker_poses
from .factors import TOOL_FRAME, check_arm_entry, entry_arm, entry_layout, pose_matrices
from .kinematics import Layout, Parameters
from .model import marker_of, tool_frames

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


def rigid_fit(P: np.ndarray, Z: np.ndarray) -> np.ndarray:
    """The pose B (4x4) minimizing sum |B p_i - z_i|^2 for points P, Z (N, 3) (Kabsch, scipy's align_vectors)."""
    from scipy.spatial.transform import Rotation
    p0, z0 = P.mean(axis=0), Z.mean(axis=0)
    R = Rotation.align_vectors(Z - z0, P - p0)[0].as_matrix()
    B = np.eye(4)
    B[:3, :3], B[:3, 3] = R, z0 - R @ p0
    return B


def base_and_points(F: list[np.ndarray], Z: list[np.ndarray], m: list[np.ndarray], rounds: int = 50
                    ) -> tuple[np.ndarray, list[np.ndarray]]:
    """(B, [m_e]) with z ~ B F m_e for each marker e's flange poses F[e] (N_e, 4, 4), measured points Z[e] (N_e, 3)
    and start m[e] (3,): the base by Kabsch given the markers, each marker by linear least squares given the base,
    alternately until they stop moving. Degenerate unless the points span a plane."""
    m = [np.asarray(x, float).copy() for x in m]
    P_all = np.concatenate(Z)
    if len(P_all) < 3 or np.linalg.matrix_rank(P_all - P_all.mean(axis=0), tol=1e-6) < 2:
        raise Degenerate(f"{len(P_all)} marker position(s)")
    B = np.eye(4)
    for _ in range(rounds):
        points = np.concatenate([f[:, :3, :3] @ x + f[:, :3, 3] for f, x in zip(F, m)])
        B = rigid_fit(points, P_all)
        moved = 0.0
        for e, (f, z) in enumerate(zip(F, Z)):
            A = (B[:3, :3] @ f[:, :3, :3]).reshape(-1, 3)  # z_i = R_B (R_Fi m + t_Fi) + t_B
            b = (z - f[:, :3, 3] @ B[:3, :3].T - B[:3, 3]).reshape(-1)
            new = np.linalg.lstsq(A, b, rcond=None)[0]
            moved, m[e] = max(moved, float(np.linalg.norm(new - m[e]))), new
        if moved < 1e-9:
            break
    return B, m


class PointMarkers(Initializer):
    name = "arm.point_markers"
    summary = ("initial base and point markers of a serial_arm from its arm.tool_position entries (one marker per tool "
               "frame, several in one CSV): base by Kabsch, markers by least squares, alternately")
    robot_fields = ("robot",)
    schema = {"type": "object", "properties": {"robot": NAME}, "required": ["robot"], "additionalProperties": False}

    def check(self, spec: Spec, scope) -> None:
        """A serial_arm with a pose3 base (kinematics.base)."""
        desc = scope.require_model(spec, "robot", "serial_arm")
        base = (desc.extra.get("kinematics") or {}).get("base")
        if not base or desc.parameters[base].vartype.name != "pose3":
            raise spec.error("robot", f"robot {spec['robot']!r} has no pose3 base (kinematics.base): nothing for "
                             "arm.point_markers to start")

    def initialize(self, ctx, spec: Spec) -> None:
        """Every arm.tool_position entry of the robot: its samples' flange positions at the joint states (current
        offsets and placement errors) and its measured points; the entries' base must be the description's."""
        robot = spec["robot"]
        desc = ctx.robot(robot)
        entries = ctx.entries("arm.tool_position", robot)
        if not entries:
            raise spec.error("robot", f"robot {robot!r} has no arm.tool_position entry to start the base from")
        F, Z, starts, markers = [], [], [], []
        for entry in entries:
            arm = entry_arm(desc, entry)
            layout, variables = entry_layout(arm, entry, "point3")
            flange = Layout(False, "", layout.offsets, layout.placements, layout.compliances, layout.payload,
                            layout.mass_compliances, layout.lumped)
            stream = ctx.stream(entry["stream"])
            a = ctx.associate(stream, robot, entry)
            ks = a.state.tolist()
            known = variables[layout.base + bool(layout.tool):]
            values = [HandEye._value(ctx, robot, name, index, ks) for name, index in known]
            counts = np.cumsum([0, len(layout.offsets), len(layout.placements), len(layout.compliances)])
            p = Parameters(offsets=values[:counts[1]], placements=values[counts[1]:counts[2]],
                           compliances=values[counts[2]:counts[3]], mass_compliances=values[counts[3]:])
            q = np.array([ctx.initial_value(key) for key in ctx.state_keys(robot, ks)], float).reshape(len(ks), -1)
            F.append(marker_poses(arm.chain, flange, q, p).T)
            Z.append(np.column_stack([stream.column(c) for c in entry["columns"]])[a.row])
            tool = entry.get("tool", arm.tool)
            markers.append(tool)
            starts.append(np.asarray(ctx.initial_value(ctx.parameter(robot, tool)), float) if tool else np.zeros(3))
        try:
            B, found = base_and_points(F, Z, starts)
        except Degenerate as exc:
            raise spec.error("robot", f"the marker positions ({exc}) do not determine the base: they need three or "
                             "more points not on one line") from None
        ctx.set_initial(ctx.parameter(robot, (desc.extra.get("kinematics") or {})["base"]), gtsam.Pose3(B))
        for tool, m in zip(markers, found):
            if tool and desc.parameters[tool].vartype.name == "point3":
                ctx.set_initial(ctx.parameter(robot, tool), m)


INITIALIZERS = [HandEye, PointMarkers]
