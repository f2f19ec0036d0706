"""Motion models between consecutive states of any robot (the `motion` family).

`odometry.diff_drive`: the wheel speeds of a differential-drive robot (SE(2) states), each held
until the next sample, integrated into one native BetweenFactorPose2 per state interval.
`odometry.increments`: dead reckoning logged as increments (distance, heading change per sample), composed
between states as arcs; with a heading-rate bias parameter (a gyro's) the factor estimates it.
`motion.constant_velocity`: a constant-velocity prior: the body-frame twist of consecutive
intervals agrees (SE(2) or SE(3) states).
"""

from __future__ import annotations

from functools import partial

import gtsam
import numpy as np

from fusionkit.api import (FactorExample, FactorType, NAME_SCHEMA as NAME, POSE2, POSE_SIGMA_SCHEMA,
                           POSITIVE_SCHEMA as SIGMA, Spec, differential_drive_twist, gaussian, held_intervals,
                           pose_sigmas, unicycle_increment, vectorized_factor)

from .residuals import CONSTANT_VELOCITY



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


def increment_segments(t: np.ndarray, distance: np.ndarray, turn: np.ndarray, t0: float, t1: float):
    """(d, theta, dt) of the pieces of [t0, t1] between the stream's stamps: row i is the motion over
    (t_{i-1}, t_i] (the first row's is not used), spread evenly over that span, so a row that straddles a
    state time is split in proportion; only the part of [t0, t1] inside the stream's span (none: empty)."""
    D = np.concatenate([[0.0], np.cumsum(distance[1:])])
    T = np.concatenate([[0.0], np.cumsum(turn[1:])])
    lo, hi = max(t0, float(t[0])), min(t1, float(t[-1]))  # nothing is known outside the stream's span
    if hi <= lo:
        return np.zeros(0), np.zeros(0), np.zeros(0)
    cuts = np.concatenate([[lo], t[(t > lo) & (t < hi)], [hi]])
    return np.diff(np.interp(cuts, t, D)), np.diff(np.interp(cuts, t, T)), np.diff(cuts)


def composed_arcs(d: np.ndarray, theta: np.ndarray, bias: float, dt: np.ndarray) -> tuple[gtsam.Pose2, np.ndarray]:
    """Delta = Exp(d_1, 0, theta_1 - b dt_1) ... Exp(d_m, 0, theta_m - b dt_m) and dDelta/db in Delta's right
    tangent: sum_j Ad(R_j^-1) J_r(xi_j) (0, 0, -dt_j), R_j the arcs after j."""
    arcs = [np.array([dj, 0.0, tj - bias * hj]) for dj, tj, hj in zip(d, theta, dt)]
    delta, g = gtsam.Pose2(), np.zeros(3)
    for xi, h in zip(reversed(arcs), reversed(dt)):  # from the last arc back: `delta` is R_j before arc j joins
        g = g + delta.inverse().AdjointMap() @ gtsam.Pose2.ExpmapDerivative(xi) @ np.array([0.0, 0.0, -h])
        delta = gtsam.Pose2.Expmap(xi).compose(delta)
    return delta, g


def _increments_error(d: np.ndarray, theta: np.ndarray, dt: np.ndarray, this, values: gtsam.Values, H):
    """e = Log(Delta(b)^-1 X_a^-1 X_b) (BetweenFactorPose2's error with the measurement built at the bias b)."""
    a, b, bias = this.keys()
    delta, g = composed_arcs(d, theta, values.atDouble(bias), dt)
    Ha, Hb = np.zeros((3, 3), order="F"), np.zeros((3, 3), order="F")
    relative = values.atPose2(a).between(values.atPose2(b), Ha, Hb)
    mismatch = delta.between(relative)
    e = gtsam.Pose2.Logmap(mismatch)
    if H is not None:
        L = gtsam.Pose2.LogmapDerivative(e)
        H[0], H[1] = L @ Ha, L @ Hb
        H[2] = (-L @ mismatch.inverse().AdjointMap() @ g).reshape(3, 1)
    return e


class IncrementOdometry(FactorType):
    name = "odometry.increments"
    summary = ("dead reckoning logged as increments (distance, heading change per sample) composed as arcs "
               "between consecutive states; optionally a heading-rate bias parameter (rad/s)")
    robot_fields = ("robot",)
    stream_fields = ("stream",)
    schema = {"type": "object",
              "properties": {"robot": NAME, "stream": NAME, "distance": {**NAME, "default": "distance"},
                             "turn": {**NAME, "default": "turn"}, "bias": NAME, "sigma": POSE_SIGMA_SCHEMA},
              "required": ["robot", "stream", "sigma"], "additionalProperties": False}

    def check(self, spec: Spec, scope) -> None:
        scope.require_states(spec, "robot", "pose2")
        scope.require_columns(spec, "stream", (spec["distance"], spec["turn"]))
        if "bias" in spec.data:
            scope.require_parameter(spec, "robot", "bias", "scalar")

    def build(self, ctx, spec: Spec) -> None:
        """Row i: the distance (m) travelled and the heading change (rad) over (t_{i-1}, t_i]; with `bias`
        (rad/s), the true heading change is the logged one minus bias * dt. sigma (per sqrt(s): m and rad)
        grows with the square root of the state interval, as odometry.diff_drive's."""
        robot = spec["robot"]
        states = ctx.state_set(robot, spec)
        stream = ctx.stream(spec["stream"])
        distance, turn = stream.column(spec["distance"]), stream.column(spec["turn"])
        sig = pose_sigmas(spec["sigma"], planar=True)
        outside = 0
        for k in range(1, len(states)):
            t0, t1 = float(states.t[k - 1]), float(states.t[k])
            d, theta, dt = increment_segments(stream.t, distance, turn, t0, t1)
            if not len(d):
                outside += 1
                continue
            noise = ctx.noise(sig * np.sqrt(max(dt.sum(), 1e-9)), spec)
            keys = [ctx.pose_key(robot, k - 1), ctx.pose_key(robot, k)]
            if "bias" in spec.data:
                factor = gtsam.CustomFactor(noise, keys + [ctx.parameter(robot, spec["bias"], None, k - 1)],
                                            partial(_increments_error, d, theta, dt))
            else:
                factor = gtsam.BetweenFactorPose2(*keys, unicycle_increment(d, theta, np.ones(len(d))), noise)
            ctx.add(factor, spec, t1)
        if outside:
            ctx.note(f"{spec.label}: {outside} state interval(s) lie outside stream {spec['stream']!r} and "
                             "have no increment factor")

    @classmethod
    def example(cls, rng):
        """Ten logged increments with a heading-rate bias, the end pose composed exactly."""
        d, theta, dt = rng.uniform(0.0, 0.1, 10), rng.normal(0, 0.05, 10), np.full(10, 0.05)
        bias = float(rng.normal(0, 0.01))
        a = gtsam.Pose2(*rng.normal(size=3))
        values = gtsam.Values()
        values.insert(0, a)
        values.insert(1, a.compose(composed_arcs(d, theta, bias, dt)[0]))
        values.insert(2, bias)
        factor = gtsam.CustomFactor(gaussian([0.01, 0.01, 0.02]), [0, 1, 2], partial(_increments_error, d, theta, dt))
        return FactorExample(factor, values)


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
        t = np.asarray(states.t, float)
        if len(t) < 3:
            return
        dt1, dt2 = np.diff(t)[:-1], np.diff(t)[1:]
        poses = [ctx.pose_key(robot, k) for k in range(len(t))]
        keys = np.column_stack([poses[:-2], poses[1:-1], poses[2:]])
        ctx.add_vectorized(CONSTANT_VELOCITY[planar], keys, {"dt1": dt1, "dt2": dt2},
                           sig[None, :] * np.sqrt(0.5 * (dt1 + dt2))[:, None], spec, t[2:])

    @classmethod
    def example(cls, rng):
        planar = bool(rng.random() < 0.5)
        cls_, d = (gtsam.Pose2, 3) if planar else (gtsam.Pose3, 6)
        x0 = cls_.Expmap(rng.normal(size=d))
        twist = rng.normal(size=d) * 0.5
        dt1, dt2 = 0.1, 0.15
        x1 = x0.compose(cls_.Expmap(twist * dt1))
        x2 = x1.compose(cls_.Expmap(twist * dt2))
        values = gtsam.Values()
        for i, x in enumerate((x0, x1, x2)):
            values.insert(i, x)
        factor = vectorized_factor(CONSTANT_VELOCITY[planar], gaussian([0.1] * d), [0, 1, 2],
                                   {"dt1": np.array([dt1]), "dt2": np.array([dt2])})
        return FactorExample(factor, values)


FACTOR_TYPES = [DiffDriveOdometry, IncrementOdometry, ConstantVelocity]
