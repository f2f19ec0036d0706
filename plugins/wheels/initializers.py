"""`wheels.dead_reckoning`: initial poses from the driven wheels' odometry at the nominal intrinsics."""

from __future__ import annotations

import gtsam
import numpy as np

from fusionkit.api import Initializer, Spec, arc_path

from .factors import require_gyro, require_wheels
from .kinematics import driven_twist, gyro_turns, increments, wheel_column
from .model import PASSIVE_RADIUS, drive_of


class DeadReckoning(Initializer):
    name = "wheels.dead_reckoning"
    summary = ("initial Pose2 states by odometry (one arc per state interval, nominal intrinsics): turn from the "
               "driven wheels, forward travel from them or from the passive wheel; from the first state's current "
               "initial value (pose.origin; identity otherwise)")
    robot_fields = ("robot",)
    stream_fields = ("stream",)
    schema = {"type": "object", "properties": {"robot": {"type": "string"}, "stream": {"type": "string"},
                                               "forward": {"enum": ["driven", "passive"], "default": "driven"},
                                               "turn": {"enum": ["driven", "gyro"], "default": "driven"}},
              "required": ["robot", "stream"], "additionalProperties": False}

    def check(self, spec: Spec, scope) -> None:
        desc = scope.require_model(spec, "robot", "diff_drive")
        scope.require_states(spec, "robot", "pose2")
        wheels = ("left", "right") + (("passive",) if spec["forward"] == "passive" else ())
        if spec["forward"] == "passive" and PASSIVE_RADIUS not in desc.parameters:
            raise spec.error("forward", f"robot {spec['robot']!r} has no passive wheel (no parameter 'passive_radius')")
        require_wheels(spec, scope, drive_of(desc), wheels)
        if spec["turn"] == "gyro":
            if not drive_of(desc).has_gyro:
                raise spec.error("turn", f"robot {spec['robot']!r} has no gyro (no parameters 'gyro_scale', 'gyro_bias')")
            require_gyro(spec, scope, "stream")

    def initialize(self, ctx, spec: Spec) -> None:
        """`forward: passive`: the passive wheel's travel carried to the axle midpoint (it hardly slips: a
        robot stuck with spinning wheels starts where it stands). States before (after) the stream's span
        take its first (last) reading: they stand still."""
        robot = spec["robot"]
        drive = drive_of(ctx.robot(robot))
        stream = ctx.stream(spec["stream"])
        states = ctx.state_set(robot, spec)
        t = np.clip(states.t, stream.t[0], stream.t[-1])
        forward, turn = driven_twist(stream, drive, t)
        if spec["turn"] == "gyro":  # a calibrated gyro
            turn = gyro_turns(stream, drive, t)
        if spec["forward"] == "passive":
            passive = increments(stream.t, wheel_column(stream, drive, "passive"), t)
            forward = drive.nominal[PASSIVE_RADIUS] * passive + drive.passive_offset * turn
        first = states.key(0)
        start = ctx.initial_value(first) if ctx.has_variable(first) else gtsam.Pose2()
        poses = arc_path(forward, turn, np.ones(len(turn)), (start.x(), start.y(), start.theta()))
        for key, (x, y, theta) in zip(states.family.keys(range(len(states))), poses.tolist()):
            if ctx.has_variable(key):
                ctx.set_initial(key, gtsam.Pose2(x, y, theta))


INITIALIZERS = [DeadReckoning]
