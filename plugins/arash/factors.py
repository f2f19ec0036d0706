"""Factor types of the RCM arm (docs/models/arash.md): joint encoders, the tracked tool tip, and the
co-registration of two arms -- the follower's tip seen from the leader's (tool to tool) and a
survey of the follower's base -- through the base-to-base transform `<other>/base_in_<robot>`."""

from __future__ import annotations

from functools import partial

import gtsam
import numpy as np

from fusionkit.api import (FactorExample, FactorType, POSE3, POSE_COLUMNS, POSE_SIGMA_SCHEMA,
                           POSITIVE_SCHEMA as POSITIVE, ResidualPart, Spec, TOLERANCE_SCHEMA, gaussian, pose_sigmas,
                           poses_from_array)

from .kinematics import CONVENTIONS
from .model import JOINTS, PARAMETERS, convention_of
from .residuals import tool_position_residual, tool_to_tool_residual



def columns_schema(default: list[str]) -> dict:
    return {"type": "array", "items": {"type": "string"}, "minItems": 3, "maxItems": 3, "default": default}


def check_arm(spec: Spec, scope, key: str) -> str:
    """Robot `spec[key]` is an rcm_arm with vector3 (joint) states; its convention."""
    desc = scope.require_model(spec, key, "rcm_arm")
    scope.require_states(spec, key, "vector3")
    return convention_of(desc)


def check_pair(spec: Spec, scope) -> None:
    """`robot` and `other` are two rcm_arms of one convention (one length unit)."""
    if spec["robot"] == spec["other"]:
        raise spec.error("other", "must name a different robot than `robot`")
    mine, theirs = check_arm(spec, scope, "robot"), check_arm(spec, scope, "other")
    if mine != theirs:
        raise spec.error("other", f"robot {spec['other']!r} uses convention {theirs!r}, robot {spec['robot']!r} "
                         f"{mine!r}: co-registered arms must share one convention (one length unit)")


def parameter_keys(ctx, robot: str, k: int) -> list[int]:
    """Keys of alpha, theta, l_1234 at state k (one variable each unless time-varying)."""
    return [ctx.parameter(robot, name, k=k) for name in PARAMETERS]


def base_key(ctx, spec: Spec) -> int:
    """`<other>/base_in_<robot>`: robot `other`'s base frame in robot `robot`'s (set by rcm.base_transform)."""
    return ctx.base_transform(spec["other"], spec["robot"])


def measurements(ctx, spec: Spec) -> np.ndarray:
    stream = ctx.stream(spec["stream"])
    return np.column_stack([stream.column(c) for c in spec["columns"]])


class JointEncoders(FactorType):
    name = "rcm.joint_encoders"
    summary = "joint encoders (phi, psi, d) of an rcm_arm: native prior on its joint state; sets its initial value"
    robot_fields = ("robot",)
    stream_fields = ("stream",)
    schema = {"type": "object",
              "properties": {"robot": {"type": "string"}, "stream": {"type": "string"},
                             "sigma": {"type": "object", "properties": {j: POSITIVE for j in JOINTS},
                                       "required": list(JOINTS), "additionalProperties": False},
                             "columns": columns_schema(list(JOINTS)), "tolerance": TOLERANCE_SCHEMA},
              "required": ["robot", "stream", "sigma"], "additionalProperties": False}

    def check(self, spec: Spec, scope) -> None:
        check_arm(spec, scope, "robot")
        scope.require_columns(spec, "stream", tuple(spec["columns"]))

    def build(self, ctx, spec: Spec) -> None:
        robot = spec["robot"]
        assoc = ctx.associate(ctx.stream(spec["stream"]), robot, spec)
        noise = ctx.noise([spec["sigma"][j] for j in JOINTS], spec)
        readings = measurements(ctx, spec)[assoc.row]
        for k, z in zip(assoc.state.tolist(), readings):
            key = ctx.state_key(robot, k)
            ctx.add(gtsam.PriorFactorVector(key, z, noise), spec, ctx.state_time(robot, k))
            ctx.set_initial(key, z)

    @classmethod
    def example(cls, rng):
        q = rng.normal(size=3)
        values = gtsam.Values()
        values.insert(0, q)
        return FactorExample(gtsam.PriorFactorVector(0, q, gaussian([1e-4, 1e-4, 1e-5])), values)


def _tool_error(z: np.ndarray, convention: str, this: gtsam.CustomFactor, v: gtsam.Values, H) -> np.ndarray:
    keys = this.keys()
    k = np.array([v.atDouble(key) for key in keys[1:4]])
    return tool_position_residual(v.atVector(keys[0]), k, z, convention, H)


def tool_position_factor(q: int, params: list[int], z: np.ndarray, convention: str, noise) -> gtsam.CustomFactor:
    return gtsam.CustomFactor(noise, [q, *params], partial(_tool_error, np.asarray(z, float), convention))


class ToolPosition(FactorType):
    name = "rcm.tool_position"
    summary = ("tracker measurement of an rcm_arm's tool tip in its base frame (thesis eq. 3.7 or the authors' "
               "convention)")
    robot_fields = ("robot",)
    stream_fields = ("stream",)
    schema = {"type": "object",
              "properties": {"robot": {"type": "string"}, "stream": {"type": "string"}, "sigma": POSITIVE,
                             "columns": columns_schema(["x", "y", "z"]), "tolerance": TOLERANCE_SCHEMA},
              "required": ["robot", "stream", "sigma"], "additionalProperties": False}

    def check(self, spec: Spec, scope) -> None:
        check_arm(spec, scope, "robot")
        scope.require_columns(spec, "stream", tuple(spec["columns"]))

    def build(self, ctx, spec: Spec) -> None:
        robot = spec["robot"]
        convention = convention_of(ctx.robot(robot))
        assoc = ctx.associate(ctx.stream(spec["stream"]), robot, spec)
        noise = ctx.noise([spec["sigma"]] * 3, spec)
        for k, z in zip(assoc.state.tolist(), measurements(ctx, spec)[assoc.row]):
            factor = tool_position_factor(ctx.state_key(robot, k), parameter_keys(ctx, robot, k), z, convention, noise)
            ctx.add(factor, spec, ctx.state_time(robot, k))

    def residual_parts(self, ctx, spec: Spec):
        """The tool tip's position, in the convention's length unit."""
        return [ResidualPart("position", CONVENTIONS[convention_of(ctx.robot(spec['robot']))], (0, 1, 2))]

    @classmethod
    def example(cls, rng):
        convention = list(CONVENTIONS)[int(rng.integers(2))]
        q, k = _random_configuration(rng, convention)
        values = gtsam.Values()
        values.insert(0, q)
        for i in range(3):
            values.insert(1 + i, float(k[i]))
        z = tool_position_residual(q, k, np.zeros(3), convention)
        return FactorExample(tool_position_factor(0, [1, 2, 3], z, convention, gaussian([0.1] * 3)), values)


def _random_configuration(rng, convention: str) -> tuple[np.ndarray, np.ndarray]:
    """General joints and parameters of either convention (lengths in its unit)."""
    scale = 1.0 if CONVENTIONS[convention] == "m" else 1000.0
    q = np.array([rng.uniform(-1, 1), rng.uniform(-1, 1), scale * rng.uniform(-0.03, 0.03)])
    k = np.array([rng.uniform(0.3, 1.2), rng.uniform(0.3, 1.2), scale * rng.uniform(0.2, 0.5)])
    return q, k


def _tool_to_tool_error(z: np.ndarray, convention: str, this: gtsam.CustomFactor, v: gtsam.Values, H) -> np.ndarray:
    keys = this.keys()
    ka = np.array([v.atDouble(key) for key in keys[1:4]])
    kb = np.array([v.atDouble(key) for key in keys[5:8]])
    return tool_to_tool_residual(v.atVector(keys[0]), ka, v.atVector(keys[4]), kb, v.atPose3(keys[8]), z,
                                 convention, H)


def tool_to_tool_factor(qa: int, ka: list[int], qb: int, kb: list[int], base: int, z: np.ndarray,
                        convention: str, noise) -> gtsam.CustomFactor:
    return gtsam.CustomFactor(noise, [qa, *ka, qb, *kb, base], partial(_tool_to_tool_error, np.asarray(z, float),
                                                                       convention))


class ToolToTool(FactorType):
    name = "rcm.tool_to_tool"
    summary = ("co-registration of two rcm_arms: the `other` arm's tool tip seen from `robot`'s, in robot's base "
               "frame (0: the tips coincide); estimates other/base_in_<robot>")
    robot_fields = ("robot", "other")
    stream_fields = ("stream",)
    schema = {"type": "object",
              "properties": {"robot": {"type": "string"}, "other": {"type": "string"}, "stream": {"type": "string"},
                             "sigma": POSITIVE, "columns": columns_schema(["dx", "dy", "dz"]),
                             "tolerance": TOLERANCE_SCHEMA},
              "required": ["robot", "other", "stream", "sigma"], "additionalProperties": False}

    def check(self, spec: Spec, scope) -> None:
        check_pair(spec, scope)
        scope.require_columns(spec, "stream", tuple(spec["columns"]))

    def build(self, ctx, spec: Spec) -> None:
        a, b = spec["robot"], spec["other"]
        convention = convention_of(ctx.robot(a))
        stream = ctx.stream(spec["stream"])
        pairs = paired_states(ctx, spec, stream)
        z = measurements(ctx, spec)
        base = base_key(ctx, spec)
        noise = ctx.noise([spec["sigma"]] * 3, spec)
        for row, ka, kb in pairs:
            factor = tool_to_tool_factor(ctx.state_key(a, ka), parameter_keys(ctx, a, ka), ctx.state_key(b, kb),
                                         parameter_keys(ctx, b, kb), base, z[row], convention, noise)
            ctx.add(factor, spec, max(ctx.state_time(a, ka), ctx.state_time(b, kb)))

    @classmethod
    def example(cls, rng):
        convention = list(CONVENTIONS)[int(rng.integers(2))]
        (qa, ka), (qb, kb) = _random_configuration(rng, convention), _random_configuration(rng, convention)
        base = gtsam.Pose3.Expmap(np.concatenate([rng.normal(size=3), 0.3 * rng.normal(size=3)]))
        values = gtsam.Values()
        for key, value in enumerate([qa, *map(float, ka), qb, *map(float, kb), base]):
            values.insert(key, value)
        z = tool_to_tool_residual(qa, ka, qb, kb, base, np.zeros(3), convention)
        factor = tool_to_tool_factor(0, [1, 2, 3], 4, [5, 6, 7], 8, z, convention, gaussian([0.1] * 3))
        return FactorExample(factor, values)


def paired_states(ctx, spec: Spec, stream) -> list[tuple[int, int, int]]:
    """(row, state of `robot`, state of `other`) for the stream rows both robots have a state for."""
    assoc_a = ctx.associate(stream, spec["robot"], spec)
    assoc_b = ctx.associate(stream, spec["other"], spec)
    ka, kb = dict(zip(assoc_a.row.tolist(), assoc_a.state.tolist())), dict(zip(assoc_b.row.tolist(),
                                                                               assoc_b.state.tolist()))
    return [(row, ka[row], kb[row]) for row in sorted(ka.keys() & kb.keys())]


class BasePose(FactorType):
    name = "rcm.base_pose"
    summary = ("survey of the `other` arm's base frame in `robot`'s (markers on its base plate): native prior on "
               "other/base_in_<robot>")
    robot_fields = ("robot", "other")
    stream_fields = ("stream",)
    schema = {"type": "object",
              "properties": {"robot": {"type": "string"}, "other": {"type": "string"}, "stream": {"type": "string"},
                             "sigma": POSE_SIGMA_SCHEMA},
              "required": ["robot", "other", "stream", "sigma"], "additionalProperties": False}

    def check(self, spec: Spec, scope) -> None:
        check_pair(spec, scope)
        scope.require_columns(spec, "stream", POSE_COLUMNS)

    def build(self, ctx, spec: Spec) -> None:
        base = base_key(ctx, spec)
        noise = ctx.noise(pose_sigmas(spec["sigma"], False), spec)
        for pose in poses_from_array(ctx.stream(spec["stream"]).pose_array()):
            ctx.add(gtsam.PriorFactorPose3(base, pose, noise), spec)

    @classmethod
    def example(cls, rng):
        pose = gtsam.Pose3.Expmap(rng.normal(size=6))
        values = gtsam.Values()
        values.insert(0, pose)
        return FactorExample(gtsam.PriorFactorPose3(0, pose, gaussian([0.01] * 3 + [0.02] * 3)), values)


FACTOR_TYPES = [JointEncoders, ToolPosition, ToolToTool, BasePose]
