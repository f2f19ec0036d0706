"""Generic pose factor types: absolute pose, origin prior, relative pose (odometry), relative pose
with unknown scale (monocular VO, thesis eq. 4.3), co-registration between robots, and the
random walk that chains a time-varying parameter."""

from __future__ import annotations

import gtsam
import numpy as np

from fusionkit.api import (POSE2, POSE3, POSE_COLUMNS, POSE_SIGMA_SCHEMA, SCALAR, TOLERANCE_SCHEMA, FactorExample,
                           FactorType, gaussian, odometry_pairs, pose_parts, pose_sigmas, poses_from_array, sensor_mount,
                           Spec, Stream, vectorized_factor)

from .residuals import CO_REGISTRATION, SCALED_BETWEEN

SIGMA = POSE_SIGMA_SCHEMA


def to_pose2(p: gtsam.Pose3) -> gtsam.Pose2:
    """Project a 3-D pose onto the plane: x, y and yaw."""
    return gtsam.Pose2(p.x(), p.y(), p.rotation().yaw())


def check_pose_stream_entry(spec: Spec, scope) -> None:
    """A pose stream, a robot with states, and (if named) a sensor of that robot."""
    scope.require_columns(spec, "stream", POSE_COLUMNS)
    scope.require_states(spec, "robot")
    check_sensor(spec, scope)


def check_sensor(spec: Spec, scope) -> None:
    if "sensor" in spec.data:
        sensors = scope.robots[spec["robot"]].sensors
        if spec["sensor"] not in sensors:
            raise spec.error("sensor", f"robot {spec['robot']!r} has no sensor {spec['sensor']!r}; it has: "
                             f"{', '.join(sorted(sensors)) or '(none)'}")


def dead_reckoned(start: gtsam.Pose3, before: list[gtsam.Pose3], after: list[gtsam.Pose3],
                  scale: float = 1.0) -> list[gtsam.Pose3]:
    """`start` followed by each increment before[i]^-1 after[i] composed onto the last pose, its translation
    times `scale` (an odometry in its own units)."""
    poses = [start]
    for a, b in zip(before, after):
        d = a.between(b)
        poses.append(poses[-1].compose(gtsam.Pose3(d.rotation(), scale * d.translation())))
    return poses


class AbsolutePose(FactorType):
    name = "pose.absolute"
    summary = "absolute pose measurements of a robot (motion capture, GNSS+heading): native prior"
    robot_fields = ("robot",)
    stream_fields = ("stream",)
    accepts_repeated_stamps = ("stream",)  # each sample its own factor, paired by stamp
    schema = {"type": "object",
              "properties": {"robot": {"type": "string"}, "stream": {"type": "string"},
                             "sensor": {"type": "string"}, "sigma": SIGMA, "tolerance": TOLERANCE_SCHEMA},
              "required": ["robot", "stream", "sigma"], "additionalProperties": False}

    def check(self, spec: Spec, scope) -> None:
        check_pose_stream_entry(spec, scope)

    def build(self, ctx, spec: Spec) -> None:
        robot = spec["robot"]
        states = ctx.state_set(robot, spec)
        stream = ctx.stream(spec["stream"])
        assoc = ctx.associate(stream, robot, spec)
        planar = states.family.vartype is POSE2
        noise = ctx.noise(pose_sigmas(spec["sigma"], planar), spec)
        mount_inv = sensor_mount(ctx, spec).inverse()
        poses = poses_from_array(stream.pose_array()[assoc.row])
        for k, meas in zip(assoc.state, poses):
            body = meas.compose(mount_inv)
            key = ctx.pose_key(robot, int(k))
            factor = gtsam.PriorFactorPose2(key, to_pose2(body), noise) if planar else \
                gtsam.PriorFactorPose3(key, body, noise)
            ctx.add(factor, spec, ctx.state_time(robot, int(k)))

    def residual_parts(self, ctx, spec: Spec):
        return pose_parts(ctx.state_set(spec["robot"]).family.vartype is POSE2)

    @classmethod
    def example(cls, rng):
        x = gtsam.Pose3.Expmap(rng.normal(size=6))
        values = gtsam.Values()
        values.insert(0, x)
        return FactorExample(gtsam.PriorFactorPose3(0, x, gaussian([0.01] * 3 + [0.02] * 3)), values)


class OriginPrior(FactorType):
    name = "pose.origin"
    summary = "prior on a robot's first pose: fixes its base frame (default: identity)"
    robot_fields = ("robot",)
    schema = {"type": "object",
              "properties": {"robot": {"type": "string"}, "sigma": SIGMA,
                             "pose": {"type": "array", "items": {"type": "number"}, "minItems": 3, "maxItems": 7}},
              "required": ["robot", "sigma"], "additionalProperties": False}

    def check(self, spec: Spec, scope) -> None:
        scope.require_states(spec, "robot")

    def build(self, ctx, spec: Spec) -> None:
        robot = spec["robot"]
        vt = ctx.state_set(robot, spec).family.vartype
        try:
            pose = vt.from_list(spec["pose"]) if "pose" in spec.data else vt.zero()
        except ValueError as exc:
            raise spec.error("pose", f"{exc} for a {vt.name} state") from None
        key = ctx.pose_key(robot, 0)
        ctx.add(vt.prior(key, pose, ctx.noise(pose_sigmas(spec["sigma"], vt is POSE2), spec)), spec,
                ctx.state_time(robot, 0))
        ctx.set_initial(key, pose)

    @classmethod
    def example(cls, rng):
        return AbsolutePose.example(rng)


class RelativePose(FactorType):
    name = "pose.relative"
    summary = "odometry: relative pose between consecutive states from a pose stream (native between)"
    robot_fields = ("robot",)
    stream_fields = ("stream",)
    schema = {"type": "object",
              "properties": {"robot": {"type": "string"}, "stream": {"type": "string"},
                             "sensor": {"type": "string"}, "sigma": SIGMA,
                             "max_gap": {"type": "number", "exclusiveMinimum": 0}},
              "required": ["robot", "stream", "sigma"], "additionalProperties": False}

    def check(self, spec: Spec, scope) -> None:
        check_pose_stream_entry(spec, scope)

    def build(self, ctx, spec: Spec) -> None:
        robot = spec["robot"]
        states = ctx.state_set(robot)
        planar = states.family.vartype is POSE2
        noise = ctx.noise(pose_sigmas(spec["sigma"], planar), spec)
        ka, before, after = odometry_pairs(ctx, spec, robot)
        keys = ctx.state_keys(robot, np.column_stack([ka, ka + 1]).ravel())  # a, b, a, b, ...
        for a, b, pa, pb, t in zip(keys[::2], keys[1::2], before, after, states.t[ka + 1].tolist()):
            delta = pa.between(pb)
            factor = gtsam.BetweenFactorPose2(a, b, to_pose2(delta), noise) if planar else \
                gtsam.BetweenFactorPose3(a, b, delta, noise)
            ctx.add(factor, spec, t)

    def residual_parts(self, ctx, spec: Spec):
        return pose_parts(ctx.state_set(spec["robot"]).family.vartype is POSE2)

    @classmethod
    def example(cls, rng):
        xa, xb = (gtsam.Pose3.Expmap(rng.normal(size=6)) for _ in range(2))
        values = gtsam.Values()
        values.insert(0, xa)
        values.insert(1, xb)
        return FactorExample(gtsam.BetweenFactorPose3(0, 1, xa.between(xb), gaussian([0.01] * 6)), values)


class ScaledRelativePose(FactorType):
    name = "pose.scaled_relative"
    summary = ("monocular visual odometry: relative pose with an unknown scale shared by the sequence "
               "(thesis eq. 4.3); "
               "sigma.translation in the VO's own units")
    robot_fields = ("robot",)
    stream_fields = ("stream",)
    schema = {"type": "object",
              "properties": {"robot": {"type": "string"}, "stream": {"type": "string"},
                             "sensor": {"type": "string"}, "scale": {"type": "string"}, "sigma": SIGMA,
                             "max_gap": {"type": "number", "exclusiveMinimum": 0}},
              "required": ["robot", "stream", "scale", "sigma"], "additionalProperties": False}

    def check(self, spec: Spec, scope) -> None:
        scope.require_columns(spec, "stream", POSE_COLUMNS)
        scope.require_parameter(spec, "robot", "scale", "scalar")
        scope.require_states(spec, "robot", "pose3")
        check_sensor(spec, scope)
        if "sensor" in spec.data:
            mount = scope.robots[spec["robot"]].sensors[spec["sensor"]].mount
            if np.linalg.norm(mount.translation()) > 0:
                raise spec.error("sensor", "a scaled-odometry sensor must sit at the body origin (its "
                                 "mount may rotate but not translate): make the camera the body frame")

    def build(self, ctx, spec: Spec) -> None:
        robot = spec["robot"]
        scale = ctx.parameter(robot, spec["scale"])
        ka, before, after = odometry_pairs(ctx, spec, robot)
        keys = np.asarray(ctx.state_keys(robot, np.column_stack([ka, ka + 1]).ravel())).reshape(-1, 2)
        measured = np.array([pa.between(pb).matrix() for pa, pb in zip(before, after)]).reshape(-1, 4, 4)
        ctx.add_vectorized(SCALED_BETWEEN, np.column_stack([keys, np.full(len(keys), scale)]),
                           {"measured": measured}, pose_sigmas(spec["sigma"], False), spec,
                           ctx.state_set(robot).t[ka + 1])

    def baseline(self, ctx, spec: Spec, values) -> dict:
        """`visual_odometry`: the odometry alone, its increments at the estimated scale composed from the
        estimated first pose (dead reckoning; a gap of the stream adds no motion), at the states' times."""
        robot = spec["robot"]
        ka, before, after = odometry_pairs(ctx, spec, robot)
        if not len(ka):
            return {}
        scale = values.atDouble(ctx.parameter(robot, spec["scale"]))
        poses = dead_reckoned(values.atPose3(ctx.pose_key(robot, int(ka[0]))), before, after, scale)
        t = ctx.state_set(robot).t[np.concatenate([ka[:1], ka + 1])]
        return {"visual_odometry": Stream("visual_odometry", t, ("x", "y", "z"),
                                          np.array([p.translation() for p in poses]), f"{spec.label}: dead reckoning")}

    @classmethod
    def example(cls, rng):
        xa, xb = (gtsam.Pose3.Expmap(rng.normal(size=6)) for _ in range(2))
        s = float(rng.uniform(0.5, 3.0))
        d = xa.between(xb)
        values = gtsam.Values()
        values.insert(0, xa)
        values.insert(1, xb)
        values.insert(2, s)
        meas = gtsam.Pose3(d.rotation(), d.translation() / s)
        factor = vectorized_factor(SCALED_BETWEEN, gaussian([0.01] * 3 + [0.03] * 3), [0, 1, 2],
                                   {"measured": meas.matrix()[None]})
        return FactorExample(factor, values)


def co_registration_factor(xa: int, base: int, xb: int, z: gtsam.Pose3, noise) -> gtsam.CustomFactor:
    """One co-registration factor (residuals.co_registrations)."""
    return vectorized_factor(CO_REGISTRATION, noise, [xa, base, xb], {"z": z.matrix()[None]})




class CoRegistration(FactorType):
    name = "pose.co_registration"
    summary = ("robot-to-robot relative pose a_T_b: links two pose chains and estimates the transform "
               "between their base frames (thesis fig. 3.3)")
    robot_fields = ("robot", "other")
    stream_fields = ("stream",)
    schema = {"type": "object",
              "properties": {"robot": {"type": "string"}, "other": {"type": "string"},
                             "stream": {"type": "string"}, "sigma": SIGMA, "tolerance": TOLERANCE_SCHEMA,
                             "base_sigma": SIGMA},
              "required": ["robot", "other", "stream", "sigma"], "additionalProperties": False}

    def check(self, spec: Spec, scope) -> None:
        scope.require_columns(spec, "stream", POSE_COLUMNS)
        scope.require_states(spec, "robot", "pose3")
        scope.require_states(spec, "other", "pose3")
        if spec["robot"] == spec["other"]:
            raise spec.error("other", "must name a different robot than `robot`")

    def build(self, ctx, spec: Spec) -> None:
        a, b = spec["robot"], spec["other"]
        stream = ctx.stream(spec["stream"])
        assoc_a = ctx.associate(stream, a, spec)
        assoc_b = ctx.associate(stream, b, spec)
        rows = np.intersect1d(assoc_a.row, assoc_b.row)
        ka = dict(zip(assoc_a.row, assoc_a.state))
        kb = dict(zip(assoc_b.row, assoc_b.state))
        prior = pose_sigmas(spec["base_sigma"], False) if "base_sigma" in spec.data else None
        base = ctx.base_transform(b, a, prior)
        z = np.array([p.matrix() for p in poses_from_array(stream.pose_array()[rows])]).reshape(-1, 4, 4)
        keys = [[ctx.pose_key(a, int(ka[row])), base, ctx.pose_key(b, int(kb[row]))] for row in rows]
        times = [max(ctx.state_time(a, int(ka[row])), ctx.state_time(b, int(kb[row]))) for row in rows]
        ctx.add_vectorized(CO_REGISTRATION, np.asarray(keys, dtype=np.int64).reshape(-1, 3), {"z": z},
                           pose_sigmas(spec["sigma"], False), spec, times)

    @classmethod
    def example(cls, rng):
        xa, w, xb = (gtsam.Pose3.Expmap(rng.normal(size=6)) for _ in range(3))
        values = gtsam.Values()
        for k, p in enumerate((xa, w, xb)):
            values.insert(k, p)
        z = xa.between(w.compose(xb))
        return FactorExample(co_registration_factor(0, 1, 2, z, gaussian([0.01] * 3 + [0.02] * 3)), values)


class ParameterRandomWalk(FactorType):
    name = "parameter.random_walk"
    summary = "chains a time-varying parameter between consecutive states: native between, sigma*sqrt(dt)"
    robot_fields = ("robot",)
    schema = {"type": "object",
              "properties": {"robot": {"type": "string"}, "parameter": {"type": "string"},
                             "sigma": {"type": "number", "exclusiveMinimum": 0},
                             "every": {"type": "integer", "minimum": 1, "default": 1}},
              "required": ["robot", "parameter", "sigma"], "additionalProperties": False}

    def check(self, spec: Spec, scope) -> None:
        scope.require_parameter(spec, "robot", "parameter")
        scope.require_states(spec, "robot")
        if not scope.robots[spec["robot"]].parameters[spec["parameter"]].time_varying:
            raise spec.error("parameter", f"parameter {spec['parameter']!r} is not time-varying; set "
                             "`time_varying: true` in the robot description")

    def build(self, ctx, spec: Spec) -> None:
        """With `every: m` the parameter has a value at every m-th state only (k = 0, m, 2m, ...):
        the factors that use it must read it there (e.g. uwb.range's `bias_every`)."""
        robot, name = spec["robot"], spec["parameter"]
        param = ctx.robot(robot).parameters[name]
        states = ctx.state_set(robot, spec)
        ks = np.arange(0, len(states), spec["every"])
        dt = np.diff(states.t[ks])
        zero = param.vartype.zero()
        noises = {}
        for i in range(param.count):
            prev = ctx.parameter(robot, name, i, 0)
            for j in range(1, len(ks)):
                key = ctx.parameter(robot, name, i, int(ks[j]))
                step = round(float(dt[j - 1]), 9)
                if step not in noises:  # one noise model per distinct interval, not per factor
                    noises[step] = ctx.noise([spec["sigma"] * np.sqrt(step)] * param.vartype.dim, spec)
                ctx.add(param.vartype.between(prev, key, zero, noises[step]), spec, float(states.t[ks[j]]))
                prev = key

    @classmethod
    def example(cls, rng):
        values = gtsam.Values()
        a = float(rng.normal())
        values.insert(0, a)
        values.insert(1, a)
        return FactorExample(SCALAR.between(0, 1, 0.0, gaussian([0.1])), values)


FACTOR_TYPES = [AbsolutePose, OriginPrior, RelativePose, ScaledRelativePose, CoRegistration, ParameterRandomWalk]
