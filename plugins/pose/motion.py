"""Motion models between consecutive states of any robot.

`odometry.diff_drive`: the wheel speeds of a differential-drive robot (SE(2) states), each held
until the next sample, integrated into one native BetweenFactorPose2 per state interval.
`motion.constant_velocity`: a constant-velocity prior: the body-frame twist of consecutive
intervals agrees (SE(2) or SE(3) states).
"""

from __future__ import annotations

from functools import partial

import gtsam
import numpy as np

from fusionkit.api import (POSE2, POSE_SIGMA_SCHEMA, differential_drive_twist, FactorExample, FactorType,
                           gaussian, held_intervals, pose_sigmas, Spec, unicycle_increment)

SIGMA = {"type": "number", "exclusiveMinimum": 0}
NAME = {"type": "string"}


class DiffDriveOdometry(FactorType):
    name = "odometry.diff_drive"
    summary = ("differential-drive wheel odometry: wheel speeds integrated between consecutive states "
               "(native BetweenFactorPose2)")
    robot_fields = ("robot",)
    stream_fields = ("stream",)
    schema = {"type": "object",
              "properties": {"robot": NAME, "stream": NAME, "wheel_distance": SIGMA,
                             "right": {**NAME, "default": "v_right"}, "left": {**NAME, "default": "v_left"},
                             "sigma": POSE_SIGMA_SCHEMA},
              "required": ["robot", "stream", "wheel_distance", "sigma"], "additionalProperties": False}

    def check(self, spec: Spec, scope) -> None:
        scope.require_states(spec, "robot", "pose2")
        scope.require_columns(spec, "stream", (spec["right"], spec["left"]))

    def build(self, ctx, spec: Spec) -> None:
        """Each wheel-speed sample holds until the next; sigma (per sqrt(s): m and rad) grows with
        the square root of the interval."""
        robot = spec["robot"]
        states = ctx.state_set(robot, spec)
        stream = ctx.stream(spec["stream"])
        v, omega = differential_drive_twist(stream.column(spec["right"]), stream.column(spec["left"]),
                                            float(spec["wheel_distance"]))
        sig = pose_sigmas(spec["sigma"], planar=True)
        for k in range(1, len(states)):
            t0, t1 = float(states.t[k - 1]), float(states.t[k])
            rows, dt = held_intervals(stream.t, t0, t1)
            delta = unicycle_increment(v[rows], omega[rows], dt)
            root = np.sqrt(max(t1 - t0, 1e-9))
            noise = ctx.noise(sig * root, spec)
            ctx.add(gtsam.BetweenFactorPose2(ctx.pose_key(robot, k - 1), ctx.pose_key(robot, k), delta, noise),
                    spec, t1)

    @classmethod
    def example(cls, rng):
        a = gtsam.Pose2(*rng.normal(size=3))
        delta = unicycle_increment(*differential_drive_twist(rng.normal(size=3) * 0.3, rng.normal(size=3) * 0.3, 0.08),
                                   np.full(3, 0.1))
        values = gtsam.Values()
        values.insert(0, a)
        values.insert(1, a.compose(delta))
        return FactorExample(gtsam.BetweenFactorPose2(0, 1, delta, gaussian([0.01, 0.01, 0.02])), values)


def _constant_velocity_error(dt1: float, dt2: float, planar: bool, this, v: gtsam.Values, H):
    k = this.keys()
    cls = gtsam.Pose2 if planar else gtsam.Pose3
    at = v.atPose2 if planar else v.atPose3
    x0, x1, x2 = at(k[0]), at(k[1]), at(k[2])
    d = 3 if planar else 6
    A0, A1, B1, B2 = (np.zeros((d, d), order="F") for _ in range(4))
    L1, L2 = np.zeros((d, d), order="F"), np.zeros((d, d), order="F")
    xi1 = cls.Logmap(x0.between(x1, A0, A1), L1)
    xi2 = cls.Logmap(x1.between(x2, B1, B2), L2)
    if H is not None:
        H[0] = L1 @ A0 / dt1
        H[1] = L1 @ A1 / dt1 - L2 @ B1 / dt2
        H[2] = -L2 @ B2 / dt2
    return xi1 / dt1 - xi2 / dt2


class ConstantVelocity(FactorType):
    name = "motion.constant_velocity"
    summary = ("constant-velocity prior between ranging epochs: the body-frame twist of consecutive intervals "
               "agrees, Log(X0^-1 X1)/dt1 = Log(X1^-1 X2)/dt2")
    robot_fields = ("robot",)
    schema = {"type": "object",
              "properties": {"robot": NAME, "sigma": POSE_SIGMA_SCHEMA},
              "required": ["robot", "sigma"], "additionalProperties": False}

    def check(self, spec: Spec, scope) -> None:
        scope.require_states(spec, "robot")

    def build(self, ctx, spec: Spec) -> None:
        """sigma: the velocity change allowed across one epoch (m/s and rad/s), scaled by
        sqrt(mean interval) (a white-acceleration model)."""
        robot = spec["robot"]
        states = ctx.state_set(robot, spec)
        planar = states.family.vartype is POSE2
        sig = pose_sigmas(spec["sigma"], planar)
        for k in range(1, len(states) - 1):
            dt1, dt2 = float(states.t[k] - states.t[k - 1]), float(states.t[k + 1] - states.t[k])
            root = np.sqrt(0.5 * (dt1 + dt2))
            keys = [ctx.pose_key(robot, k - 1), ctx.pose_key(robot, k), ctx.pose_key(robot, k + 1)]
            factor = gtsam.CustomFactor(ctx.noise(sig * root, spec), keys,
                                        partial(_constant_velocity_error, dt1, dt2, planar))
            ctx.add(factor, spec, float(states.t[k + 1]))

    @classmethod
    def example(cls, rng):
        x0 = gtsam.Pose3(gtsam.Rot3.Expmap(rng.normal(size=3)), rng.normal(size=3))
        twist = rng.normal(size=6) * 0.5
        dt1, dt2 = 0.1, 0.15
        x1 = x0.compose(gtsam.Pose3.Expmap(twist * dt1))
        x2 = x1.compose(gtsam.Pose3.Expmap(twist * dt2))
        values = gtsam.Values()
        for i, x in enumerate((x0, x1, x2)):
            values.insert(i, x)
        factor = gtsam.CustomFactor(gaussian([0.1] * 6), [0, 1, 2], partial(_constant_velocity_error, dt1, dt2, False))
        return FactorExample(factor, values)


FACTOR_TYPES = [DiffDriveOdometry, ConstantVelocity]
