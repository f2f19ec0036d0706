"""An IMU between states: GTSAM's preintegrated IMU factor, and the velocities it needs.

`imu.preintegrated`: the accelerometer (m/s^2, specific force in the body frame) and gyroscope
(rad/s) samples between consecutive states, each held until the next sample, preintegrated
(Forster et al.) into one native `ImuFactor` over (pose_i, velocity_i, pose_j, velocity_j, bias).
Gravity points down the world z axis (`gravity`, m/s^2). The bias is an `imu_bias`
parameter of the robot ([accelerometer (3), gyroscope (3)]); per-state velocities are the
`velocity` family (world frame, m/s). `imu.velocity` initializes them from the poses.
"""

from __future__ import annotations

import gtsam
import numpy as np

from fusionkit.api import VELOCITY3, FactorExample, FactorType, Initializer, Spec, held_intervals

NAME = {"type": "string"}
IMU_COLUMNS = ("ax", "ay", "az", "gx", "gy", "gz")
VELOCITY = "velocity"


def preintegration_params(accel_density: float, gyro_density: float, gravity: float,
                          integration: float = 1e-8) -> gtsam.PreintegrationParams:
    """Continuous-time noise densities (m/s^2/sqrt(Hz), rad/s/sqrt(Hz)), gravity along -z."""
    p = gtsam.PreintegrationParams.MakeSharedU(gravity)
    p.setAccelerometerCovariance(np.eye(3) * accel_density ** 2)
    p.setGyroscopeCovariance(np.eye(3) * gyro_density ** 2)
    p.setIntegrationCovariance(np.eye(3) * integration ** 2)
    return p


def preintegrate(params, bias: gtsam.imuBias.ConstantBias, t: np.ndarray, samples: np.ndarray, t0: float,
                 t1: float) -> gtsam.PreintegratedImuMeasurements:
    """The samples (K, 6) at times t held over [t0, t1), each until the next sample."""
    pim = gtsam.PreintegratedImuMeasurements(params, bias)
    rows, dts = held_intervals(t, t0, t1)
    for j, dt in zip(rows, dts):
        if dt > 0:
            pim.integrateMeasurement(samples[j, :3], samples[j, 3:], float(dt))
    return pim


class PreintegratedImu(FactorType):
    name = "imu.preintegrated"
    summary = "IMU samples between consecutive states, preintegrated into GTSAM's native ImuFactor (pose, velocity, bias)"
    accepts_robust = False  # GTSAM's ImuFactor takes its noise from the preintegrated covariance
    robot_fields = ("robot",)
    stream_fields = ("stream",)
    schema = {"type": "object",
              "properties": {"robot": NAME, "stream": NAME, "bias": NAME,
                             "columns": {"type": "array", "items": NAME, "minItems": 6, "maxItems": 6,
                                         "default": list(IMU_COLUMNS)},
                             "sigma": {"type": "object",
                                       "properties": {"accelerometer": {"type": "number", "exclusiveMinimum": 0},
                                                      "gyroscope": {"type": "number", "exclusiveMinimum": 0}},
                                       "required": ["accelerometer", "gyroscope"], "additionalProperties": False},
                             "gravity": {"type": "number", "minimum": 0, "default": 9.81}},
              "required": ["robot", "stream", "bias", "sigma"], "additionalProperties": False}

    def check(self, spec: Spec, scope) -> None:
        scope.require_states(spec, "robot", "pose3")
        scope.require_parameter(spec, "robot", "bias", "imu_bias")
        scope.require_columns(spec, "stream", tuple(spec["columns"]))

    def build(self, ctx, spec: Spec) -> None:
        """sigma: noise densities (accelerometer m/s^2/sqrt(Hz), gyroscope rad/s/sqrt(Hz))."""
        robot = spec["robot"]
        states = ctx.state_set(robot, spec)
        stream = ctx.stream(spec["stream"])
        samples = np.column_stack([stream.column(c) for c in spec["columns"]])
        params = preintegration_params(spec["sigma"]["accelerometer"], spec["sigma"]["gyroscope"], spec["gravity"])
        param = ctx.robot(robot).parameters[spec["bias"]]
        for k in range(1, len(states)):
            t0, t1 = float(states.t[k - 1]), float(states.t[k])
            bias_key = ctx.parameter(robot, spec["bias"], None, k - 1)
            pim = preintegrate(params, param.values[0], stream.t, samples, t0, t1)  # about the nominal bias
            keys = [ctx.pose_key(robot, k - 1), ctx.state_variable(robot, VELOCITY, VELOCITY3, k - 1),
                    ctx.pose_key(robot, k), ctx.state_variable(robot, VELOCITY, VELOCITY3, k)]
            ctx.add(gtsam.ImuFactor(*keys, bias_key, pim), spec, t1)

    @classmethod
    def example(cls, rng):
        """A constant acceleration and turn rate over 0.1 s, the end state propagated exactly."""
        params = preintegration_params(0.02, 0.002, 9.81)
        bias = gtsam.imuBias.ConstantBias(rng.normal(size=3) * 0.05, rng.normal(size=3) * 0.005)
        pim = gtsam.PreintegratedImuMeasurements(params, bias)
        acc, gyro = rng.normal(size=3) + [0, 0, 9.81], rng.normal(size=3) * 0.3
        for _ in range(20):
            pim.integrateMeasurement(acc, gyro, 0.005)
        x0 = gtsam.Pose3(gtsam.Rot3.Expmap(rng.normal(size=3) * 0.3), rng.normal(size=3))
        v0 = rng.normal(size=3)
        state = pim.predict(gtsam.NavState(x0, v0), bias)
        values = gtsam.Values()
        values.insert(0, x0)
        values.insert(1, v0)
        values.insert(2, state.pose())
        values.insert(3, state.velocity())
        values.insert(4, bias)
        return FactorExample(gtsam.ImuFactor(0, 1, 2, 3, 4, pim), values, perturbation=0.01)


class VelocityFromPoses(Initializer):
    name = "imu.velocity"
    summary = "per-state world-frame velocities from the current poses (central differences)"
    robot_fields = ("robot",)
    schema = {"type": "object", "properties": {"robot": NAME}, "required": ["robot"], "additionalProperties": False}

    def check(self, spec: Spec, scope) -> None:
        scope.require_states(spec, "robot", "pose3")

    def initialize(self, ctx, spec: Spec) -> None:
        robot = spec["robot"]
        family = ctx.keys.get(robot, VELOCITY)
        if family is None:
            raise spec.error("robot", f"no imu.preintegrated factor on robot {robot!r}: it has no velocities")
        states = ctx.state_set(robot, spec)
        pos = np.array([ctx.initial.atPose3(ctx.pose_key(robot, k)).translation() for k in range(len(states))])
        vel = np.gradient(pos, states.t, axis=0)
        for k in range(len(states)):
            if ctx.initial.exists(family.key(k)):
                ctx.set_initial(family.key(k), vel[k])


FACTOR_TYPES = [PreintegratedImu]
INITIALIZERS = [VelocityFromPoses]
