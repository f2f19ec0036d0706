"""The `camera.pixel` factor type: pixels of known world points, each a factor on the robot's pose at the
nearest state and its camera's intrinsics (a `cal3_s2` parameter of the robot description)."""

from __future__ import annotations

import gtsam
import numpy as np

from fusionkit.api import (NAME_SCHEMA, POSITIVE_SCHEMA, TOLERANCE_SCHEMA, FactorExample, FactorType, Spec,
                           vectorized_factor)

from .intrinsics import CAL3_S2
from .residuals import PIXEL

COLUMNS = ("u", "v", "x", "y", "z")  # pixel (px), the world point it shows (m)


class CameraPixel(FactorType):
    name = "camera.pixel"
    summary = ("pinhole camera at the body frame (z forward): pixel (u, v) of a known world point (x, y, z), with "
               "the intrinsics a `cal3_s2` parameter (fusionkit-camera)")
    robot_fields = ("robot",)
    stream_fields = ("stream",)
    accepts_repeated_stamps = ("stream",)  # several points per image share its stamp
    schema = {"type": "object",
              "properties": {"robot": NAME_SCHEMA, "stream": NAME_SCHEMA,
                             "intrinsics": {**NAME_SCHEMA, "default": "K"},
                             "sigma": POSITIVE_SCHEMA, "tolerance": TOLERANCE_SCHEMA},
              "required": ["robot", "stream", "sigma"], "additionalProperties": False}

    def check(self, spec: Spec, scope) -> None:
        scope.require_parameter(spec, "robot", "intrinsics", CAL3_S2.name)
        scope.require_columns(spec, "stream", COLUMNS)

    def build(self, ctx, spec: Spec) -> None:
        robot = spec["robot"]
        if ctx.state_set(robot, spec).family.vartype.name != "pose3":
            raise spec.error("robot", "a camera needs 3-D pose states (states.type: pose3)")
        stream = ctx.stream(spec["stream"])
        assoc = ctx.associate(stream, robot, spec)
        intrinsics = ctx.parameter(robot, spec["intrinsics"])
        keys = np.column_stack([ctx.state_keys(robot, assoc.state.tolist()), np.full(len(assoc.row), intrinsics)])
        rows = assoc.row
        data = {"point": np.column_stack([stream.column(c)[rows] for c in "xyz"]),
                "pixel": np.column_stack([stream.column(c)[rows] for c in "uv"])}
        times = [ctx.state_time(robot, k) for k in assoc.state.tolist()]
        ctx.add_vectorized(PIXEL, keys.reshape(-1, 2), data, [spec["sigma"]] * 2, spec, times)

    @classmethod
    def example(cls, rng: np.random.Generator) -> FactorExample:
        """A camera looking at a point 2-4 m ahead, intrinsics near a VGA camera's, a consistent pixel."""
        pose = gtsam.Pose3(gtsam.Rot3.Expmap(rng.normal(scale=0.5, size=3)), rng.normal(size=3))
        k = gtsam.Cal3_S2(*(np.array([500.0, 480.0, 0.0, 320.0, 240.0]) + rng.normal(scale=[20, 20, 1, 10, 10])))
        point = pose.transformFrom(np.r_[rng.uniform(-1, 1, size=2), rng.uniform(2, 4)])
        values = gtsam.Values()
        values.insert(0, pose)
        values.insert(1, k)
        pixel = PIXEL.evaluate([pose.matrix()[None], k.vector()[None]], {"point": point[None],
                                                                          "pixel": np.zeros((1, 2))}, False)[0]
        data = {"point": point[None], "pixel": pixel[None]}
        return FactorExample(vectorized_factor(PIXEL, gtsam.noiseModel.Isotropic.Sigma(2, 0.5), [0, 1], data), values)


FACTOR_TYPES = [CameraPixel]
