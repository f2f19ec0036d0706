"""`cable.catenary` and `cable.statics`: cables with sag at measured poses
(docs/models/cable_sag.md#sag-from-the-measured-pose), both through measured_geometry.hanging at the pose X itself.

- `cable.catenary`, one factor per pose with all n cables, residual (n,) (m): e_i = l_i + l0_i - z_i, l_i the
  catenary arc length from pulley i to the attachment of X; over X, the n pulleys and the n offsets. With weight
  per length 0 it is the rigid `cable.length` residual exactly.
- `cable.statics`, optional, one factor per pose, residual (6,): the wrench [N; N m] the cables' pulls leave
  unbalanced against the end-effector's weight -- the force and moment balance as a constraint of its own noise
  (`sigma: {force, moment}`), which ties the measured orientation, the pulleys and the centre of mass; over X and
  the n pulleys.

Both may estimate what shapes the catenaries: `weight:` (a scalar robot parameter, the cables' weight per length,
N/m), `mass:` (scalar, the end-effector's mass, kg) and `com:` (point3, its centre of mass, m, body frame), each a
variable of every factor of the entry with the description's prior; what is not named is the description's value,
held. Jacobians are central differences of the vectorized residual.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import gtsam
import numpy as np

from fusionkit.api import (NAME_SCHEMA, POINT3, POSE3, POSITIVE_SCHEMA, SCALAR, TOLERANCE_SCHEMA, FactorExample,
                           FactorType, ResidualPart, Spec, VectorizedResidual, cable_robot, gaussian,
                           robot_description_data, vectorized_factor)

from .measured_geometry import hanging
from .model import length_columns, refuse_pulley_radius, shipped_robot
from .static_solver import inverse_pose

ESTIMABLE = {"weight": SCALAR, "mass": SCALAR, "com": POINT3}  # entry key -> the parameter's type
ESTIMABLE_SCHEMA = {key: NAME_SCHEMA for key in ESTIMABLE}
DETECTABLE = 2.0  # sigmas from zero a weight per length must be for the sag to count as seen in the data


@dataclass(frozen=True)
class Hanging:
    """What one entry's residual reads: the robot's attachments (n, 3), gravity (m/s^2), the description's weight
    per length (N/m), mass (kg) and centre of mass (3,) for what it holds, and which of them are variables
    (`estimated`, in ESTIMABLE order), after the pose, the n pulleys and (`offsets`) the n offsets."""

    attachments: np.ndarray
    gravity: float
    weight_per_length: float
    mass: float
    com: np.ndarray
    estimated: tuple[str, ...]
    offsets: bool

    @property
    def n(self) -> int:
        return len(self.attachments)

    def variables(self) -> tuple:
        return ((POSE3,) + (POINT3,) * self.n + ((SCALAR,) * self.n if self.offsets else ())
                + tuple(ESTIMABLE[k] for k in self.estimated))

    def evaluate(self, x: list[np.ndarray]):
        """(lengths (N, n), unbalanced wrench (N, 6), offsets (N, n) or None) at the variables x."""
        n = self.n
        poses, pulleys = x[0], np.stack(x[1:1 + n], axis=1)
        at = 1 + n
        offsets = None
        if self.offsets:
            offsets, at = np.column_stack(x[at:at + n]), at + n
        given = dict(zip(self.estimated, x[at:]))
        w = given.get("weight", self.weight_per_length)
        weight = self.gravity * np.asarray(given.get("mass", self.mass), float)
        com = given.get("com", self.com)
        hung = hanging(poses[:, :3, :3], poses[:, :3, 3], pulleys, self.attachments, com, weight, w)
        return hung.lengths, hung.unbalanced, offsets


def hanging_of(ctx, spec: Spec, offsets: bool) -> Hanging:
    cdpr = cable_robot(ctx.robot(spec["robot"]))
    return Hanging(cdpr.attachments, cdpr.gravity, float(cdpr.weight_per_length or 0.0), float(cdpr.mass or 0.0),
                   np.asarray(cdpr.com, float), tuple(k for k in ESTIMABLE if k in spec.data), offsets)


def length_residual(model: Hanging) -> VectorizedResidual:
    """cable.catenary's residual; data z (N, n)."""
    def function(x, data, jacobians):
        lengths, _, offsets = model.evaluate(x)
        return lengths + offsets - data["z"]
    return VectorizedResidual("cable.catenary", model.variables(), model.n, function, jacobians="numerical")


def statics_residual(model: Hanging) -> VectorizedResidual:
    """cable.statics' residual: the unbalanced wrench (N, 6)."""
    def function(x, data, jacobians):
        return model.evaluate(x)[1]
    return VectorizedResidual("cable.statics", model.variables(), 6, function, jacobians="numerical")


def check_hanging(spec: Spec, scope) -> int:
    """A `cdpr` robot with an end-effector mass, a cable weight (or a `weight` parameter), no pulley radius; the named
    parameters of the right type; pose3 states. Returns the number of cables."""
    desc = scope.require_model(spec, "robot", "cdpr")
    robot = cable_robot(desc)
    if robot.mass is None and "mass" not in spec.data:
        raise spec.error("robot", f"robot {spec['robot']!r} has no end_effector.mass (kg) or end_effector.weight (N): "
                         "the forces that shape the catenaries come from it (or name a `mass` parameter)")
    if robot.weight_per_length is None and "weight" not in spec.data:
        raise spec.error("robot", f"robot {spec['robot']!r} has no cables.weight_per_length (N/m): give it, or name "
                         "a scalar parameter with `weight:` to estimate it")
    refuse_pulley_radius(spec, robot)
    for key, vartype in ESTIMABLE.items():
        if key in spec.data:
            scope.require_parameter(spec, "robot", key, vartype.name)
    scope.require_states(spec, "robot", "pose3")
    return robot.n


def _keys(ctx, spec: Spec, model: Hanging, states) -> np.ndarray:
    name = spec["robot"]
    shared = [ctx.parameter(name, "pulley", i) for i in range(model.n)]
    if model.offsets:
        shared += [ctx.parameter(name, "offset", i) for i in range(model.n)]
    shared += [ctx.parameter(name, spec[key]) for key in model.estimated]
    return np.asarray([[ctx.pose_key(name, int(k))] + shared for k in states], dtype=np.int64).reshape(-1, len(shared) + 1)


class CatenaryCable(FactorType):
    name = "cable.catenary"
    summary = ("sagging cables at measured poses: catenary arc length + offset = encoder, the catenary through pulley "
               "and attachment with the forces of the end-effector's statics at that pose; weight 0 is cable.length")
    robot_fields = ("robot",)
    stream_fields = ("stream",)
    accepts_repeated_stamps = ("stream",)
    schema = {"type": "object",
              "properties": {"robot": NAME_SCHEMA, "stream": NAME_SCHEMA, "sigma": POSITIVE_SCHEMA,
                             "columns": {"type": "array", "items": NAME_SCHEMA}, "tolerance": TOLERANCE_SCHEMA,
                             **ESTIMABLE_SCHEMA},
              "required": ["robot", "stream", "sigma"], "additionalProperties": False}

    def residual_parts(self, ctx, spec: Spec) -> list[ResidualPart]:
        return [ResidualPart("length", "m", tuple(range(cable_robot(ctx.robot(spec["robot"])).n)))]

    def review(self, ctx, spec: Spec, values) -> list[str]:
        """With the weight per length estimated: whether the data support sag at all (the estimate more than two
        sigmas from zero), in one sentence."""
        if "weight" not in spec.data:
            return []
        key = ctx.parameter(spec["robot"], spec["weight"])
        sigma = ctx.sigma(key)
        if sigma is None:
            return []
        w, s = values.atDouble(key), float(sigma[0])
        if abs(w) < DETECTABLE * s:
            return [f"{spec.label}: sag not detectable: the cables' weight per length {w:.3g} +- {s:.2g} N/m is within "
                    f"{DETECTABLE:g} sigmas of zero; straight cables (cable.length) explain these lengths as well"]
        return [f"{spec.label}: sag detected: the cables' weight per length is {w:.3g} +- {s:.2g} N/m "
                f"({abs(w) / s:.1f} sigmas from zero)"]

    def check(self, spec: Spec, scope) -> None:
        n = check_hanging(spec, scope)
        scope.require_columns(spec, "stream", tuple(length_columns(spec, n)))

    def build(self, ctx, spec: Spec) -> None:
        model = hanging_of(ctx, spec, offsets=True)
        stream = ctx.stream(spec["stream"])
        assoc = ctx.associate(stream, spec["robot"], spec)
        z = np.column_stack([stream.column(c) for c in length_columns(spec, model.n)])[assoc.row]
        ctx.add_vectorized(length_residual(model), _keys(ctx, spec, model, assoc.state), {"z": z},
                           [float(spec["sigma"])] * model.n, spec,
                           [ctx.state_time(spec["robot"], int(k)) for k in assoc.state])

    @classmethod
    def example(cls, rng):
        """cdpr_small (light cables) hanging in equilibrium at a random pose of its taut workspace, consistent
        lengths; the weight per length, the mass and the centre of mass estimated."""
        model, values = _example_values(rng, offsets=True)
        lengths, _, offsets = model.evaluate(_arrays(model, values))
        factor = vectorized_factor(length_residual(model), gaussian([1.0] * model.n), list(range(values.size())),
                                   {"z": lengths + offsets})
        return FactorExample(factor, values, perturbation=0.003)


class CableStatics(FactorType):
    name = "cable.statics"
    summary = ("force and moment balance at measured poses of a cable robot with sagging cables: the wrench the "
               "cables leave unbalanced against the weight, a constraint of its own noise (optional)")
    robot_fields = ("robot",)
    stream_fields = ("stream",)
    accepts_repeated_stamps = ("stream",)
    schema = {"type": "object",
              "properties": {"robot": NAME_SCHEMA, "stream": NAME_SCHEMA,
                             "sigma": {"type": "object", "properties": {"force": POSITIVE_SCHEMA,
                                                                        "moment": POSITIVE_SCHEMA},
                                       "required": ["force", "moment"], "additionalProperties": False},
                             "tolerance": TOLERANCE_SCHEMA, **ESTIMABLE_SCHEMA},
              "required": ["robot", "stream", "sigma"], "additionalProperties": False}

    def residual_parts(self, ctx, spec: Spec) -> list[ResidualPart]:
        return [ResidualPart("force", "N", (0, 1, 2)), ResidualPart("moment", "N m", (3, 4, 5))]

    def check(self, spec: Spec, scope) -> None:
        check_hanging(spec, scope)

    def build(self, ctx, spec: Spec) -> None:
        model = hanging_of(ctx, spec, offsets=False)
        assoc = ctx.associate(ctx.stream(spec["stream"]), spec["robot"], spec)
        sigma = [float(spec["sigma"]["force"])] * 3 + [float(spec["sigma"]["moment"])] * 3
        ctx.add_vectorized(statics_residual(model), _keys(ctx, spec, model, assoc.state), {}, sigma, spec,
                           [ctx.state_time(spec["robot"], int(k)) for k in assoc.state])

    @classmethod
    def example(cls, rng):
        """Weightless cables (the weight per length estimated at 0) at a pose the simulator's statics put in
        equilibrium for them: the cables balance the end-effector exactly, the wrench left is zero."""
        model, values = _example_values(rng, offsets=False, cable_weight=0.0)
        factor = vectorized_factor(statics_residual(model), gaussian([1.0] * 6), list(range(values.size())), {})
        return FactorExample(factor, values, perturbation=0.003)


def _example_values(rng, offsets: bool, cable_weight: float | None = None):
    """A Hanging model of cdpr_small (its cables' weight per length, or `cable_weight`) estimating weight, mass and
    centre of mass, and values at a pose in equilibrium: keys 0 pose, 1..n pulleys, then the offsets (random) if
    `offsets`, then weight, mass, com."""
    robot, pulleys = shipped_robot("cdpr_small")
    if cable_weight is not None:
        robot = replace(robot, cable_weight=cable_weight)
    mass = float(robot_description_data("cdpr_small")["end_effector"]["mass"])
    model = Hanging(robot.attachments, robot.weight / mass, robot.cable_weight, mass, robot.com, tuple(ESTIMABLE),
                    offsets)
    pose = inverse_pose(rng.uniform([-0.5, -3.0, -12.0], [1.0, 0.0, -3.0]), pulleys, robot, yaw=rng.normal(0, 0.02))
    values = gtsam.Values()
    values.insert(0, gtsam.Pose3(gtsam.Rot3(pose.R), pose.t))
    for i in range(robot.n):
        values.insert(1 + i, pulleys[i])
    key = 1 + robot.n
    if offsets:
        for i in range(robot.n):
            values.insert(key + i, float(rng.normal()))
        key += robot.n
    values.insert(key, float(robot.cable_weight))
    values.insert(key + 1, mass)
    values.insert(key + 2, np.asarray(robot.com, float))
    return model, values


def _arrays(model: Hanging, values: gtsam.Values) -> list[np.ndarray]:
    out = []
    for key, vartype in enumerate(model.variables()):
        out.append(np.asarray(vartype.to_array(vartype.read(values, key)))[None])
    return out


FACTOR_TYPES = [CatenaryCable, CableStatics]
