"""Rigid-cable factor types (docs/models/cable_rigid.md): cable length with encoder offset (thesis
eq. 4.1), elastic cable with measured tension (thesis eq. 4.2), and the pseudo-measurements on pulley geometry."""

from __future__ import annotations

from functools import partial

import gtsam
import numpy as np

from fusionkit.api import (cable_robot, FactorExample, FactorType, POSITIVE_SCHEMA as SIGMA, ResidualPart, Spec, Stream,
                           TOLERANCE_SCHEMA, gaussian, parameter_indices, pulley_cables, range_factor, vectorized_factor)

LENGTH_PART = [ResidualPart("length", "m", (0,))]  # a cable-length residual (m)

from .kinematics import forward_kinematics

from .residuals import along_normal_residual, elastic_cable_residual, plane_distance_residual

INDEX_LIST = {"type": "array", "items": {"type": "integer", "minimum": 0}, "minItems": 1}


def length_columns(spec: Spec, n: int) -> list[str]:
    """Stream columns of the cable lengths: `columns:` or l0 .. l{n-1}."""
    return list(spec.get("columns") or [f"l{i}" for i in range(n)])


def check_cdpr(spec: Spec, scope) -> int:
    """The robot must be a cdpr; returns its number of cables."""
    return cable_robot(scope.require_model(spec, "robot", "cdpr")).n


def check_cables(spec: Spec, key: str, n: int) -> None:
    bad = [i for i in spec.get(key, []) if i >= n]
    if bad:
        raise spec.error(key, f"cable index {bad[0]} out of range: the robot has cables 0..{n - 1}")


def attachment_offset(b: np.ndarray) -> gtsam.Pose3:
    return gtsam.Pose3(gtsam.Rot3(), np.asarray(b, float))


def pulley_offset_hint(self, spec: Spec, parameters: list[str]) -> str | None:
    """FactorType.separation_hint of the cable factors: a pulley moved along its cable and the cable's offset
    changed by as much give the same readings at every pose whose cable points the same way; only cable
    directions that vary tell them apart."""
    if parameter_indices(parameters, spec["robot"], "pulley") & parameter_indices(parameters, spec["robot"], "offset"):
        return ("to separate a pulley from its cable's offset: poses over a larger volume, moving across the "
                "cable directions (the cable's direction at the pulley must vary)")
    return None


class CableLength(FactorType):
    name = "cable.length"
    summary = ("rigid cable: encoder z_i = ||R b_i + t - a_i|| + l0_i (thesis eq. 4.1): native GTSAM range+bias "
               "factor; over a swivelling pulley of the description's pulley_radius, its length from a_i")
    robot_fields = ("robot",)
    stream_fields = ("stream",)
    accepts_repeated_stamps = ("stream",)  # each sample its own factor, paired by stamp
    schema = {"type": "object",
              "properties": {"robot": {"type": "string"}, "stream": {"type": "string"}, "sigma": SIGMA,
                             "columns": {"type": "array", "items": {"type": "string"}},
                             "cables": INDEX_LIST, "tolerance": TOLERANCE_SCHEMA},
              "required": ["robot", "stream", "sigma"], "additionalProperties": False}

    separation_hint = pulley_offset_hint  # what separates a pulley from its cable's offset

    def check(self, spec: Spec, scope) -> None:
        n = check_cdpr(spec, scope)
        scope.require_states(spec, "robot", "pose3")
        check_cables(spec, "cables", n)
        if "columns" in spec.data and len(spec["columns"]) != n:
            raise spec.error("columns", f"{len(spec['columns'])} columns named; the robot has {n} cables")
        scope.require_columns(spec, "stream", tuple(length_columns(spec, n)))

    def build(self, ctx, spec: Spec) -> None:
        robot = spec["robot"]
        cdpr = cable_robot(ctx.robot(robot))
        stream = ctx.stream(spec["stream"])
        assoc = ctx.associate(stream, robot, spec)
        noise = ctx.noise([spec["sigma"]], spec)
        columns = length_columns(spec, cdpr.n)
        for i in spec.get("cables", range(cdpr.n)):
            pulley, offset = ctx.parameter(robot, "pulley", i), ctx.parameter(robot, "offset", i)
            mount = attachment_offset(cdpr.attachments[i])
            z = stream.column(columns[i])[assoc.row]
            poses = [ctx.pose_key(robot, int(k)) for k in assoc.state]
            times = [ctx.state_time(robot, int(k)) for k in assoc.state]
            if cdpr.pulley_radius > 0:  # the cable leaves a swivelling pulley of that radius (pulley.py)
                keys = [[pose, pulley, offset] for pose in poses]
                add_cables(ctx, spec, cdpr, keys, [cdpr.attachments[i]] * len(keys), np.zeros(len(keys)), z,
                           np.full(len(keys), spec["sigma"]), times)
                continue
            for pose, zk, t in zip(poses, z, times):
                ctx.add(range_factor(pose, pulley, float(zk), noise, mount, offset), spec, t)

    def baseline(self, ctx, spec: Spec, values) -> dict:
        """`forward_kinematics`: the end-effector positions from this entry's encoder readings alone at the
        estimated pulleys and offsets (rigid straight cables, the end effector level as the kinematics
        assumes: thesis Table 4.1's FK column), at the readings' times; none with fewer than 3 cables."""
        robot = spec["robot"]
        cdpr = cable_robot(ctx.robot(robot))
        cables = list(spec.get("cables", range(cdpr.n)))
        if len(cables) < 3:
            return {}
        stream = ctx.stream(spec["stream"])
        rows = ctx.associate(stream, robot, spec).row
        columns = length_columns(spec, cdpr.n)
        pulleys = np.array([values.atPoint3(ctx.parameter(robot, "pulley", i)) for i in cables])
        offsets = np.array([values.atDouble(ctx.parameter(robot, "offset", i)) for i in cables])
        z = np.column_stack([stream.column(columns[i])[rows] for i in cables])
        positions, _ = forward_kinematics(pulleys, offsets, cdpr.attachments[cables], z)
        return {"forward_kinematics": Stream("forward_kinematics", stream.t[rows], ("x", "y", "z"), positions,
                                             f"{spec.label}: forward kinematics")}

    def diagnose(self, ctx, spec: Spec) -> None:
        """Observability of each cable's pulley and offset from this trajectory (thesis eqs. 4.6-4.7)."""
        from .observability import diagnose_cable_lengths
        diagnose_cable_lengths(ctx, spec)

    def residual_parts(self, ctx, spec: Spec):
        return LENGTH_PART

    @classmethod
    def example(cls, rng):
        """Half of the examples over a swivelling pulley of 3-8 cm (the attachment point 1-2 m below it)."""
        pose = gtsam.Pose3(gtsam.Rot3.Expmap(rng.normal(size=3) * 0.3), rng.normal(size=3))
        b, l0 = rng.normal(size=3) * 0.2, float(rng.normal())
        a = pose.transformFrom(b) + np.r_[rng.normal(size=2), rng.uniform(1.0, 2.0)]
        values = gtsam.Values()
        values.insert(0, pose)
        values.insert(1, a)
        values.insert(2, l0)
        if rng.random() < 0.5:
            z = float(np.linalg.norm(pose.transformFrom(b) - a)) + l0
            return FactorExample(gtsam.RangeFactorWithTransformBias3D(0, 1, 2, z, gaussian([0.001]),
                                                                      attachment_offset(b)), values)
        rho, axis = float(rng.uniform(0.03, 0.08)), np.array([0.0, 0.0, 1.0])
        z = float(pulley_cables(pose.transformFrom(b), a, rho, axis)[0][0]) + l0
        return FactorExample(elastic_cable_factor(0, 1, 2, b, 0.0, z, gaussian([0.001]), rho, axis), values)


def elastic_cable_factor(pose: int, pulley: int, offset: int, b, stretch: float, z: float, noise, rho: float = 0.0,
                         axis=None):
    """One factor e = (1 - stretch) l* + l0 - z (residuals.elastic_cables); stretch 0 is a rigid cable, and with
    a pulley radius `rho` the length runs over a pulley swivelling about `axis`."""
    data = {"attachment": np.asarray(b, float)[None], "stretch": np.array([stretch], float), "z": np.array([z], float)}
    return vectorized_factor(elastic_cable_residual(rho, axis), noise, [pose, pulley, offset], data)


def add_cables(ctx, spec: Spec, cdpr, keys, attachments, stretch, z, sigmas, times) -> None:
    """Elastic-cable factors (rows: pose, pulley, offset keys; attachment b; stretch; z; sigma; time) in one
    vectorized group."""
    ctx.add_vectorized(elastic_cable_residual(cdpr.pulley_radius, cdpr.swivel_axis), np.asarray(keys).reshape(-1, 3),
                       {"attachment": np.asarray(attachments, float).reshape(-1, 3),
                        "stretch": np.asarray(stretch, float), "z": np.asarray(z, float)},
                       np.asarray(sigmas, float).reshape(-1, 1), spec, times)


class ElasticCableLength(FactorType):
    name = "cable.elastic_length"
    summary = ("elastic cable with measured tension T_i: z_i = (1 - T_i/EA) l*_i + l0_i (thesis eq. 4.2); over "
               "swivelling pulleys when the description has a pulley_radius")
    robot_fields = ("robot",)
    stream_fields = ("stream", "tension_stream")
    schema = {"type": "object",
              "properties": {"robot": {"type": "string"}, "stream": {"type": "string"},
                             "tension_stream": {"type": "string"}, "sigma": SIGMA, "tension_sigma": SIGMA,
                             "columns": {"type": "array", "items": {"type": "string"}},
                             "tension_columns": {"type": "array", "items": {"type": "string"}},
                             "cables": INDEX_LIST, "tolerance": TOLERANCE_SCHEMA},
              "required": ["robot", "stream", "tension_stream", "sigma", "tension_sigma"],
              "additionalProperties": False}

    separation_hint = pulley_offset_hint

    def check(self, spec: Spec, scope) -> None:
        n = check_cdpr(spec, scope)
        scope.require_states(spec, "robot", "pose3")
        check_cables(spec, "cables", n)
        if cable_robot(scope.robots[spec["robot"]]).stiffness_EA is None:
            raise spec.error("robot", f"robot {spec['robot']!r} has no cables.stiffness_EA; elastic cables need it")
        scope.require_values(spec, "robot", "offset", "to scale the tension noise by the cable length")
        scope.require_columns(spec, "stream", tuple(length_columns(spec, n)))
        tcols = tuple(spec.get("tension_columns") or [f"T{i}" for i in range(n)])
        scope.require_columns(spec, "tension_stream", tcols)

    def build(self, ctx, spec: Spec) -> None:
        robot = spec["robot"]
        desc = ctx.robot(robot)
        cdpr = cable_robot(desc)
        lengths, tensions = ctx.stream(spec["stream"]), ctx.stream(spec["tension_stream"])
        a_len = ctx.associate(lengths, robot, spec)
        a_ten = ctx.associate(tensions, robot, spec)
        tension_row = dict(zip(a_ten.state, a_ten.row))
        columns = length_columns(spec, cdpr.n)
        tcols = spec.get("tension_columns") or [f"T{i}" for i in range(cdpr.n)]
        offsets = desc.parameters["offset"].values
        without = sum(k not in tension_row for k in a_len.state)
        if without:
            ctx.note(f"{spec.label}: {without} of {len(a_len.state)} length samples had no tension sample "
                             f"at their state and were not used")
        pairs = [(int(k), row) for k, row in zip(a_len.state, a_len.row) if k in tension_row]
        for i in spec.get("cables", range(cdpr.n)):
            pulley, offset = ctx.parameter(robot, "pulley", i), ctx.parameter(robot, "offset", i)
            z_all, t_all = lengths.column(columns[i]), tensions.column(tcols[i])
            z = np.array([z_all[row] for _, row in pairs], float)
            stretch = np.array([t_all[tension_row[k]] for k, _ in pairs], float) / cdpr.stiffness_EA
            # tension noise enters through the length: d e / d T = -l*/EA, with l* ~ z - l0
            sigma = np.hypot(spec["sigma"], (z - float(offsets[i])) / cdpr.stiffness_EA * spec["tension_sigma"])
            keys = [[ctx.pose_key(robot, k), pulley, offset] for k, _ in pairs]
            add_cables(ctx, spec, cdpr, keys, [cdpr.attachments[i]] * len(keys), stretch, z, sigma,
                       [ctx.state_time(robot, k) for k, _ in pairs])

    def residual_parts(self, ctx, spec: Spec):
        return LENGTH_PART

    @classmethod
    def example(cls, rng):
        pose = gtsam.Pose3.Expmap(rng.normal(size=6))
        b, a, l0 = rng.normal(size=3) * 0.2, rng.normal(size=3) * 3, float(rng.normal())
        stretch = float(rng.uniform(0.0, 0.01))
        rho, axis = (float(rng.uniform(0.03, 0.08)), np.array([0.0, 0.0, 1.0])) if rng.random() < 0.5 else (0.0, None)
        if rho:  # the attachment 1-2 m below the pulley
            a = pose.transformFrom(b) + np.r_[rng.normal(size=2), rng.uniform(1.0, 2.0)]
        z = (1 - stretch) * float(pulley_cables(pose.transformFrom(b), a, rho, axis if rho else np.ones(3))[0][0]) + l0
        values = gtsam.Values()
        values.insert(0, pose)
        values.insert(1, a)
        values.insert(2, l0)
        return FactorExample(elastic_cable_factor(0, 1, 2, b, stretch, z, gaussian([0.001]), rho, axis), values)


class PulleyDistance(FactorType):
    name = "cable.pulley_distance"
    summary = "pseudo-measurement: a taped distance between two pulleys, ||a_i - a_j|| = d (native range)"
    robot_fields = ("robot",)
    schema = {"type": "object",
              "properties": {"robot": {"type": "string"},
                             "pulleys": {"type": "array", "items": {"type": "integer", "minimum": 0},
                                         "minItems": 2, "maxItems": 2},
                             "distance": {"type": "number", "exclusiveMinimum": 0}, "sigma": SIGMA},
              "required": ["robot", "pulleys", "distance", "sigma"], "additionalProperties": False}

    def check(self, spec: Spec, scope) -> None:
        check_cables(spec, "pulleys", check_cdpr(spec, scope))

    def build(self, ctx, spec: Spec) -> None:
        i, j = spec["pulleys"]
        robot = spec["robot"]
        ctx.add(gtsam.RangeFactor3(ctx.parameter(robot, "pulley", i), ctx.parameter(robot, "pulley", j),
                                    float(spec["distance"]), ctx.noise([spec["sigma"]], spec)), spec)

    @classmethod
    def example(cls, rng):
        a, b = rng.normal(size=3) * 3, rng.normal(size=3) * 3
        values = gtsam.Values()
        values.insert(0, a)
        values.insert(1, b)
        return FactorExample(gtsam.RangeFactor3(0, 1, float(np.linalg.norm(a - b)), gaussian([0.005])), values)


def _plane_error(this, v: gtsam.Values, H) -> np.ndarray:
    return plane_distance_residual(*(v.atPoint3(k) for k in this.keys()), H)


def _normal_error(normal: np.ndarray, this, v: gtsam.Values, H) -> np.ndarray:
    k = this.keys()
    return along_normal_residual(v.atPoint3(k[0]), v.atPoint3(k[1]), normal, H)


class PulleysCoplanar(FactorType):
    name = "cable.pulleys_coplanar"
    summary = ("pseudo-measurement: pulleys on one plane; with `normal`, n.(a_j - a_i) = 0 (one wall); "
               "without, each pulley beyond the third lies on the plane of the first three")
    robot_fields = ("robot",)
    schema = {"type": "object",
              "properties": {"robot": {"type": "string"}, "pulleys": {**INDEX_LIST, "minItems": 2},
                             "normal": {"type": "array", "items": {"type": "number"}, "minItems": 3, "maxItems": 3},
                             "sigma": SIGMA},
              "required": ["robot", "pulleys", "sigma"], "additionalProperties": False}

    def check(self, spec: Spec, scope) -> None:
        check_cables(spec, "pulleys", check_cdpr(spec, scope))
        if "normal" not in spec.data and len(spec["pulleys"]) < 4:
            raise spec.error("pulleys", "without a known `normal`, coplanarity needs at least 4 pulleys")
        if "normal" in spec.data and np.linalg.norm(spec["normal"]) == 0:
            raise spec.error("normal", "expected a non-zero normal vector")

    def build(self, ctx, spec: Spec) -> None:
        robot = spec["robot"]
        keys = [ctx.parameter(robot, "pulley", i) for i in spec["pulleys"]]
        noise = ctx.noise([spec["sigma"]], spec)
        if "normal" in spec.data:
            n = np.asarray(spec["normal"], float)
            n /= np.linalg.norm(n)
            for kj in keys[1:]:
                ctx.add(gtsam.CustomFactor(noise, [keys[0], kj], partial(_normal_error, n)), spec)
        else:
            for kk in keys[3:]:
                ctx.add(gtsam.CustomFactor(noise, keys[:3] + [kk], _plane_error), spec)

    @classmethod
    def example(cls, rng):
        pts = [rng.normal(size=3) * 3 for _ in range(3)]
        u, v = pts[1] - pts[0], pts[2] - pts[0]
        pts.append(pts[0] + 0.3 * u + 0.6 * v)  # on the plane
        values = gtsam.Values()
        for k, p in enumerate(pts):
            values.insert(k, p)
        return FactorExample(gtsam.CustomFactor(gaussian([0.01]), [0, 1, 2, 3], _plane_error), values)


FACTOR_TYPES = [CableLength, ElasticCableLength, PulleyDistance, PulleysCoplanar]
