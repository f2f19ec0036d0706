"""`cable.catenary`: cable lengths with sag at measured poses (docs/models/cable_sag.md#sag-from-the-measured-pose).

One factor per pose with all n cables, residual (n,) (m):  e_i = l_i(X, a, w) + l0_i - z_i,  l_i the catenary arc
length of measured_geometry.catenary_lengths at the pose X itself (no orientation of the statics' own), over X,
the n pulleys, the n offsets and, with `weight:`, the cables' weight per length w (a scalar robot parameter, N/m;
else the description's `cables.weight_per_length`, held). With w = 0 it is the rigid `cable.length` residual
exactly. Jacobians are central differences of the vectorized residual (fusionkit's numerical option).
"""

from __future__ import annotations

import gtsam
import numpy as np

from fusionkit.api import (NAME_SCHEMA, POINT3, POSE3, POSITIVE_SCHEMA, SCALAR, TOLERANCE_SCHEMA, FactorExample,
                           FactorType, ResidualPart, Spec, VectorizedResidual, cable_robot, gaussian, vectorized_factor)

from .measured_geometry import catenary_lengths
from .model import length_columns
from .statics import SagRobot


def catenary_residual(robot, n: int, estimated_weight: bool) -> VectorizedResidual:
    """The residual of one robot's entry: variables [pose, pulley_0..n-1, offset_0..n-1 (, w)]; data z (N, n) and,
    without an estimated weight, w (N,)."""
    def function(x, data, jacobians):
        poses = x[0]
        pulleys = np.stack(x[1:1 + n], axis=1)
        offsets = np.column_stack(x[1 + n:1 + 2 * n])
        w = x[1 + 2 * n] if estimated_weight else data["w"]
        lengths = catenary_lengths(poses[:, :3, :3], poses[:, :3, 3], pulleys, robot.attachments, robot.com,
                                   robot.weight, w)
        return lengths + offsets - data["z"]

    variables = (POSE3,) + (POINT3,) * n + (SCALAR,) * n + ((SCALAR,) if estimated_weight else ())
    return VectorizedResidual("cable.catenary", variables, n, function, jacobians="numerical")


class CatenaryCable(FactorType):
    name = "cable.catenary"
    summary = ("sagging cables at measured poses: catenary arc length + offset = encoder, the catenary through pulley "
               "and attachment with the forces of the end-effector's statics at that pose; w = 0 is cable.length")
    robot_fields = ("robot",)
    stream_fields = ("stream",)
    accepts_repeated_stamps = ("stream",)
    schema = {"type": "object",
              "properties": {"robot": NAME_SCHEMA, "stream": NAME_SCHEMA, "sigma": POSITIVE_SCHEMA,
                             "weight": NAME_SCHEMA, "columns": {"type": "array", "items": NAME_SCHEMA},
                             "tolerance": TOLERANCE_SCHEMA},
              "required": ["robot", "stream", "sigma"], "additionalProperties": False}

    def residual_parts(self, ctx, spec: Spec) -> list[ResidualPart]:
        n = cable_robot(ctx.robot(spec["robot"])).n
        return [ResidualPart("length", "m", tuple(range(n)))]

    def check(self, spec: Spec, scope) -> None:
        """A `cdpr` robot with an end-effector mass, a cable weight (or a `weight` parameter), no pulley radius."""
        desc = scope.require_model(spec, "robot", "cdpr")
        robot = cable_robot(desc)
        if robot.mass is None:
            raise spec.error("robot", f"robot {spec['robot']!r} has no end_effector.mass (kg) or end_effector.weight "
                             "(N): the forces that shape the catenaries come from it")
        if "weight" in spec.data:
            scope.require_parameter(spec, "robot", "weight", "scalar")
        elif robot.weight_per_length is None:
            raise spec.error("robot", f"robot {spec['robot']!r} has no cables.weight_per_length (N/m): give it, or "
                             "name a scalar parameter with `weight:` to estimate it")
        if robot.pulley_radius > 0:
            raise spec.error("robot", f"robot {spec['robot']!r} has cables.pulley_radius {robot.pulley_radius:g} m: "
                             "the catenary starts at a fixed exit point (the pulley parameter); remove it, or use "
                             "cable.length, which models swivelling pulleys")
        scope.require_states(spec, "robot", "pose3")
        scope.require_columns(spec, "stream", tuple(length_columns(spec, robot.n)))

    def build(self, ctx, spec: Spec) -> None:
        name = spec["robot"]
        cdpr = cable_robot(ctx.robot(name))
        n = cdpr.n
        robot = SagRobot(cdpr.attachments, cdpr.com, cdpr.gravity * float(cdpr.mass), float(cdpr.weight_per_length or 0.0))
        stream = ctx.stream(spec["stream"])
        assoc = ctx.associate(stream, name, spec)
        z = np.column_stack([stream.column(c) for c in length_columns(spec, n)])[assoc.row]
        shared = [ctx.parameter(name, "pulley", i) for i in range(n)] + [ctx.parameter(name, "offset", i)
                                                                          for i in range(n)]
        estimated = "weight" in spec.data
        if estimated:
            shared.append(ctx.parameter(name, spec["weight"]))
        keys = [[ctx.pose_key(name, int(k))] + shared for k in assoc.state]
        data = {"z": z} if estimated else {"z": z, "w": np.full(len(z), robot.cable_weight)}
        ctx.add_vectorized(catenary_residual(robot, n, estimated), np.asarray(keys, dtype=np.int64).reshape(-1, len(shared) + 1),
                           data, [float(spec["sigma"])] * n, spec, [ctx.state_time(name, int(k)) for k in assoc.state])

    @classmethod
    def example(cls, rng):
        """cdpr_small (light cables) at a random pose in its workspace hanging in equilibrium, consistent lengths,
        the weight per length estimated."""
        from .model import shipped_robot
        from .static_solver import inverse_pose
        robot, pulleys = shipped_robot("cdpr_small")
        pose = inverse_pose(rng.uniform([-0.5, -3.0, -12.0], [1.0, 0.0, -3.0]), pulleys, robot, yaw=rng.normal(0, 0.02))
        X = gtsam.Pose3(gtsam.Rot3(pose.R), pose.t)
        offsets = rng.normal(size=robot.n)
        w = robot.cable_weight
        lengths = catenary_lengths(pose.R[None], pose.t[None], pulleys[None], robot.attachments, robot.com, robot.weight,
                                   np.array([w]))[0]
        values = gtsam.Values()
        values.insert(0, X)
        for i in range(robot.n):
            values.insert(1 + i, pulleys[i])
            values.insert(1 + robot.n + i, float(offsets[i]))
        values.insert(1 + 2 * robot.n, float(w))
        keys = list(range(2 + 2 * robot.n))
        factor = vectorized_factor(catenary_residual(robot, robot.n, True), gaussian([1.0] * robot.n), keys,
                                   {"z": (lengths + offsets)[None]})
        return FactorExample(factor, values, perturbation=0.003)


FACTOR_TYPES = [CatenaryCable]
