"""Initial values for pose states: dead reckoning, interpolation of absolute poses, base transforms."""

from __future__ import annotations

import gtsam
import numpy as np

from fusionkit.api import POSE_COLUMNS, Initializer, nearest, poses_from_array, Spec, stream_poses_at

from .factors import dead_reckoned, to_pose2


def _set_poses(ctx, robot: str, poses: list[gtsam.Pose3]) -> None:
    """Initial values of the robot's declared states (those some factor uses)."""
    states = ctx.state_set(robot)
    planar = states.family.vartype.name == "pose2"
    for key, p in zip(states.family.keys(range(len(poses))), poses):
        if ctx.has_variable(key):
            ctx.set_initial(key, to_pose2(p) if planar else p)


def _first_state_pose(ctx, robot: str) -> gtsam.Pose3:
    """The first state's current initial value as a Pose3 (a Pose2 lifted to the plane z = 0)."""
    states = ctx.state_set(robot)
    if not ctx.has_variable(states.key(0)):
        return gtsam.Pose3()
    p = ctx.initial_value(states.key(0))
    if isinstance(p, gtsam.Pose2):
        return gtsam.Pose3(gtsam.Rot3.Yaw(p.theta()), np.array([p.x(), p.y(), 0.0]))
    return p


def _at_states(stream, t: np.ndarray) -> list[gtsam.Pose3]:
    """Stream poses at times t; times outside the stream's span take the nearest end pose."""
    return stream_poses_at(stream, np.clip(t, stream.t[0], stream.t[-1]))[1]


class DeadReckoning(Initializer):
    name = "pose.dead_reckoning"
    summary = ("compose odometry increments from a start pose: the first `anchor` pose if given, else the "
               "first state's current initial value (set by pose.origin; identity otherwise)")
    robot_fields = ("robot",)
    stream_fields = ("stream", "anchor")
    schema = {"type": "object",
              "properties": {"robot": {"type": "string"}, "stream": {"type": "string"},
                             "anchor": {"type": "string"}, "scale": {"type": "string"}},
              "required": ["robot", "stream"], "additionalProperties": False}

    def check(self, spec: Spec, scope) -> None:
        scope.require_columns(spec, "stream", POSE_COLUMNS)
        if "scale" in spec.data:
            scope.require_parameter(spec, "robot", "scale", "scalar")

    def initialize(self, ctx, spec: Spec) -> None:
        robot = spec["robot"]
        states = ctx.state_set(robot, spec)
        odo = _at_states(ctx.stream(spec["stream"]), states.t)
        if "anchor" in spec.data:
            anchor = ctx.stream(spec["anchor"])
            first = nearest(anchor.t, states.t[:1], np.inf)
            start = poses_from_array(anchor.pose_array()[first.state])[0]
        else:
            start = _first_state_pose(ctx, robot)
        scale = float(ctx.initial_value(ctx.parameter(robot, spec["scale"]))) if "scale" in spec.data else 1.0
        _set_poses(ctx, robot, dead_reckoned(start, odo[:-1], odo[1:], scale))


class ScaleFromAbsolute(Initializer):
    name = "pose.scale_from_absolute"
    summary = "initial odometry scale: least-squares ratio of absolute to odometry displacements"
    robot_fields = ("robot",)
    stream_fields = ("stream", "anchor")
    schema = {"type": "object",
              "properties": {"robot": {"type": "string"}, "stream": {"type": "string"},
                             "anchor": {"type": "string"}, "scale": {"type": "string"}},
              "required": ["robot", "stream", "anchor", "scale"], "additionalProperties": False}

    def check(self, spec: Spec, scope) -> None:
        scope.require_columns(spec, "stream", POSE_COLUMNS)
        scope.require_columns(spec, "anchor", POSE_COLUMNS)
        scope.require_parameter(spec, "robot", "scale", "scalar")

    def initialize(self, ctx, spec: Spec) -> None:
        anchor = ctx.stream(spec["anchor"])
        if len(anchor) < 2:
            raise spec.error("anchor", f"stream {anchor.name!r} has {len(anchor)} pose(s); the scale needs two")
        odo = _at_states(ctx.stream(spec["stream"]), anchor.t)
        d_abs = np.linalg.norm(np.diff(anchor.pose_array()[:, :3], axis=0), axis=1)
        d_odo = np.linalg.norm(np.diff(np.array([p.translation() for p in odo]), axis=0), axis=1)
        if not np.any(d_odo > 0):
            raise spec.error("stream", f"stream {spec['stream']!r} does not move between the anchor poses")
        ctx.set_initial(ctx.parameter(spec["robot"], spec["scale"]), float(d_abs @ d_odo / (d_odo @ d_odo)))


class InterpolateAbsolute(Initializer):
    name = "pose.interpolate"
    summary = "interpolate an absolute pose stream at the state times (ends held)"
    robot_fields = ("robot",)
    stream_fields = ("stream",)
    schema = {"type": "object", "properties": {"robot": {"type": "string"}, "stream": {"type": "string"}},
              "required": ["robot", "stream"], "additionalProperties": False}

    def check(self, spec: Spec, scope) -> None:
        scope.require_columns(spec, "stream", POSE_COLUMNS)

    def initialize(self, ctx, spec: Spec) -> None:
        states = ctx.state_set(spec["robot"], spec)
        _set_poses(ctx, spec["robot"], _at_states(ctx.stream(spec["stream"]), states.t))


class BaseTransform(Initializer):
    name = "pose.base_transform"
    summary = "initial base-to-base transform of a co-registered robot pair from the first relative pose"
    robot_fields = ("robot", "other")
    stream_fields = ("stream",)
    schema = {"type": "object",
              "properties": {"robot": {"type": "string"}, "other": {"type": "string"},
                             "stream": {"type": "string"}},
              "required": ["robot", "other", "stream"], "additionalProperties": False}

    def initialize(self, ctx, spec: Spec) -> None:
        a, b = spec["robot"], spec["other"]
        stream = ctx.stream(spec["stream"])
        ka = nearest(ctx.state_set(a, spec).t, stream.t[:1], np.inf).state[0]
        kb = nearest(ctx.state_set(b, spec).t, stream.t[:1], np.inf).state[0]
        z = stream.poses()[0]
        xa = ctx.initial_value(ctx.pose_key(a, int(ka)))
        xb = ctx.initial_value(ctx.pose_key(b, int(kb)))
        base = ctx.base_transform(b, a, declare=False)
        if base is None:
            raise spec.error("other", f"no pose.co_registration factor links {a!r} and {b!r}")
        ctx.set_initial(base, xa.compose(z).compose(xb.inverse()))


INITIALIZERS = [ScaleFromAbsolute, DeadReckoning, InterpolateAbsolute, BaseTransform]
