"""An IMU between states: GTSAM's preintegrated IMU factor, and the velocities it needs.

`imu.preintegrated`: the accelerometer (m/s^2, specific force in the body frame) and gyroscope
(rad/s) samples between consecutive states, each held until the next sample, preintegrated
(Forster et al.) into one native `ImuFactor` over (pose_i, velocity_i, pose_j, velocity_j, bias).
Gravity points down the world z axis (`gravity`, m/s^2). The bias is an `imu_bias`
parameter of the robot ([accelerometer (3), gyroscope (3)]); per-state velocities are the
`velocity` family (world frame, m/s). `imu.velocity` initializes them from the poses;
`imu.odometry_scale` the unknown scale of a scaled odometry (monocular VO) from the IMU.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import gtsam
import numpy as np

from fusionkit.api import (FactorExample, FactorType, GRAVITY, Initializer, NAME_SCHEMA as NAME, POSE_COLUMNS, Spec,
                           VELOCITY3, held_intervals, odometry_pairs)

if TYPE_CHECKING:
    from scipy.sparse import coo_matrix

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


def integrate_held(pim: gtsam.PreintegratedImuMeasurements, t: np.ndarray, samples: np.ndarray, t0: float,
                   t1: float) -> gtsam.PreintegratedImuMeasurements:
    """Adds to `pim` the samples (K, 6) at times t held over [t0, t1), each until the next sample."""
    rows, dts = held_intervals(t, t0, t1)
    for j, dt in zip(rows, dts):
        if dt > 0:
            pim.integrateMeasurement(samples[j, :3], samples[j, 3:], float(dt))
    return pim


def preintegrate(params, bias: gtsam.imuBias.ConstantBias, t: np.ndarray, samples: np.ndarray, t0: float,
                 t1: float) -> gtsam.PreintegratedImuMeasurements:
    """The samples (K, 6) at times t held over [t0, t1), each until the next sample."""
    return integrate_held(gtsam.PreintegratedImuMeasurements(params, bias), t, samples, t0, t1)


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
        family = ctx.family(robot, VELOCITY)
        if family is None:
            raise spec.error("robot", f"no imu.preintegrated factor on robot {robot!r}: it has no velocities")
        states = ctx.state_set(robot, spec)
        pos = np.array([ctx.initial_value(ctx.pose_key(robot, k)).translation() for k in range(len(states))])
        vel = np.gradient(pos, states.t, axis=0)
        for k in range(len(states)):
            if ctx.has_variable(family.key(k)):
                ctx.set_initial(family.key(k), vel[k])


def scale_rows(dp_odo: np.ndarray, R: np.ndarray, dp: np.ndarray, dv: np.ndarray, dt: np.ndarray,
               ka: np.ndarray, kb: np.ndarray, gravity: float) -> tuple[coo_matrix, np.ndarray]:
    """The linear system in x = [s, v_0, v_1, ...] (scale, world velocities of the states) of N odometry pairs
    (ka, kb) dt apart: s dp_odo - v_a dt = R_a dp + g dt^2 / 2 and v_b - v_a = R_a dv + g dt (the
    preintegrated increments dp, dv about a zero bias, R_a the world attitude of state a, g = [0, 0, -gravity])."""
    from scipy.sparse import coo_matrix
    n = len(ka)
    g = np.array([0.0, 0.0, -gravity])
    rows = np.arange(6 * n).reshape(n, 2, 3)
    va = 1 + 3 * ka[:, None] + np.arange(3)                     # columns of v_a, v_b
    vb = 1 + 3 * kb[:, None] + np.arange(3)
    r_pos, r_vel = rows[:, 0], rows[:, 1]
    entries = [(r_pos, np.zeros_like(r_pos), dp_odo), (r_pos, va, -dt[:, None] * np.ones(3)),
               (r_vel, vb, np.ones((n, 3))), (r_vel, va, -np.ones((n, 3)))]
    i, j, v = (np.concatenate([e[k].ravel() for e in entries]) for k in range(3))
    A = coo_matrix((v, (i, j)), shape=(6 * n, 1 + 3 * (int(max(ka.max(), kb.max())) + 1)))
    b = np.stack([np.einsum("nij,nj->ni", R, dp) + 0.5 * g * dt[:, None] ** 2,
                  np.einsum("nij,nj->ni", R, dv) + g * dt[:, None]], axis=1).ravel()
    return A, b


def strided_pairs(ka: np.ndarray, stride: int) -> tuple[np.ndarray, np.ndarray]:
    """(a, b) state pairs `stride` states apart along each unbroken stretch of consecutive pairs (ka, ka + 1),
    the last one of a stretch shorter."""
    cuts = np.flatnonzero(np.diff(ka) > 1) + 1
    a_out, b_out = [], []
    for stretch in np.split(ka, cuts):
        starts = stretch[::stride]
        ends = np.minimum(starts + stride, stretch[-1] + 1)
        a_out.append(starts)
        b_out.append(ends)
    return np.concatenate(a_out), np.concatenate(b_out)


# the keys of the initializers that read an odometry pose stream (`stream`) and an IMU stream (`imu`)
ODOMETRY_AND_IMU = {"robot": NAME, "stream": NAME, "imu": NAME, "max_gap": {"type": "number", "exclusiveMinimum": 0},
                    "columns": {"type": "array", "items": NAME, "minItems": 6, "maxItems": 6,
                                "default": list(IMU_COLUMNS)},
                    "gravity": {"type": "number", "minimum": 0, "default": GRAVITY}}


def check_odometry_and_imu(spec: Spec, scope) -> None:
    scope.require_states(spec, "robot", "pose3")
    scope.require_columns(spec, "stream", POSE_COLUMNS)
    scope.require_columns(spec, "imu", tuple(spec["columns"]))


class OdometryScaleFromImu(Initializer):
    name = "imu.odometry_scale"
    summary = ("initial scale of a scaled odometry (monocular VO) from the IMU: least squares over the scale and "
               "the velocities of every tenth state, zero bias")
    robot_fields = ("robot",)
    stream_fields = ("stream", "imu")
    schema = {"type": "object", "properties": {**ODOMETRY_AND_IMU, "scale": NAME},
              "required": ["robot", "stream", "imu", "scale"], "additionalProperties": False}
    # states per pair: the odometry's noise enters the velocity changes as a second difference, which over
    # one state step (50 ms) is larger than the motion's and shrinks the scale (errors in the regressor:
    # 1.99 for a true 2.5, measured); over ten steps the motion's grows a hundredfold
    STRIDE = 10

    def check(self, spec: Spec, scope) -> None:
        check_odometry_and_imu(spec, scope)
        scope.require_parameter(spec, "robot", "scale", "scalar")

    def initialize(self, ctx, spec: Spec) -> None:
        """The odometry's frame is taken as the world frame turned by the first state's initial attitude
        (pose.origin's), as pose.dead_reckoning does; pairs across a gap of the odometry are left out."""
        from scipy.sparse.linalg import lsqr
        robot = spec["robot"]
        states = ctx.state_set(robot, spec)
        ka, before, after = odometry_pairs(ctx, spec, robot)
        if len(ka) < 3:
            raise spec.error("stream", f"{len(ka)} pairs of consecutive states have odometry: expected at least 3 "
                             "to estimate a scale")
        first = ctx.initial_value(ctx.pose_key(robot, 0)) if ctx.has_variable(ctx.pose_key(robot, 0)) \
            else gtsam.Pose3()
        turn = first.rotation().matrix() @ before[0].rotation().matrix().T  # odometry frame -> world
        odo = {**dict(zip(ka.tolist(), before)), **dict(zip((ka + 1).tolist(), after))}
        a, b = strided_pairs(ka, self.STRIDE)
        t_imu, samples = _imu_samples(ctx, spec)
        params = preintegration_params(1e-3, 1e-4, spec["gravity"])
        zero = gtsam.imuBias.ConstantBias()
        dp, dv = np.empty((len(a), 3)), np.empty((len(a), 3))
        for n, (i, j) in enumerate(zip(a.tolist(), b.tolist())):
            pim = preintegrate(params, zero, t_imu, samples, float(states.t[i]), float(states.t[j]))
            dp[n], dv[n] = pim.deltaPij(), pim.deltaVij()
        R = np.array([turn @ odo[i].rotation().matrix() for i in a.tolist()])
        dp_odo = np.array([turn @ (odo[j].translation() - odo[i].translation()) for i, j in zip(a.tolist(), b.tolist())])
        A, rhs = scale_rows(dp_odo, R, dp, dv, states.t[b] - states.t[a], a, b, spec["gravity"])
        A = A.tocsc()
        used = np.flatnonzero(np.diff(A.indptr))  # velocity columns of states in no pair stay out
        scale = float(lsqr(A[:, used], rhs, atol=1e-12, btol=1e-12)[0][0])
        if not scale > 0:
            raise spec.error("scale", f"the IMU gives a scale of {scale:.3g} for the odometry (expected > 0): "
                             "check the IMU's axes and units and the odometry's frame")
        ctx.set_initial(ctx.parameter(robot, spec["scale"]), scale)


def _imu_samples(ctx, spec: Spec):
    imu = ctx.stream(spec["imu"])
    return imu.t, np.column_stack([imu.column(c) for c in spec["columns"]])


def end_velocities(t: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Velocities (3,) at the first and the last of the times t from positions p (N, 3): derivatives of a
    least-squares quadratic (a line for fewer than 4 points)."""
    fit = np.polynomial.polynomial.polyfit(t - t[-1], p, 2 if len(t) >= 4 else 1)
    slope = np.polynomial.polynomial.polyder(fit)
    return np.polynomial.polynomial.polyval(t[0] - t[-1], slope), slope[0]


def gravity_tilt(R: list[np.ndarray], dv: np.ndarray, v_first: np.ndarray, v_last: np.ndarray, duration: float,
                 gravity: float) -> np.ndarray:
    """The rotation (3, 3) that levels attitudes R_a whose preintegrated velocity increments dv_a add up to the
    velocity change over `duration` s: sum R_a dv_a = v_last - v_first - g duration. Gravity dominates the sum,
    so roll and pitch errors of R show as its tilt; the smallest rotation taking it onto the right side."""
    u = sum(Ra @ d for Ra, d in zip(R, dv))
    w = v_last - v_first + np.array([0.0, 0.0, gravity * duration])
    axis = np.cross(u, w)
    angle = np.arctan2(np.linalg.norm(axis), u @ w)
    return gtsam.Rot3.Rodrigues(axis / max(np.linalg.norm(axis), 1e-12) * angle).matrix()


class BridgeOdometryGaps(Initializer):
    name = "imu.bridge_gaps"
    summary = ("initial poses across the gaps of an odometry from the IMU (zero bias): each gap predicted from the "
               "state before it, levelled by gravity; the states after it moved rigidly to continue from the prediction")
    robot_fields = ("robot",)
    stream_fields = ("stream", "imu")
    schema = {"type": "object", "properties": ODOMETRY_AND_IMU,
              "required": ["robot", "stream", "imu", "max_gap"], "additionalProperties": False}
    WINDOW = 20  # states before a gap: their positions give its starting velocity, their IMU its tilt

    def check(self, spec: Spec, scope) -> None:
        check_odometry_and_imu(spec, scope)

    def initialize(self, ctx, spec: Spec) -> None:
        """Runs after the odometry set the poses (pose.dead_reckoning); a gap is a run of state pairs with no
        odometry pair between two pairs that have one (or after the last)."""
        robot = spec["robot"]
        states = ctx.state_set(robot, spec)
        keys = [ctx.pose_key(robot, k) for k in range(len(states))]
        poses = [ctx.initial_value(key) for key in keys]
        ka = odometry_pairs(ctx, spec, robot)[0]
        t_imu, samples = _imu_samples(ctx, spec)
        params = preintegration_params(1e-3, 1e-4, spec["gravity"])
        zero = gtsam.imuBias.ConstantBias()
        starts = ka[np.flatnonzero(np.diff(ka) > 1)] + 1            # last state of a stretch: a gap follows
        if len(ka) and ka[-1] + 1 < len(states) - 1:
            starts = np.append(starts, ka[-1] + 1)
        for e in starts.tolist():
            following = ka[ka > e]
            end = int(following[0]) if len(following) else len(states) - 1   # first state after the gap
            lo = max(0, e - self.WINDOW)
            pos = np.array([p.translation() for p in poses[lo:e + 1]])
            v_first, v_last = end_velocities(states.t[lo:e + 1], pos)
            dv = [preintegrate(params, zero, t_imu, samples, float(states.t[k]), float(states.t[k + 1])).deltaVij()
                  for k in range(lo, e)]
            tilt = gravity_tilt([poses[k].rotation().matrix() for k in range(lo, e)], dv, v_first, v_last,
                                float(states.t[e] - states.t[lo]), spec["gravity"])
            start = gtsam.Pose3(gtsam.Rot3(tilt @ poses[e].rotation().matrix()), poses[e].translation())
            nav = gtsam.NavState(start, v_last)
            pim = gtsam.PreintegratedImuMeasurements(params, zero)
            for k in range(e + 1, end + 1):  # one preintegration grown state by state across the gap
                integrate_held(pim, t_imu, samples, float(states.t[k - 1]), float(states.t[k]))
                predicted = pim.predict(nav, zero).pose()
                if k < end:
                    poses[k] = predicted
            move = predicted.compose(poses[end].inverse())
            poses[end:] = [move.compose(p) for p in poses[end:]]
        for key, pose in zip(keys, poses):
            if ctx.has_variable(key):
                ctx.set_initial(key, pose)


FACTOR_TYPES = [PreintegratedImu]
INITIALIZERS = [VelocityFromPoses, OdometryScaleFromImu, BridgeOdometryGaps]
