"""Serial-arm factor types (docs/models/serial_arm.md#factors): the marker's pose (6-D tracker), its
position (laser tracker), its motion between two configurations, and joint encoders. Joint vectors
are the robot's states (`states: {stream: ..., type: vectorN, family: joints}`); static samples use
the sample index as their time."""

from __future__ import annotations

from abc import abstractmethod
from pathlib import Path

import gtsam
import numpy as np

from fusionkit.api import (FactorExample, FactorType, NAME_SCHEMA as NAME, POSE_COLUMNS, POSE_SIGMA_SCHEMA,
                           POSITIVE_SCHEMA as SIGMA, ResidualPart, Spec, TOLERANCE_SCHEMA, gaussian, lie, pose_parts,
                           pose_sigmas, vectorized_factor)

from .kinematics import Layout, Parameters, marker_pose
from .marker_residual import marker_residual
from .model import arm_of, chain_from, marker_of, tool_frames
from .urdf import PREFIX, urdf_path

TOOL_FRAME = {"type": "string"}  # the description's tool frame the entry measures (required when it has several)


def entry_layout(arm, spec: Spec, tool_type: str, base: bool = True) -> tuple[Layout, list[tuple[str, int | None]]]:
    """The layout of an entry's kinematic variables and each one's (parameter, element): the entry's
    `base`/`tool` (else the description's kinematics), the elements of every offset, placement and compliance group
    whose joint moves the arm's tool frame (the other hand's joints do not enter this hand's factors)."""
    base_name = spec.get("base", arm.base) if base else None
    tool_name = spec.get("tool", arm.tool)
    variables: list[tuple[str, int | None]] = [(base_name, None)] if base_name else []
    variables += [(tool_name, None)] if tool_name else []
    active = set(arm.chain.active)

    def kept(groups, element=lambda group, j: j) -> tuple:
        """The groups' elements whose joint moves the tool: their layout entries, and their variables added."""
        picked = [(g, i, j) for g in groups for i, j in enumerate(g.joints) if j in active]
        variables.extend((g.parameter, i) for g, i, _ in picked)
        return tuple(element(g, j) for g, _, j in picked)
    offsets = kept(arm.offsets)
    placements = kept(arm.placements, lambda g, j: (j, g.axes))
    compliances = kept(arm.compliances)
    mass_compliances = kept(arm.mass_compliances)
    return Layout(bool(base_name), tool_type if tool_name else "", offsets, placements, compliances,
                  arm.payload if compliances else (), mass_compliances, arm.lumped if mass_compliances else ()), \
        variables


def entry_arm(desc, spec: Spec):
    """The description seen from the entry's tool frame (`tool_frame:`, default the description's only one)."""
    return arm_of(desc, spec.get("tool_frame"))


def parameter_keys(ctx, robot: str, variables: list[tuple[str, int | None]], states) -> list[list[int]]:
    """The variables' keys at each state k of `states`: a static parameter's key looked up once."""
    desc = ctx.robot(robot)
    static = {v: ctx.parameter(robot, *v) for v in variables if not desc.parameters[v[0]].time_varying}
    return [[static[v] if v in static else ctx.parameter(robot, *v, k) for v in variables] for k in states]


def check_arm_entry(spec: Spec, scope, tools: tuple[str, ...] = ("pose3",), base: bool = True):
    """A serial_arm robot with joint-vector states; the entry names one of its tool frames when it has several; the
    entry's base and tool name pose parameters."""
    desc = scope.require_model(spec, "robot", "serial_arm")
    scope.require_states(spec, "robot", f"vector{len(desc.extra['joints'])}")
    frames = tool_frames(desc.extra)
    frame = spec.get("tool_frame")
    if frame is None and len(frames) > 1:
        raise spec.error("robot", f"robot {spec['robot']!r} has several tool frames ({', '.join(frames)}): name the "
                         "one this entry measures (`tool_frame:`)")
    if frame is not None and frame not in frames:
        raise spec.error("tool_frame", f"{frame!r} is not a tool frame of robot {spec['robot']!r}: "
                         f"{', '.join(frames)}")
    kin = {"base": (desc.extra.get("kinematics") or {}).get("base"),
           "tool": marker_of(desc.extra, frame or frames[0])}
    for key, types in (("base", ("pose3",)), ("tool", tools)):
        if key == "base" and not base:
            continue
        if key in spec.data:
            scope.require_parameter(spec, "robot", key)
            vartype = desc.parameters[spec[key]].vartype.name
            if vartype not in types or desc.parameters[spec[key]].indexed:
                raise spec.error(key, f"parameter {spec[key]!r} is {vartype}; a {key} is one {' or '.join(types)}")
        elif kin[key] and desc.parameters[kin[key]].vartype.name not in types:
            raise spec.error("robot", f"the description's kinematics.{key} {kin[key]!r} is a "
                             f"{desc.parameters[kin[key]].vartype.name}; {spec.type} needs a {' or '.join(types)} "
                             f"(name one with `{key}:`)")
    return desc


def tool_type(desc, spec: Spec) -> str:
    name = spec.get("tool", marker_of(desc.extra, spec.get("tool_frame") or tool_frames(desc.extra)[0]))
    return desc.parameters[name].vartype.name if name else ""


def pose_matrices(rows: np.ndarray) -> np.ndarray:
    """(N, 4, 4) poses from (N, 7) rows x y z qx qy qz qw (quaternions normalized)."""
    from scipy.spatial.transform import Rotation
    rows = np.asarray(rows, float).reshape(-1, 7)
    T = np.zeros((len(rows), 4, 4))
    T[:, :3, :3] = Rotation.from_quat(rows[:, 3:]).as_matrix()
    T[:, :3, 3] = rows[:, :3]
    T[:, 3, 3] = 1.0
    return T


def marker_example(chain, layout: Layout, kind: str, measured: np.ndarray, values: gtsam.Values, sigma: float):
    """The contract example of one marker factor: keys 0.. of `values` (example_values' order)."""
    return FactorExample(vectorized_factor(marker_residual(chain, layout, kind), gaussian([sigma] * (
        3 if kind == "position" else 6)), list(range(values.size())), {"measured": measured[None]}), values)


class ArmMeasurement(FactorType):
    """Shared by the marker measurements: one factor per sample at its nearest state."""

    kind = ""             # "pose", "position" or "relative" (marker_residual, identifiability.kinematic_regressor)
    robot_fields = ("robot",)
    stream_fields = ("stream",)

    def layout(self, ctx, spec: Spec):
        desc = ctx.robot(spec["robot"])
        return entry_layout(entry_arm(desc, spec), spec, tool_type(desc, spec), self.kind != "relative")

    def sigmas(self, spec: Spec) -> np.ndarray:
        return np.asarray(pose_sigmas(spec["sigma"], False), float)

    def samples(self, ctx, spec: Spec) -> tuple[np.ndarray, np.ndarray]:
        """(states, stream rows) of the samples this entry uses; relative: (pairs of states, pairs of rows)."""
        a = ctx.associate(ctx.stream(spec["stream"]), spec["robot"], spec)
        return a.state, a.row

    @abstractmethod
    def measured(self, stream, rows: np.ndarray, spec: Spec) -> np.ndarray:
        """What the marker residual compares with (its `measured` data), for the stream rows of the samples."""

    def build(self, ctx, spec: Spec) -> None:
        """One factor per sample, all evaluated together (one vectorized residual)."""
        robot = spec["robot"]
        chain = entry_arm(ctx.robot(robot), spec).chain
        layout, variables = self.layout(ctx, spec)
        ks, rows = self.samples(ctx, spec)
        states = ks.reshape(len(ks), -1)  # relative: pairs; the parameters are those of the later state
        pairs = states.tolist()
        keys = [[ctx.state_key(robot, k) for k in pair] + params
                for pair, params in zip(pairs, parameter_keys(ctx, robot, variables, [p[-1] for p in pairs]))]
        measured = self.measured(ctx.stream(spec["stream"]), rows, spec)
        ctx.add_vectorized(marker_residual(chain, layout, self.kind), np.asarray(keys, dtype=np.int64).reshape(
            len(keys), -1), {"measured": measured}, self.sigmas(spec), spec,
            [ctx.state_time(robot, pair[-1]) for pair in pairs])

    def residual_parts(self, ctx, spec: Spec):
        """A pose (or motion) residual's position and orientation; a position residual is all position."""
        return pose_parts(False) if self.kind != "position" else [ResidualPart("position", "m", (0, 1, 2))]

    def diagnose(self, ctx, spec: Spec) -> None:
        """Identifiability of the robot's kinematic parameters (run once, by its first marker entry)."""
        from .diagnosis import identify
        identify(ctx, spec)


class ToolPose(ArmMeasurement):
    name = "arm.tool_pose"
    summary = ("6-D tracker: the marker's pose in the measurement frame, B * FK(q + dq; placements) * M "
               "(serial_arm, Pinocchio FK, analytic Jacobians)")
    kind = "pose"
    schema = {"type": "object",
              "properties": {"robot": NAME, "stream": NAME, "sigma": POSE_SIGMA_SCHEMA, "base": NAME, "tool": NAME,
                             "tool_frame": TOOL_FRAME,
                             "tolerance": TOLERANCE_SCHEMA},
              "required": ["robot", "stream", "sigma"], "additionalProperties": False}

    def check(self, spec: Spec, scope) -> None:
        check_arm_entry(spec, scope)
        scope.require_columns(spec, "stream", POSE_COLUMNS)

    def measured(self, stream, rows: np.ndarray, spec: Spec) -> np.ndarray:
        return lie.inverse(pose_matrices(stream.pose_array()[rows]))

    @classmethod
    def example(cls, rng):
        chain, layout, p = example_arm(rng, "pose3")
        q = rng.uniform(-np.pi, np.pi, chain.n)
        values = example_values(layout, p, q)
        z = marker_pose(chain, layout, q, p)[0]  # Pinocchio's forward kinematics: the batched code must agree
        return marker_example(chain, layout, cls.kind, lie.inverse(z), values, 1e-3)


class ToolPosition(ArmMeasurement):
    name = "arm.tool_position"
    summary = ("laser tracker: the marker's position (m) in the measurement frame, from the stream's x, y, z columns "
               "or the three `columns:` named (serial_arm)")
    kind = "position"
    schema = {"type": "object",
              "properties": {"robot": NAME, "stream": NAME, "sigma": SIGMA, "base": NAME, "tool": NAME,
                             "tool_frame": TOOL_FRAME,
                             "columns": {"type": "array", "items": NAME, "minItems": 3, "maxItems": 3,
                                         "uniqueItems": True, "default": ["x", "y", "z"]},
                             "tolerance": TOLERANCE_SCHEMA},
              "required": ["robot", "stream", "sigma"], "additionalProperties": False}

    def check(self, spec: Spec, scope) -> None:
        """`columns` (x, y, z of the marker, m; default x, y, z) are columns of the stream: several markers (two
        hands) in one CSV."""
        check_arm_entry(spec, scope, ("pose3", "point3"))
        scope.require_columns(spec, "stream", tuple(spec["columns"]))

    def sigmas(self, spec: Spec) -> np.ndarray:
        return np.full(3, float(spec["sigma"]))

    def measured(self, stream, rows: np.ndarray, spec: Spec) -> np.ndarray:
        return np.column_stack([stream.column(c) for c in spec["columns"]])[rows]

    @classmethod
    def example(cls, rng):
        chain, layout, p = example_arm(rng, "point3" if rng.uniform() < 0.5 else "pose3")
        q = rng.uniform(-np.pi, np.pi, chain.n)
        values = example_values(layout, p, q)
        z = marker_pose(chain, layout, q, p)[0][:3, 3]
        return marker_example(chain, layout, cls.kind, z, values, 1e-4)


class RelativeToolPose(ArmMeasurement):
    name = "arm.relative_tool_pose"
    summary = ("marker motion between consecutive samples of a pose stream in any fixed frame: "
               "T(q_a)^-1 T(q_b); the base cancels (serial_arm)")
    kind = "relative"
    schema = {"type": "object",
              "properties": {"robot": NAME, "stream": NAME, "sigma": POSE_SIGMA_SCHEMA, "tool": NAME,
                             "tool_frame": TOOL_FRAME,
                             "tolerance": TOLERANCE_SCHEMA},
              "required": ["robot", "stream", "sigma"], "additionalProperties": False}

    def check(self, spec: Spec, scope) -> None:
        check_arm_entry(spec, scope, base=False)
        scope.require_columns(spec, "stream", POSE_COLUMNS)

    def samples(self, ctx, spec: Spec) -> tuple[np.ndarray, np.ndarray]:
        ks, rows = super().samples(ctx, spec)
        nxt = np.flatnonzero(np.diff(rows) == 1)  # consecutive samples, both at a state
        return np.column_stack([ks[nxt], ks[nxt + 1]]), np.column_stack([rows[nxt], rows[nxt + 1]])

    def measured(self, stream, rows: np.ndarray, spec: Spec) -> np.ndarray:
        """z^-1 = P_b^-1 P_a for the measured motion z = P_a^-1 P_b of each pair."""
        poses = stream.pose_array()
        return lie.inverse(pose_matrices(poses[rows[:, 1]])) @ pose_matrices(poses[rows[:, 0]])

    @classmethod
    def example(cls, rng):
        chain, layout, p = example_arm(rng, "pose3", base=False)
        qa, qb = rng.uniform(-np.pi, np.pi, (2, chain.n))
        values = example_values(layout, p, qa, qb)
        z = lie.inverse(marker_pose(chain, layout, qa, p)[0]) @ marker_pose(chain, layout, qb, p)[0]
        # 1e-2: the motion's residual carries ~1e-15 of rounding, which central differences at 1e-6 turn into
        # ~1e-6 of whitened Jacobian at 1e-3 (the contract's tolerance); the Jacobian is the same
        return marker_example(chain, layout, cls.kind, lie.inverse(z), values, 1e-2)


class JointEncoders(FactorType):
    name = "arm.joint_encoders"
    summary = "joint encoder readings -> the joint-vector state (native vector prior, a sigma per joint), and its start"
    robot_fields = ("robot",)
    stream_fields = ("stream",)
    schema = {"type": "object",
              "properties": {"robot": NAME, "stream": NAME,
                             "sigma": {"oneOf": [SIGMA, {"type": "array", "items": SIGMA, "minItems": 1}]},
                             "columns": {"type": "array", "items": NAME, "minItems": 1},
                             "tolerance": TOLERANCE_SCHEMA},
              "required": ["robot", "stream", "sigma"], "additionalProperties": False}

    def check(self, spec: Spec, scope) -> None:
        """`columns` (default: the description's joint names) and a list `sigma` have one per joint."""
        desc = scope.require_model(spec, "robot", "serial_arm")
        n = len(desc.extra["joints"])
        scope.require_states(spec, "robot", f"vector{n}")
        for key in ("columns", "sigma"):
            if isinstance(spec.get(key), list) and len(spec[key]) != n:
                raise spec.error(key, f"{len(spec[key])} given; the arm has {n} joints "
                                 f"({', '.join(desc.extra['joints'])})")
        scope.require_columns(spec, "stream", tuple(spec.get("columns") or desc.extra["joints"]))

    def build(self, ctx, spec: Spec) -> None:
        robot = spec["robot"]
        joints = ctx.robot(robot).extra["joints"]
        stream = ctx.stream(spec["stream"])
        readings = np.column_stack([stream.column(c) for c in spec.get("columns") or joints])
        sigma = spec["sigma"]
        noise = ctx.noise(sigma if isinstance(sigma, list) else [sigma] * len(joints), spec)
        a = ctx.associate(stream, robot, spec)
        for k, z in zip(a.state.tolist(), readings[a.row]):
            key = ctx.state_key(robot, k)
            ctx.add(gtsam.PriorFactorVector(key, z, noise), spec, ctx.state_time(robot, k))
            ctx.set_initial(key, z)

    @classmethod
    def example(cls, rng):
        q = rng.uniform(-np.pi, np.pi, 6)
        values = gtsam.Values()
        values.insert(0, q)
        return FactorExample(gtsam.PriorFactorVector(0, q, gaussian(rng.uniform(1e-5, 1e-3, 6))), values)


def example_arm(rng: np.random.Generator, tool: str, base: bool = True) -> tuple:
    """A UR10 (example-robot-data) with a random base, tool, two joint offsets, placement errors on four joints
    (one joint in two placement entries), compliances of three joints under gravity with a 3 kg payload at the
    flange and mass compliances of two joints with two lumped masses: (chain, layout, parameters)."""
    chain = chain_from(urdf_path(PREFIX + "ur10", Path(".")), "base_link", "tool0", UR_JOINTS)
    layout = Layout(base, tool, (1, 3), ((0, (0, 1, 2, 3, 4, 5)), (2, (3, 5)), (2, (1,)), (5, (2, 4))), (1, 2, 4),
                    ("tool0", 3.0, 0.0, 0.02, 0.05), (1, 3), (("forearm_link", 0.0, 0.0, 0.3), ("wrist_3_link", 0.0,
                                                                                                  0.05, 0.0)))
    pose = lambda: gtsam.Pose3.Expmap(rng.normal(scale=0.5, size=6)).matrix()  # noqa: E731
    tool_value = pose() if tool == "pose3" else np.block([[np.eye(3), rng.normal(size=(3, 1))], [0, 0, 0, 1]])
    return chain, layout, Parameters(pose() if base else None, tool_value, rng.normal(scale=0.1, size=2),
                                     [rng.normal(scale=0.1, size=len(axes)) for _, axes in layout.placements],
                                     rng.uniform(0.0, 3e-4, size=3), [rng.uniform(0.0, 1e-3, size=2) for _ in range(2)])


def example_values(layout: Layout, p: Parameters, *joint_vectors: np.ndarray) -> gtsam.Values:
    """Keys 0.. the joint vectors, then the layout's variables in order."""
    values = gtsam.Values()
    items = list(joint_vectors) + ([gtsam.Pose3(p.base)] if layout.base else [])
    items += [gtsam.Pose3(p.tool) if layout.tool == "pose3" else p.tool[:3, 3].copy()] if layout.tool else []
    items += [float(v) for v in p.offsets] + [np.asarray(v, float) for v in p.placements]
    items += [float(v) for v in p.compliances] + [np.asarray(v, float) for v in p.mass_compliances]
    for key, item in enumerate(items):
        values.insert(key, item)
    return values


UR_JOINTS = ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
             "wrist_3_joint")
FACTOR_TYPES = [ToolPose, ToolPosition, RelativeToolPose, JointEncoders]
