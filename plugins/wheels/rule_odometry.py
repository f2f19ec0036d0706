"""`wheels.rule_odometry`: a rule-based baseline (rules.py) run from a config, on the same wheel
stream the graph uses (docs/models/wheels.md#baselines).

The rule `method` dead-reckons the whole stream with the description's nominal parameters (radii,
axle length, passive wheel, gyro scale and bias: true rate = scale * reading + bias); the motion
between consecutive states is then one native BetweenFactorPose2. With `pose.origin` as the only
other factor the estimate is exactly the rule's trajectory, which `fusionkit run` evaluates against
truth like any estimate; the states this entry declares start at the rule's poses.
"""

from __future__ import annotations

import gtsam
import numpy as np

from fusionkit.api import (DataError, FactorExample, FactorType, NAME_SCHEMA as NAME, POSE_SIGMA_SCHEMA, Spec, Stream,
                           gaussian, pose_sigmas)

from . import rules
from .factors import check_drive_entry, require_gyro, require_wheels
from .kinematics import GYRO, IMU_GYRO, gyro_integrals, inside, wheel_column
from .model import AXLE, GYRO_BIAS, GYRO_SCALE, PASSIVE_OFFSET, RADIUS, drive_of

RATE = {"type": "number", "minimum": 0}
NEEDS = {"odometry": (), "gyrodometry": ("gyro",), "first_version": ("passive", "gyro"),
         "minimal_gyro": ("passive", "gyro"), "final_version": ("passive", "gyro")}
THRESHOLDS = {"v": ({**RATE, "default": rules.V_THRES}, "m/s"),
              "omega": ({**RATE, "default": rules.OMEGA_THRES}, "rad/s"),
              "d_omega": ({**RATE, "default": rules.D_OMEGA_THRES}, "rad/s"),
              "dv": ({**RATE, "default": rules.DV_THRES}, "m/s")}


def wheel_steps(stream, drive, gyro_stream=None) -> rules.WheelSteps:
    """Per-interval wheel-contact speeds (m/s) of a wheel stream with the description's nominal
    parameters; the gyro's mean rate over each interval, scaled and biased: the wheel stream's gyro
    sample ending it, or an IMU's `gz` samples (of `gyro_stream` when given) integrated over it
    (kinematics.gyro_integrals; the wheel stream must lie inside the IMU's span)."""
    dt = np.diff(stream.t)

    def speed(wheel: str) -> np.ndarray:
        return drive.nominal[RADIUS[wheel]] * np.diff(wheel_column(stream, drive, wheel)) / dt
    rate, source = None, stream if gyro_stream is None else gyro_stream
    if source is stream and GYRO in stream.columns:
        rate = stream.column(GYRO)[1:]  # the interval means themselves
    elif GYRO in source.columns or IMU_GYRO in source.columns:
        rate = gyro_integrals(source, stream.t) / dt
    gyro = drive.nominal[GYRO_SCALE] * rate + drive.nominal[GYRO_BIAS] if drive.has_gyro and rate is not None else None
    middle = speed("passive") if drive.has_passive and drive.columns["passive"] in stream.columns else None
    return rules.WheelSteps(dt, speed("left"), speed("right"), drive.nominal[AXLE], middle=middle, gyro=gyro,
                            passive_offset=drive.nominal.get(PASSIVE_OFFSET, 0.0))


def inside_gyro_span(stream, gyro_stream, spec: Spec, note) -> Stream:
    """The wheel samples inside the gyro stream's span (a note counts those left out); DataError with
    fewer than two."""
    rows = inside(gyro_stream.t, stream.t)
    if rows.sum() < 2:
        raise DataError(f"{spec.label}: wheel stream {stream.name!r} (t = {stream.t[0]:.6f} .. {stream.t[-1]:.6f} s) "
                        f"and gyro stream {gyro_stream.name!r} (t = {gyro_stream.t[0]:.6f} .. "
                        f"{gyro_stream.t[-1]:.6f} s) overlap by fewer than two wheel samples (expected streams on one "
                        f"clock that overlap)")
    if not rows.all():
        note(f"{spec.label}: {int((~rows).sum())} of {len(rows)} samples of stream {stream.name!r} lie "
                     f"outside gyro stream {gyro_stream.name!r} and are left out")
    return stream.subset(rows)


def rule_poses(method: str, steps: rules.WheelSteps, thresholds: dict, reconstruct: bool) -> np.ndarray:
    """(N + 1, 3) poses of `method` from the origin."""
    v, w, dw, dv = (thresholds[k] for k in ("v", "omega", "d_omega", "dv"))
    if method == "odometry":
        return rules.odometry(steps)
    if method == "gyrodometry":
        return rules.gyrodometry(steps, w, reconstruct, dw)
    if method == "first_version":
        return rules.first_version(steps, v)
    if method == "minimal_gyro":
        return rules.minimal_gyro(steps, v, w)
    return rules.final_version(steps, v, w, dw, dv)


class RuleOdometry(FactorType):
    name = "wheels.rule_odometry"
    summary = ("rule-based dead reckoning of a wheel stream (odometry, gyrodometry, the passive-wheel paper's "
               "rules) as relative poses between consecutive states (native BetweenFactorPose2)")
    robot_fields = ("robot",)
    stream_fields = ("stream", "gyro_stream")
    schema = {"type": "object",
              "properties": {"robot": NAME, "stream": NAME, "gyro_stream": NAME,
                             "method": {"enum": list(NEEDS), "default": "final_version"},
                             "thresholds": {"type": "object",
                                            "properties": {k: s for k, (s, _) in THRESHOLDS.items()},
                                            "additionalProperties": False,
                                            "default": {k: s["default"] for k, (s, _) in THRESHOLDS.items()}},
                             "reconstruct": {"type": "boolean", "default": False},
                             "sigma": {**POSE_SIGMA_SCHEMA, "default": {"rotation": 0.01, "translation": 0.01}}},
              "required": ["robot", "stream"], "additionalProperties": False}

    def check(self, spec: Spec, scope) -> None:
        """A diff_drive robot with pose2 states; the stream has left, right and what the method needs
        (the gyro: in `gyro_stream` when given), and the description has the passive wheel / gyro the
        method uses."""
        drive = drive_of(check_drive_entry(spec, scope))
        needs = NEEDS[spec["method"]]
        for sensor, present, param in (("passive wheel", drive.has_passive, "passive_radius"),
                                       ("gyro", drive.has_gyro, "gyro_scale and gyro_bias")):
            if sensor.split()[0] in needs and not present:
                raise spec.error("method", f"method {spec['method']} needs the {sensor}; robot {spec['robot']!r} "
                                 f"has none (its description lacks parameter {param})")
        require_wheels(spec, scope, drive, ("left", "right") + tuple(w for w in needs if w == "passive"))
        if "gyro" in needs:
            require_gyro(spec, scope, "gyro_stream" if "gyro_stream" in spec.data else "stream")

    def build(self, ctx, spec: Spec) -> None:
        """The rule's poses at the stream's samples, interpolated at the state times (x, y, unwrapped
        theta; states outside the stream are left out with a note). The states this entry declares
        start at the rule's motion from the first state's current value. Sigma (rad and m per sqrt(s)) grows
        with the square root of each interval. With `gyro_stream`, the wheel samples inside its span."""
        robot = spec["robot"]
        states = ctx.state_set(robot, spec)
        stream = ctx.stream(spec["stream"])
        gyro_stream = ctx.stream(spec["gyro_stream"]) if "gyro_stream" in spec.data else None
        if gyro_stream is not None:
            stream = inside_gyro_span(stream, gyro_stream, spec, ctx.note)
        steps = wheel_steps(stream, drive_of(ctx.robot(robot)), gyro_stream)
        poses = rule_poses(spec["method"], steps, spec["thresholds"], spec["reconstruct"])
        ks = np.flatnonzero((states.t >= stream.t[0]) & (states.t <= stream.t[-1]))
        if len(ks) < len(states):
            ctx.note(f"{spec.label}: {len(states) - len(ks)} of {len(states)} states of robot {robot!r} "
                             f"lie outside stream {stream.name!r} and get no dead-reckoning factor")
        at = np.column_stack([np.interp(states.t[ks], stream.t, poses[:, i]) for i in range(3)])
        fresh = [not ctx.has_variable(key) for key in states.family.keys(ks)]
        keys = ctx.state_keys(robot, ks)
        sig = pose_sigmas(spec["sigma"], planar=True)
        pose2 = [gtsam.Pose2(*p) for p in at]
        for i in range(1, len(ks)):
            if ks[i] != ks[i - 1] + 1:
                continue  # states outside the stream between them
            t0, t1 = float(states.t[ks[i - 1]]), float(states.t[ks[i]])
            noise = ctx.noise(sig * np.sqrt(max(t1 - t0, 1e-9)), spec)
            ctx.add(gtsam.BetweenFactorPose2(keys[i - 1], keys[i], pose2[i - 1].between(pose2[i]), noise), spec, t1)
        start = gtsam.Pose2() if not keys or fresh[0] else ctx.initial_value(keys[0])
        for key, pose, new in zip(keys, pose2, fresh):
            if new:  # the rule's motion from the first state's current value (pose.origin's, if set)
                ctx.set_initial(key, start.compose(pose2[0].between(pose)))

    @classmethod
    def example(cls, rng):
        a, delta = gtsam.Pose2(*rng.normal(size=3)), gtsam.Pose2(*(rng.normal(size=3) * 0.1))
        values = gtsam.Values()
        values.insert(0, a)
        values.insert(1, a.compose(delta))
        return FactorExample(gtsam.BetweenFactorPose2(0, 1, delta, gaussian([0.01, 0.01, 0.02])), values)


RULE_ODOMETRY = [RuleOdometry]
