"""Layers 1 and 2 of the `altimeter.height` factor type: the config schema (+ semantic
checks) and the builder that turns one config entry into GTSAM factors through the BuildContext.
The model itself lives in `residuals.py`."""

from __future__ import annotations

from functools import partial

import gtsam
import numpy as np

from fusionkit.api import TOLERANCE_SCHEMA, FactorExample, FactorType, Spec

from .residuals import height_residual


def _error(measured: float, this: gtsam.CustomFactor, values: gtsam.Values, H) -> np.ndarray:
    """CustomFactor callback: unpack the variables, delegate to the pure residual."""
    keys = this.keys()
    return height_residual(values.atPose3(keys[0]), values.atDouble(keys[1]), measured, H)


def altimeter_factor(pose_key: int, bias_key: int, measured: float,
                     noise: gtsam.noiseModel.Base) -> gtsam.CustomFactor:
    """One altimeter reading `measured` (m) on a Pose3 variable and a scalar bias variable."""
    return gtsam.CustomFactor(noise, [pose_key, bias_key], partial(_error, float(measured)))


class AltimeterHeight(FactorType):
    name = "altimeter.height"
    summary = "barometric altimeter: body height + unknown bias (a robot parameter), at the nearest state"
    robot_fields = ("robot",)     # the core checks these name a robot of the config...
    stream_fields = ("stream",)   # ...and this a stream some source provides
    schema = {"type": "object",
              "properties": {"robot": {"type": "string"},
                             "stream": {"type": "string"},
                             "bias": {"type": "string"},
                             "sigma": {"type": "number", "exclusiveMinimum": 0},
                             "tolerance": TOLERANCE_SCHEMA},   # s; the default every factor type shares
              "required": ["robot", "stream", "bias", "sigma"], "additionalProperties": False}

    def check(self, spec: Spec, scope) -> None:
        """Before any data is read: the bias names a scalar parameter of the robot, and the
        stream has a `height` column."""
        scope.require_parameter(spec, "robot", "bias", "scalar")
        scope.require_columns(spec, "stream", ("height",))

    def build(self, ctx, spec: Spec) -> None:
        robot = spec["robot"]
        states = ctx.state_set(robot, spec)
        if states.family.vartype.name != "pose3":
            raise spec.error("robot", "an altimeter needs 3-D pose states (states.type: pose3)")
        stream = ctx.stream(spec["stream"])
        assoc = ctx.associate(stream, robot, spec)   # within the entry's `tolerance`
        noise = ctx.noise([spec["sigma"]], spec)
        heights = stream.column("height")[assoc.row]
        for k, z in zip(assoc.state.tolist(), heights.tolist()):
            # k=k: a time-varying bias (time_varying: true + parameter.random_walk) gets the
            # bias variable of state k; a static one ignores k and is one variable.
            bias = ctx.parameter(robot, spec["bias"], k=k)
            ctx.add(altimeter_factor(ctx.pose_key(robot, k), bias, z, noise), spec, ctx.state_time(robot, k))

    @classmethod
    def example(cls, rng: np.random.Generator) -> FactorExample:
        """A factor at a random (rotated, translated) pose and bias, with a consistent reading."""
        pose = gtsam.Pose3.Expmap(rng.normal(size=6))
        bias = float(rng.normal(scale=2.0))
        values = gtsam.Values()
        values.insert(0, pose)
        values.insert(1, bias)
        measured = float(pose.translation()[2] + bias)
        return FactorExample(altimeter_factor(0, 1, measured, gtsam.noiseModel.Isotropic.Sigma(1, 0.1)), values)


FACTOR_TYPES = [AltimeterHeight]
