"""Factor types of the UWB plugin (models: docs/models/uwb.md).

`uwb.range`: two-way range from a tag (a sensor of the robot: its mount is the lever arm) to an
anchor (a point parameter of an anchors description), z = (1 + alpha) ||X b - a|| + beta + w.
beta is a robot parameter indexed per anchor -- constant (level 1) or `time_varying: true` and
chained by `parameter.random_walk` (level 2); alpha (`scale:`) is optional. Without alpha this is
the rigid-cable model, built by the same native GTSAM factor (fusionkit.geometry.range_factor).
`uwb.tag_range`: a range between tags on two robots (multi-robot).
Wheel odometry and the constant-velocity prior that UWB configs use are the pose plugin's
(`odometry.diff_drive`, `motion.constant_velocity`).
"""

from __future__ import annotations

from functools import partial

import gtsam
import numpy as np

from fusionkit.api import (FactorExample, FactorType, NAME_SCHEMA as NAME, POINT2, POINT3, POSE2,
                           POSITIVE_SCHEMA as SIGMA, ResidualPart, Spec, TOLERANCE_SCHEMA, gaussian, range_factor,
                           vectorized_factor)

RANGE_PART = [ResidualPart("range", "m", (0,))]  # a range residual (m)

from .residuals import TAG_RANGES, scaled_range_residual

ANCHOR_PARAMETER = {**NAME, "default": "anchor"}  # the anchors' point parameter
RANGE_COLUMN = {**NAME, "default": "range"}       # with `anchor_column`: the ranges' column


SCALE_NOTE = 0.01  # a range scale error beyond 1 % that the biases took is named in the report


def lever_arm(desc, sensor: str | None) -> np.ndarray:
    """The tag's position on the body (m): its sensor mount's translation (origin without a tag)."""
    return np.zeros(3) if sensor is None else np.asarray(desc.sensors[sensor].mount.translation(), float)


def planar_mount(b: np.ndarray) -> gtsam.Pose2:
    return gtsam.Pose2(float(b[0]), float(b[1]), 0.0)


def _scaled_error(b: np.ndarray, z: float, has_bias: bool, has_scale: bool, planar: bool, planar_anchor: bool,
                  this, v: gtsam.Values, H):
    keys = this.keys()
    pose = v.atPose2(keys[0]) if planar else v.atPose3(keys[0])
    anchor = np.asarray(v.atPoint2(keys[1]) if planar_anchor else v.atPoint3(keys[1]), float)
    bias = v.atDouble(keys[2]) if has_bias else 0.0
    alpha = v.atDouble(keys[2 + has_bias]) if has_scale else 0.0
    J = [None] * 4 if H is not None else None
    e = scaled_range_residual(pose, anchor, bias, alpha, b, z, J)
    if H is not None:
        H[0], H[1] = J[0], J[1]
        if has_bias:
            H[2] = J[2]
        if has_scale:
            H[2 + has_bias] = J[3]
    return e


def scaled_range_factor(pose: int, anchor: int, bias: int | None, scale: int | None, b, z: float, noise,
                        planar: bool = False, planar_anchor: bool = False):
    """z = (1 + alpha) ||X b - a|| + beta; pose Pose2 (`planar`) or Pose3, anchor Point3 or Point2
    (`planar_anchor`: a planar world) (CustomFactor)."""
    keys = [pose, anchor] + ([bias] if bias is not None else []) + ([scale] if scale is not None else [])
    return gtsam.CustomFactor(noise, keys, partial(_scaled_error, np.asarray(b, float), float(z),
                                                   bias is not None, scale is not None, planar, planar_anchor))


def tag_range_factor(a: int, b: int, b_a, b_b, z: float, noise, planar: bool):
    """One tag-to-tag range factor (residuals.tag_ranges)."""
    data = {"tag_a": np.asarray(b_a, float)[None], "tag_b": np.asarray(b_b, float)[None], "z": np.array([z], float)}
    return vectorized_factor(TAG_RANGES[planar], noise, [a, b], data)


def _range_rows(stream, spec: Spec, n: int):
    """(row, anchor index, range) of every measurement in the stream: long format (`anchor_column`
    with ids, `range_column`) or wide (`columns`, one per anchor; a non-positive value: no range)."""
    if "anchor_column" in spec.data:
        ids = list(spec.get("ids", range(n)))
        ranges = stream.column(spec["range_column"])
        out = []
        for row, anchor_id in enumerate(stream.column(spec["anchor_column"])):
            if anchor_id not in ids:
                raise spec.error("ids", f"stream {stream.name!r} row {row + 1} names anchor {anchor_id:g}, which "
                                 f"`ids` does not list ({', '.join(f'{i:g}' for i in ids)})")
            out.append((row, ids.index(anchor_id), float(ranges[row])))
        return out
    columns = spec.get("columns") or [f"r{i}" for i in range(n)]
    values = np.column_stack([stream.column(c) for c in columns])
    return [(row, i, float(values[row, i])) for row in range(len(values)) for i in range(n) if values[row, i] > 0]


class UwbRange(FactorType):
    name = "uwb.range"
    summary = ("UWB two-way range tag -> anchor: z = (1 + alpha) ||R b + t - a|| + beta (bias constant or "
               "time-varying per anchor; native GTSAM range+bias factor without alpha)")
    robot_fields = ("robot", "anchors")
    stream_fields = ("stream",)
    accepts_repeated_stamps = ("stream",)  # each sample its own factor, paired by stamp
    schema = {"type": "object",
              "properties": {"robot": NAME, "stream": NAME, "anchors": NAME, "anchor_parameter": ANCHOR_PARAMETER,
                             "tag": NAME, "bias": NAME, "scale": NAME, "sigma": SIGMA,
                             "bias_every": {"type": "integer", "minimum": 1, "default": 1},
                             "anchor_column": NAME, "range_column": RANGE_COLUMN,
                             "ids": {"type": "array", "items": {"type": "number"}, "minItems": 1},
                             "columns": {"type": "array", "items": NAME, "minItems": 1},
                             "tolerance": TOLERANCE_SCHEMA},
              "required": ["robot", "stream", "anchors", "sigma"], "additionalProperties": False}

    def check(self, spec: Spec, scope) -> None:
        scope.require_states(spec, "robot")
        anchors = scope.robots[spec["anchors"]]
        param = spec["anchor_parameter"]
        if param not in anchors.parameters:
            raise spec.error("anchors", f"robot {spec['anchors']!r} has no parameter {param!r} (the anchor points)")
        vartype = anchors.parameters[param].vartype
        if vartype not in (POINT2, POINT3):
            raise spec.error("anchors", f"{spec['anchors']}/{param} is {vartype.name}; expected point3 (or point2 for "
                             "planar robots)")
        n = anchors.parameters[param].count
        robot = scope.robots[spec["robot"]]
        if "tag" in spec.data and spec["tag"] not in robot.sensors:
            raise spec.error("tag", f"robot {spec['robot']!r} has no sensor {spec['tag']!r}; sensors: "
                             f"{', '.join(robot.sensors) or '(none)'}")
        for key in ("bias", "scale"):
            if key in spec.data:
                scope.require_parameter(spec, "robot", key, "scalar")
        if "bias" in spec.data and robot.parameters[spec["bias"]].count != n:
            raise spec.error("bias", f"{spec['robot']}/{spec['bias']} has {robot.parameters[spec['bias']].count} "
                             f"value(s); expected one per anchor ({n})")
        if "anchor_column" in spec.data:
            scope.require_columns(spec, "stream", (spec["anchor_column"], spec["range_column"]))
        else:
            columns = spec.get("columns") or [f"r{i}" for i in range(n)]
            if len(columns) != n:
                raise spec.error("columns", f"{len(columns)} columns named; there are {n} anchors")
            scope.require_columns(spec, "stream", tuple(columns))

    def build(self, ctx, spec: Spec) -> None:
        robot, anchors = spec["robot"], spec["anchors"]
        param = spec["anchor_parameter"]
        desc = ctx.robot(robot)
        anchor_type = ctx.robot(anchors).parameters[param].vartype
        n = ctx.robot(anchors).parameters[param].count
        states = ctx.state_set(robot, spec)
        planar = states.family.vartype is POSE2
        b = lever_arm(desc, spec.get("tag"))
        stream = ctx.stream(spec["stream"])
        assoc = ctx.associate(stream, robot, spec)
        state_of = dict(zip(assoc.row, assoc.state))
        noise = ctx.noise([spec["sigma"]], spec)
        native = "scale" not in spec.data and (planar == (anchor_type is POINT2))
        if anchor_type is POINT2 and not planar:
            raise spec.error("anchors", "2-D anchors (point2) need a planar robot (states type pose2)")
        mount = planar_mount(b) if planar else gtsam.Pose3(gtsam.Rot3(), b)
        every = spec["bias_every"]  # a time-varying bias held over `every` states (parameter.random_walk every:)
        for row, i, z in _range_rows(stream, spec, n):
            if row not in state_of:
                continue  # counted by ctx.associate
            k = int(state_of[row])
            pose, anchor = ctx.pose_key(robot, k), ctx.parameter(anchors, param, i)
            held = ctx.state_index(robot, k)  # a measurement-time state (time_offset:) holds its nearest state's bias
            bias = ctx.parameter(robot, spec["bias"], i, held - held % every) if "bias" in spec.data else None
            if native:
                factor = range_factor(pose, anchor, z, noise, mount, bias)
            else:
                scale = ctx.parameter(robot, spec["scale"], None, k) if "scale" in spec.data else None
                factor = scaled_range_factor(pose, anchor, bias, scale, b, z, noise, planar, anchor_type is POINT2)
            ctx.add(factor, spec, ctx.state_time(robot, k))

    def review(self, ctx, spec: Spec, values) -> list[str]:
        """Biases that grow with range: at the estimate, each range's bias (the estimated one plus its
        residual) fitted as a constant per anchor plus s times the range; |s| above SCALE_NOTE and 5 of its
        sigmas is a scale error (ranges (1 + s) too long) that the biases took, and the note says how to
        estimate it. Only for entries with `bias:`, without `scale:` or `time_offset:`."""
        if "bias" not in spec.data or "scale" in spec.data or "time_offset" in spec.data:
            return []
        states = ctx.state_set(spec["robot"], spec)
        planar = states.family.vartype is POSE2
        b = lever_arm(ctx.robot(spec["robot"]), spec.get("tag"))
        read_pose = values.atPose2 if planar else values.atPose3
        anchor_type = ctx.robot(spec["anchors"]).parameters[spec["anchor_parameter"]].vartype
        read_anchor = values.atPoint2 if anchor_type is POINT2 else values.atPoint3
        rows = []
        for factor in ctx.factors(label=spec.label):
            pose_key, anchor_key, bias_key = factor.keys()
            tag = np.asarray(read_pose(pose_key).transformFrom(b[:2] if planar else b))
            point = np.asarray(read_anchor(anchor_key))
            d = float(np.linalg.norm(tag - point[:len(tag)]))
            rows.append((anchor_key, d, values.atDouble(bias_key) - float(factor.unwhitenedError(values)[0])))
        anchors = sorted({a for a, _, _ in rows})
        if len(rows) < len(anchors) + 10:
            return []
        column = {a: i for i, a in enumerate(anchors)}
        A = np.column_stack([np.eye(len(anchors))[[column[a] for a, _, _ in rows]], [d for _, d, _ in rows]])
        y = np.array([bias for _, _, bias in rows])
        coef, *_ = np.linalg.lstsq(A, y, rcond=None)
        resid = y - A @ coef
        sigma = float(np.sqrt(max(np.linalg.pinv(A.T @ A)[-1, -1] * (resid @ resid) / (len(y) - A.shape[1]), 0.0)))
        scale = float(coef[-1])
        if abs(scale) <= SCALE_NOTE or abs(scale) <= 5 * sigma:
            return []
        return [f"{spec.label}: the range biases grow with distance, by {100 * scale:+.1f} % (+-{100 * sigma:.1f}) of "
                f"the range beyond a constant per anchor ({len(y)} ranges at the estimate): a scale error rather than "
                f"a bias -- estimate it with `scale:` (a scalar parameter of robot {spec['robot']!r}, e.g. "
                "uwb_scale: {value: 0.0, sigma: 0.1})"]

    def residual_parts(self, ctx, spec: Spec):
        return RANGE_PART

    @classmethod
    def example(cls, rng):
        pose = gtsam.Pose3(gtsam.Rot3.Expmap(rng.normal(size=3) * 0.3), rng.normal(size=3))
        b, a = rng.normal(size=3) * 0.2, rng.normal(size=3) * 5
        bias, alpha = float(rng.normal() * 0.1), float(rng.normal() * 0.01)
        z = (1 + alpha) * float(np.linalg.norm(pose.transformFrom(b) - a)) + bias
        values = gtsam.Values()
        values.insert(0, pose)
        values.insert(1, a)
        values.insert(2, bias)
        values.insert(3, alpha)
        return FactorExample(scaled_range_factor(0, 1, 2, 3, b, z, gaussian([0.05])), values)


class UwbTagRange(FactorType):
    name = "uwb.tag_range"
    summary = "UWB range between tags on two robots: z = ||X_a b_a - X_b b_b|| (multi-robot)"
    robot_fields = ("robot", "other")
    stream_fields = ("stream",)
    accepts_repeated_stamps = ("stream",)  # each sample its own factor, paired by stamp
    schema = {"type": "object",
              "properties": {"robot": NAME, "other": NAME, "stream": NAME, "tag": NAME, "other_tag": NAME,
                             "column": RANGE_COLUMN, "sigma": SIGMA, "tolerance": TOLERANCE_SCHEMA},
              "required": ["robot", "other", "stream", "sigma"], "additionalProperties": False}

    def check(self, spec: Spec, scope) -> None:
        scope.require_states(spec, "robot")
        scope.require_states(spec, "other")
        scope.require_columns(spec, "stream", (spec["column"],))

    def build(self, ctx, spec: Spec) -> None:
        a, b = spec["robot"], spec["other"]
        planar = ctx.state_set(a, spec).family.vartype is POSE2
        if planar != (ctx.state_set(b, spec).family.vartype is POSE2):
            raise spec.error("other", f"robots {a!r} and {b!r} must both be planar (pose2) or both pose3")
        b_a, b_b = lever_arm(ctx.robot(a), spec.get("tag")), lever_arm(ctx.robot(b), spec.get("other_tag"))
        stream = ctx.stream(spec["stream"])
        assoc_a, assoc_b = ctx.associate(stream, a, spec), ctx.associate(stream, b, spec)
        state_b = dict(zip(assoc_b.row, assoc_b.state))
        z = stream.column(spec["column"])
        pairs = [(int(ka), int(state_b[row]), row) for row, ka in zip(assoc_a.row, assoc_a.state) if row in state_b]
        keys = [[ctx.pose_key(a, ka), ctx.pose_key(b, kb)] for ka, kb, _ in pairs]
        n = len(pairs)
        ctx.add_vectorized(TAG_RANGES[planar], np.asarray(keys, dtype=np.int64).reshape(n, 2),
                           {"tag_a": np.tile(b_a, (n, 1)), "tag_b": np.tile(b_b, (n, 1)),
                            "z": np.array([z[row] for _, _, row in pairs], float)},
                           [spec["sigma"]], spec,
                           [max(ctx.state_time(a, ka), ctx.state_time(b, kb)) for ka, kb, _ in pairs])

    def residual_parts(self, ctx, spec: Spec):
        return RANGE_PART

    @classmethod
    def example(cls, rng):
        planar = bool(rng.random() < 0.5)
        b_a, b_b = rng.normal(size=3) * 0.2, rng.normal(size=3) * 0.2
        if planar:
            pa, pb = (gtsam.Pose2(*rng.normal(size=2) * 3, rng.uniform(-3, 3)) for _ in range(2))
            position = lambda p, b: np.r_[p.transformFrom(b[:2]), b[2]]  # noqa: E731
        else:
            pa, pb = (gtsam.Pose3(gtsam.Rot3.Expmap(rng.normal(size=3) * 0.3), rng.normal(size=3) * 3) for _ in range(2))
            position = lambda p, b: p.transformFrom(b)  # noqa: E731
        z = float(np.linalg.norm(position(pa, b_a) - position(pb, b_b)))
        values = gtsam.Values()
        values.insert(0, pa)
        values.insert(1, pb)
        return FactorExample(tag_range_factor(0, 1, b_a, b_b, z, gaussian([0.05]), planar), values)


FACTOR_TYPES = [UwbRange, UwbTagRange]
